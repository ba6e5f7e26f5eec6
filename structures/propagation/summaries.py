"""Summaries of a tidy propagation table (one row per sample x record x scale).

* :func:`percentiles`: median, 16/84 and 2.5/97.5 percentiles per record and over all records;
* :func:`variance_split`: how much of the variance of ``ln D`` comes from the isolator
  parameters and how much from record-to-record variability (law of total variance);
* :func:`exceedance`: P(D > limit) per record and over all records.

All functions work per scale (stripe) and ignore runs that did not converge (the ``converged``
column); the number of runs used is returned with every number.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

ALL = "all records"
QUANTILES = {"p2.5": 0.025, "p16": 0.16, "median": 0.5, "p84": 0.84, "p97.5": 0.975}


def _converged(table: pd.DataFrame) -> pd.DataFrame:
    if "converged" in table:
        return table[table["converged"].astype(bool)]
    return table


def percentiles(table: pd.DataFrame, demands: Sequence[str], records: Sequence[str]) -> pd.DataFrame:
    """Empirical percentiles of each demand per (scale, record) and per scale over all records.

    Returns a DataFrame with columns ``demand, scale, record, n, p2.5, p16, median, p84, p97.5``;
    ``record == "all records"`` pools every record (each record weighs by its number of runs).
    Percentiles use linear interpolation between order statistics (NumPy's default).
    """
    t = _converged(table)
    rows = []
    for d in demands:
        for scale, ts in t.groupby("scale", sort=True):
            groups = [(r, ts.loc[ts["record"] == r, d].to_numpy(float)) for r in records]
            groups.append((ALL, ts[d].to_numpy(float)))
            for r, x in groups:
                x = x[np.isfinite(x)]
                row = {"demand": d, "scale": float(scale), "record": r, "n": int(x.size)}
                q = np.quantile(x, list(QUANTILES.values())) if x.size else [np.nan] * len(QUANTILES)
                row.update(dict(zip(QUANTILES, map(float, q))))
                rows.append(row)
    return pd.DataFrame(rows, columns=["demand", "scale", "record", "n", *QUANTILES])


def variance_split(table: pd.DataFrame, demands: Sequence[str]) -> pd.DataFrame:
    """Share of the variance of ``Y = ln D`` due to the isolator parameters vs. the records.

    Every parameter sample runs on every record (a crossed design), so with ``theta`` the
    parameter sample and ``r`` the record, the law of total variance gives, per scale,

        Var(Y) = Var_theta( E[Y | theta] ) + E_theta( Var[Y | theta] )

    and symmetrically for ``r``.  Reported (population variances over the design, i.e. every
    (theta, r) pair weighs the same):

    * ``share_params``  = Var_theta(E[Y | theta]) / Var(Y): the part explained by the isolator
      parameters alone (first-order index);
    * ``share_records`` = Var_r(E[Y | r]) / Var(Y): record-to-record variability alone;
    * ``share_interaction`` = 1 - both: how the parameters' effect changes from record to record.

    Only samples that converged on every record of the stripe are used.  Demands that are not
    strictly positive in some run have no logarithm: their row is NaN.
    """
    t = _converged(table)
    rows = []
    for d in demands:
        for scale, ts in t.groupby("scale", sort=True):
            wide = ts.pivot_table(index="sample", columns="record", values=d, aggfunc="first")
            wide = wide.dropna(axis=0, how="any")
            row = {"demand": d, "scale": float(scale), "n_samples": int(wide.shape[0]),
                   "n_records": int(wide.shape[1]), "var_log": np.nan, "share_params": np.nan,
                   "share_records": np.nan, "share_interaction": np.nan}
            y = wide.to_numpy(float)
            if y.size and np.all(y > 0) and wide.shape[0] > 1 and wide.shape[1] > 1:
                y = np.log(y)
                var = float(y.var())
                row["var_log"] = var
                if var > 0:
                    sp = float(y.mean(axis=1).var()) / var
                    sr = float(y.mean(axis=0).var()) / var
                    row.update(share_params=sp, share_records=sr, share_interaction=1.0 - sp - sr)
            rows.append(row)
    return pd.DataFrame(rows)


def exceedance(table: pd.DataFrame, limits: Mapping[str, float], records: Sequence[str]) -> pd.DataFrame:
    """P(D > limit) per (limit, scale, record) and per (limit, scale) over all records.

    Returns columns ``demand, limit, scale, record, n, n_exceed, p_exceed``.
    """
    t = _converged(table)
    rows = []
    for d, lim in limits.items():
        for scale, ts in t.groupby("scale", sort=True):
            groups = [(r, ts.loc[ts["record"] == r, d].to_numpy(float)) for r in records]
            groups.append((ALL, ts[d].to_numpy(float)))
            for r, x in groups:
                k = int(np.sum(x > lim))
                rows.append({"demand": d, "limit": float(lim), "scale": float(scale), "record": r,
                             "n": int(x.size), "n_exceed": k, "p_exceed": k / x.size if x.size else np.nan})
    return pd.DataFrame(rows)
