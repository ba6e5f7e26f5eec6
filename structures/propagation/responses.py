"""The result of a propagation: a tidy table of demands with its summaries and plots.

:class:`ResponseSet` holds one row per analysis (sample x record x scale) in prototype units and
answers the questions asked of it: percentiles, the variance split between the isolator
parameters and the records, exceedance probabilities and fragility curves
(:mod:`structures.propagation.summaries`, :mod:`structures.propagation.fragility`), and draws its
figures (:func:`distributions`, :func:`exceedance`, :func:`fragility`: each takes the response set
and returns the matplotlib figure it drew on, ``ax`` given: its figure, else a new pyplot figure;
axis labels carry units, :func:`label`).  :func:`chunk_table` turns the batched kernel's demand
arrays of one chunk into the table's rows.

Units: m, s, kN, tonnes; accelerations m/s^2; drift ratios dimensionless.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from structures.propagation import summaries
from structures.propagation.fragility import Fragility, fit_fragility

__all__ = ["DEMAND_LABELS", "MAIN_DEMANDS", "ResponseSet", "chunk_table", "distributions", "exceedance",
           "fragility", "intensity_text", "label"]

MAIN_DEMANDS = ("iso_disp_peak_m", "iso_disp_residual_m", "drift_ratio_max", "floor_acc_max_ms2",
                "base_shear_peak_kN", "iso_energy_kNm")


#: Demand column -> axis label with unit (per-story/floor columns are labelled by prefix).
DEMAND_LABELS = {
    "iso_disp_peak_m": "peak isolator displacement [m]",
    "iso_disp_residual_m": "residual isolator displacement [m]",
    "drift_ratio_max": "peak story drift ratio, largest story [-]",
    "floor_acc_max_ms2": "peak absolute floor acceleration, largest floor [m/s$^2$]",
    "base_shear_peak_kN": "peak base shear [kN]",
    "iso_energy_kNm": "isolator dissipated energy [kN m]",
    "energy_error": "energy balance error (relative) [-]",
}


def label(demand: str) -> str:
    """Axis label with unit of a demand column."""
    if demand in DEMAND_LABELS:
        return DEMAND_LABELS[demand]
    if demand.startswith("drift_ratio_s"):
        return f"peak drift ratio, story {demand[len('drift_ratio_s'):]} [-]"
    if demand.startswith("floor_acc_f"):
        floor = demand[len("floor_acc_f"):].removesuffix("_ms2")
        return f"peak absolute acceleration, floor {floor} [m/s$^2$]"
    return demand


@dataclass(frozen=True, eq=False)
class ResponseSet:
    """Demands of a building on posterior draws of its isolator law, over records and scales.

    Attributes
    ----------
    table
        Tidy DataFrame, one row per run: ``sample`` (draw index), ``record`` (name), ``scale``
        (intensity multiplier), then the demands (prototype units: ``iso_disp_peak_m``,
        ``iso_disp_residual_m``, ``drift_ratio_s1..``, ``drift_ratio_max``,
        ``floor_acc_f1_ms2..``, ``floor_acc_max_ms2``, ``base_shear_peak_kN``, ``iso_energy_kNm``,
        ``energy_error``), ``converged`` and ``extrapolated`` (the isolator went beyond the largest
        displacement the law was calibrated on, ``length_scale`` x specimen amplitude).
    draws
        The parameter draws, one row per ``sample`` (specimen units, the law's parameter names).
    law, records, scales, seed
        The inputs.
    limits
        Default demand limits for :meth:`exceedance` and :meth:`fragility`.
    calibrated_range
        Specimen displacement range [m] the posterior was calibrated on (None when unknown).
    length_scale
        Prototype displacement = ``length_scale`` x specimen displacement.
    """

    table: pd.DataFrame
    draws: pd.DataFrame
    law: str
    records: tuple[str, ...]
    scales: tuple[float, ...]
    seed: int
    limits: dict[str, float]
    calibrated_range: tuple[float, float] | None
    length_scale: float
    building: str = ""
    im_label: str = "intensity (record scale factor) [-]"
    record_factors: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = field(default=())

    # -------------------------------------------------------------------- table helpers
    @property
    def demands(self) -> tuple[str, ...]:
        """Every demand column of :attr:`table`."""
        skip = {"sample", "record", "scale", "converged", "extrapolated"}
        return tuple(c for c in self.table.columns if c not in skip)

    @property
    def main_demands(self) -> tuple[str, ...]:
        return tuple(d for d in MAIN_DEMANDS if d in self.table.columns)

    def _check(self, demands) -> tuple[str, ...]:
        if demands is None:
            ds = self.main_demands
        else:
            ds = (demands,) if isinstance(demands, str) else tuple(demands)
        for d in ds:
            if d not in self.table.columns:
                raise ValueError(f"unknown demand {d!r}; available: {', '.join(self.demands)}")
        return ds

    # -------------------------------------------------------------------- summaries
    def summary(self, demands: str | Sequence[str] | None = None) -> pd.DataFrame:
        """Median, 16/84 and 2.5/97.5 percentiles per record and over all records, per scale.

        See :func:`structures.propagation.summaries.percentiles` (converged runs only).
        """
        return summaries.percentiles(self.table, self._check(demands), self.records)

    def variance_split(self, demands: str | Sequence[str] | None = None) -> pd.DataFrame:
        """Share of Var(ln D) from the isolator parameters vs. record-to-record variability.

        Law of total variance over the crossed (sample x record) design, per scale:
        ``share_params = Var_theta(E[ln D | theta]) / Var(ln D)``,
        ``share_records = Var_r(E[ln D | r]) / Var(ln D)``, the rest is their interaction
        (see :func:`structures.propagation.summaries.variance_split`).
        """
        return summaries.variance_split(self.table, self._check(demands))

    def exceedance(self, limits: Mapping[str, float] | None = None) -> pd.DataFrame:
        """P(D > limit) per record and over all records, per scale (default: :attr:`limits`)."""
        lim = dict(self.limits if limits is None else limits)
        self._check(list(lim))
        return summaries.exceedance(self.table, lim, self.records)

    def fragility(self, limits: Mapping[str, float] | None = None) -> list[Fragility]:
        """Lognormal fragility per limit, fitted across the scales by maximum likelihood.

        Baker (2015): the runs of all records and draws at one scale form a stripe; see
        :func:`structures.propagation.fragility.fit_fragility`.  The intensity is the scale factor.
        """
        ex = self.exceedance(limits)
        ex = ex[ex["record"] == summaries.ALL]
        out = []
        for (d, lim), g in ex.groupby(["demand", "limit"], sort=False):
            out.append(fit_fragility(g["scale"], g["n"], g["n_exceed"], demand=d, limit=lim))
        return out

    def extrapolated_share(self) -> float:
        """Share of runs where the isolator left the calibrated displacement range (NaN if unknown)."""
        col = self.table["extrapolated"]
        if col.isna().all():
            return float("nan")
        return float(col.astype(float).mean())

    # -------------------------------------------------------------------- plots
    def plot_distributions(self, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
        """Box plots of ``demand`` per record (and over all records) at one scale."""
        return distributions(self, demand, scale=scale, ax=ax)

    def plot_exceedance(self, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
        """Empirical exceedance curves P(D > d) per record and over all records at one scale."""
        return exceedance(self, demand, scale=scale, ax=ax)

    def plot_fragility(self, limits: Mapping[str, float] | None = None, ax=None):
        """Fitted fragility curves with the observed stripe fractions."""
        return fragility(self, limits, ax=ax)


def chunk_table(out: dict, samples: np.ndarray, record: str, scale: float, d_max: float | None,
           length_scale: float) -> pd.DataFrame:
    """Tidy rows of one chunk from the kernel's demand arrays."""
    cols: dict[str, Any] = {"sample": samples.astype(np.int64), "record": [record] * samples.size,
                            "scale": np.full(samples.size, scale)}
    cols["iso_disp_peak_m"] = out["iso_disp_peak"]
    cols["iso_disp_residual_m"] = out["iso_disp_residual"]
    drift = np.atleast_2d(out["drift_peak"]).reshape(samples.size, -1)
    for j in range(drift.shape[1]):
        cols[f"drift_ratio_s{j + 1}"] = drift[:, j]
    cols["drift_ratio_max"] = drift.max(axis=1)
    acc = np.atleast_2d(out["floor_acc_peak"]).reshape(samples.size, -1)
    for j in range(acc.shape[1]):
        cols[f"floor_acc_f{j + 1}_ms2"] = acc[:, j]
    cols["floor_acc_max_ms2"] = acc.max(axis=1)
    cols["base_shear_peak_kN"] = out["base_shear_peak"]
    cols["iso_energy_kNm"] = out["iso_energy"]
    cols["energy_error"] = out["energy_error"]
    cols["converged"] = np.asarray(out["converged"], dtype=bool)
    cols["extrapolated"] = extrapolated(np.asarray(out["iso_disp_max_abs"], dtype=float), d_max, length_scale)
    return pd.DataFrame(cols)


def extrapolated(peak: np.ndarray, d_max: float | None, length_scale: float,
                 unknown: np.ndarray | None = None) -> pd.api.extensions.ExtensionArray:
    """Per run: did the peak isolator displacement ``peak`` [m] (prototype) exceed the
    calibrated range ``d_max`` [m] (specimen) times ``length_scale``?  NA where ``d_max`` is
    unknown (None) or where ``unknown`` (bool mask) is True."""
    if d_max is None:
        return pd.array([pd.NA] * peak.size, dtype="boolean")
    flag = pd.array(peak / length_scale > d_max * (1 + 1e-9), dtype="boolean")
    if unknown is not None:
        flag[unknown] = pd.NA
    return flag


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------
def _pyplot():
    import matplotlib.pyplot as plt  # deferred: matplotlib only when a figure is drawn

    return plt


def distributions(rs: ResponseSet, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
    """Box plots of ``demand`` per record (and over all records) at one scale (default: the first)."""
    (d,) = rs._check(demand)
    s = rs.scales[0] if scale is None else float(scale)
    t = summaries._converged(rs.table)
    t = t[np.isclose(t["scale"], s)]
    data = [t.loc[t["record"] == r, d].to_numpy(float) for r in rs.records] + [t[d].to_numpy(float)]
    names = [*rs.records, summaries.ALL]
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(max(5.0, 0.7 * len(names) + 2), 4))
    ax.boxplot(data, whis=(2.5, 97.5), showfliers=True)
    ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
    ax.set_xlabel("ground motion record")
    ax.set_ylabel(label(d))
    ax.set_title(f"{rs.law}, {len(rs.draws)} draws per record, {intensity_text(rs, s)}\n"
                 "(box 25-75 %, whiskers 2.5-97.5 %)", fontsize=9)
    if d in rs.limits:
        ax.axhline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
        ax.legend()
    ax.figure.tight_layout()
    return ax.figure


def intensity_text(rs: ResponseSet, s: float) -> str:
    """Stripe ``s`` in words: ``record scale factor 1 (records as recorded)``, ``Sa(...) = 0.3 g``."""
    lab = rs.im_label
    name, _, unit = lab.rpartition(" [")
    unit = unit.rstrip("]")
    if "scale factor" in lab:
        return f"record scale factor {s:g}" + (" (records as recorded)" if s == 1.0 else "")
    name = name or lab
    return f"{name} = {s:g}" + (f" {unit}" if unit and unit != "-" else "")


def exceedance(rs: ResponseSet, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
    """Empirical exceedance curves P(D > d) at one intensity (default: the last stripe).

    Thin lines: over the posterior draws on one record (parameter uncertainty only); thick line:
    over the draws on every record (records and parameters).  The title, the axis and the legend
    say which set each curve is over.
    """
    (d,) = rs._check(demand)
    s = rs.scales[-1] if scale is None else float(scale)
    t = summaries._converged(rs.table)
    t = t[np.isclose(t["scale"], s)]
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6.4, 4.4))
    for r in [*rs.records, summaries.ALL]:
        x = np.sort((t if r == summaries.ALL else t[t["record"] == r])[d].to_numpy(float))
        if not x.size:
            continue
        p = 1.0 - np.arange(1, x.size + 1) / x.size
        if r == summaries.ALL:
            kw = {"color": "k", "lw": 2.2,
                  "label": f"{r}: {x.size} runs (draws x {len(rs.records)} records)"}
        else:
            kw = {"lw": 1.0, "alpha": 0.8, "label": f"{r}: {x.size} draws"}
        ax.step(x, p, where="post", **kw)
    if d in rs.limits:
        ax.axvline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
    ax.set_xlabel(label(d))
    ax.set_ylabel("P(D > d) over the runs of each curve [-]")
    ax.set_title(f"{rs.law}: exceedance of the demand at {intensity_text(rs, s)}\n"
                 "thin: posterior draws on one record; thick: draws on all records", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    ax.figure.tight_layout()
    return ax.figure


def fragility(rs: ResponseSet, limits: Mapping[str, float] | None = None, ax=None):
    """Fitted fragility curves P(D > limit | IM) with the observed fraction at each stripe.

    The x axis is the response set's intensity measure (:attr:`ResponseSet.im_label`, e.g.
    ``Sa(T_iso, 5 %) [g]`` of a multiple stripe analysis); each point is the share of the
    stripe's runs (every draw on every record) beyond the limit.
    """
    frs = rs.fragility(limits)
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6.4, 4.4))
    hi = max(rs.scales) * 1.15
    x = np.linspace(hi / 400, hi, 300)
    n_runs = 0
    for i, fr in enumerate(frs):
        c = f"C{i}"
        what, _, unit = label(fr.demand).rpartition(" [")
        unit = unit.rstrip("]").replace("$^2$", "2")
        name = f"{what} > {fr.limit:.3g}" + (f" {unit}" if unit and unit != "-" else "")
        ax.plot(fr.im, np.divide(fr.z, fr.n), "o", color=c)
        n_runs = max(n_runs, max(fr.n, default=0))
        if math.isfinite(fr.theta):
            ax.plot(x, fr.probability(x), color=c,
                    label=f"{name}: median {fr.theta:.3g}, beta {fr.beta:.2f}")
        else:
            ax.plot([], [], "o", color=c, label=f"{name}: {fr.note}")
    ax.set_xlim(0.0, hi)
    ax.set_xlabel(rs.im_label)
    ax.set_ylabel("P(demand > limit | intensity) [-]")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"lognormal fragility, maximum likelihood over {len(rs.scales)} stripes (Baker 2015)\n"
                 f"points: share of the up to {n_runs} runs of a stripe ({len(rs.records)} records x "
                 "posterior draws) beyond the limit", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    ax.figure.tight_layout()
    return ax.figure
