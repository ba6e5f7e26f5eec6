"""Which law? PSIS-LOO, WAIC and leave-one-cycle-out of calibrated laws.

* PSIS-LOO (Vehtari, Gelman & Gabry 2017) and WAIC (Watanabe 2010) on the pointwise
  log-likelihood stored in each calibration (``az.loo``, ``az.waic``, ``az.compare``), with the
  Pareto-k diagnostics of the importance weights (k > 0.7: the estimate of that point is not
  reliable).
* Leave-one-cycle-out (:func:`elpd_loco`): samples of a hysteresis test are strongly dependent,
  so leaving out one sample says little about predicting new loading.  Summing the pointwise
  log-likelihood over each full loading cycle (cycles from :func:`rrfrei.energy.cycle_bounds`;
  samples before the first / after the last full cycle join it) and applying PSIS to the cycle
  sums estimates the expected log density of a whole new cycle.  For AR(1) noise the cycle sum
  of the conditional densities is the cycle's density given the previous sample.

elpd differences are judged against their standard error ``dse`` (paired over points/cycles):
a difference under 2 dse does not separate two laws.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from rrfrei.calibration.results import Calibration, _as_calibration, arviz_numpy, load_arviz
from rrfrei.io import ShearTest, read_test

__all__ = ["CompareResult", "compare", "elpd_loco", "cycle_groups", "runnable_laws", "too_few_laws"]


def runnable_laws(test: ShearTest, laws: Sequence[str] | str,
                  fixed: Mapping[str, float] | None = None) -> tuple[list[str], dict[str, str]]:
    """Split ``laws`` into the ones ``test`` can calibrate and the skipped ones, with the reason.

    Checked before any work: a law that needs what the test lacks (the bearing geometry of
    ``elastomeric_x`` on a test without a ``[geometry]`` sidecar) is skipped with the law's own
    message.  ``laws`` is a list, a comma-separated string or ``"all"`` (the OpenSees laws).
    An unknown law name is a ValueError (a typo is not a skip).
    """
    from rrfrei.laws import OPENSEES_LAWS, get

    if isinstance(laws, str):
        laws = (list(OPENSEES_LAWS) if laws.strip() == "all"
                else [s.strip() for s in laws.split(",") if s.strip()])
    ok, skipped = [], {}
    for law in laws:
        spec = get(law)
        try:
            spec.resolve_fixed(test.geometry, {k: v for k, v in (fixed or {}).items()
                                               if k in spec.param_names},
                               source=str(test.source or test.name))
        except ValueError as exc:
            skipped[law] = str(exc)
            continue
        ok.append(law)
    return ok, skipped


def cycle_groups(disp: np.ndarray) -> np.ndarray:
    """Cycle label (0..C-1) of every sample: full cycles from :func:`rrfrei.energy.cycle_bounds`.

    Samples before the first or after the last full cycle, or between cycles, join the nearest
    earlier cycle (the first one for leading samples).  Returns all zeros when no full cycle exists.
    """
    from rrfrei.energy import cycle_bounds

    disp = np.asarray(disp, dtype=float)
    bounds = np.asarray(cycle_bounds(disp))
    lab = np.zeros(disp.size, dtype=np.int64)
    if bounds.size == 0:
        return lab
    starts = bounds.reshape(-1, 2)[:, 0].astype(int)
    for c, s in enumerate(starts):
        lab[s:] = c
    return lab


def _loco_from_ll(ll: np.ndarray, labels: np.ndarray, idata) -> tuple[float, float, pd.DataFrame]:
    az = load_arviz()
    import xarray as xr

    C = int(labels.max()) + 1
    sums = np.stack([ll[..., labels == c].sum(axis=-1) for c in range(C)], axis=-1)  # (chain, draw, C)
    ds = xr.Dataset({"cycle": (("chain", "draw", "cycle_dim"), sums)},
                    coords={"chain": np.arange(sums.shape[0]), "draw": np.arange(sums.shape[1])})
    tmp = az.InferenceData(posterior=idata.posterior, log_likelihood=ds)
    with warnings.catch_warnings(), arviz_numpy():
        warnings.simplefilter("ignore")
        res = az.loo(tmp, pointwise=True, var_name="cycle")
    per = pd.DataFrame({
        "cycle": np.arange(C),
        "samples": np.bincount(labels, minlength=C),
        "elpd": np.asarray(res.loo_i.values, dtype=float),
        "pareto_k": np.asarray(res.pareto_k.values, dtype=float),
    })
    return float(res.elpd_loo), float(res.se), per


def elpd_loco(calibration) -> tuple[float, float, pd.DataFrame]:
    """Leave-one-cycle-out expected log predictive density: ``(elpd, se, per_cycle)``.

    ``per_cycle`` has columns ``cycle``, ``samples``, ``elpd`` (each cycle's contribution) and
    ``pareto_k``.  ``se = sqrt(C var(elpd_c))`` over the C cycles.
    """
    cal = _as_calibration(calibration)
    ll = np.asarray(cal.idata.log_likelihood["force"].values, dtype=float)
    return _loco_from_ll(ll, _labels(cal), cal.idata)


def _labels(cal: Calibration) -> np.ndarray:
    """Cycle labels of the samples the stored pointwise log-likelihood holds (all of the test's,
    or a dense record's likelihood subsample, whose indices are the ``sample`` coordinate)."""
    labels = cycle_groups(cal.test.disp)
    samples = np.asarray(cal.idata.log_likelihood["force"].coords["sample"].values, dtype=np.int64)
    return labels if samples.size == labels.size else labels[samples]


@dataclass(frozen=True, eq=False)
class CompareResult:
    """Tables of a comparison; ``table`` is indexed by law, best (highest LOO elpd) first, with
    each law's absolute fit on the test beside its ranking (``nrmse``, ``systematic``,
    ``coverage``, ``adequacy``: :mod:`rrfrei.calibration.quality`)."""

    table: pd.DataFrame
    loo: pd.DataFrame
    waic: pd.DataFrame
    loco: pd.DataFrame
    pareto_k: pd.DataFrame
    loco_cycles: pd.DataFrame
    calibrations: dict
    skipped: dict = field(default_factory=dict)
    """Laws left out before any work: law -> why (e.g. the bearing geometry it needs)."""

    @property
    def best(self) -> str:
        return str(self.table.index[0])

    @property
    def best_line(self) -> str:
        """The ranking's winner with its absolute fit, e.g. ``best by PSIS-LOO: bouc_wen
        (inadequate: NRMSE 45.0 % (systematic 44.8 %), coverage 95.9 %: ...)``."""
        from rrfrei.calibration.quality import Adequacy

        r = self.table.iloc[0]
        a = Adequacy(float(r["nrmse"]), float(r["systematic"]), float(r["coverage"]), str(r["adequacy"]))
        line = f"best by PSIS-LOO: {self.best} ({a.sentence})"
        if (self.table["adequacy"] == "inadequate").all():
            line += "; none of the laws compared reproduces this test: the ranking says which misses least"
        return line

    def figure(self):
        """elpd +- se per law for PSIS-LOO, WAIC and leave-one-cycle-out (matplotlib Figure)."""
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 3, figsize=(11, 3.4), constrained_layout=True)
        for ax, (title, col, se) in zip(axes, (("PSIS-LOO", "elpd_loo", "se_loo"),
                                               ("WAIC", "elpd_waic", "se_waic"),
                                               ("leave-one-cycle-out", "elpd_loco", "se_loco"))):
            t = self.table
            y = np.arange(len(t))[::-1]
            ax.errorbar(t[col], y, xerr=t[se], fmt="o", color="tab:blue", capsize=3)
            ax.set_yticks(y, t.index)
            ax.set_title(title, fontsize=9)
            ax.set_xlabel("elpd (higher is better)")
            ax.grid(alpha=0.3)
        return fig


def _paired_dse(a: np.ndarray, b: np.ndarray) -> float:
    d = np.asarray(a) - np.asarray(b)
    return float(np.sqrt(d.size * np.var(d))) if d.size > 1 else 0.0


def compare(
    tests_or_calibrations,
    laws: Sequence[str] | str | None = None,
    **calibrate_kwargs,
) -> CompareResult:
    """Compare laws by PSIS-LOO, WAIC and leave-one-cycle-out.

    Parameters
    ----------
    tests_or_calibrations : calibrations (a sequence or ``{label: Calibration}``; netCDF paths
        and InferenceData accepted) of the SAME test, or one test (ShearTest or CSV path), in
        which case every law in ``laws`` is calibrated on it with ``calibrate_kwargs``.
    laws : law names (a list, a comma-separated string, or ``"all"`` = the four OpenSees laws);
        with calibrations, restricts them to these laws.

    Returns
    -------
    CompareResult: ``table`` (elpd, p, se, dse, weight for each criterion), ``pareto_k``
    (counts of k <= 0.5, 0.5-0.7, 0.7-1, > 1 and the maximum) and a ``figure()``.
    """
    from rrfrei.laws import OPENSEES_LAWS

    if isinstance(laws, str):
        laws = (list(OPENSEES_LAWS) if laws.strip() == "all"
                else [s.strip() for s in laws.split(",") if s.strip()])
    src = tests_or_calibrations
    skipped: dict[str, str] = {}
    if isinstance(src, (ShearTest, str)) or hasattr(src, "__fspath__"):
        test = src if isinstance(src, ShearTest) else read_test(src)
        if not laws:
            raise ValueError("give the laws to compare (e.g. laws='all' or 'plasticity,bouc_wen')")
        from rrfrei.calibration import calibrate

        laws, skipped = runnable_laws(test, laws, calibrate_kwargs.get("fixed"))
        if len(laws) < 2:
            raise ValueError(too_few_laws(laws, skipped))
        cals = {law: calibrate(test, law, **calibrate_kwargs) for law in laws}
    else:
        if isinstance(src, Mapping):
            items = list(src.items())
        else:
            items = []
            for s in src:
                c = _as_calibration(s)
                items.append((c.law, c))
        cals = {str(k): _as_calibration(v) for k, v in items}
        if laws:
            cals = {k: v for k, v in cals.items() if v.law in laws or k in laws}
    if len(cals) < 2:
        raise ValueError(f"need at least two calibrations to compare, got {len(cals)}")
    ref = next(iter(cals.values())).test
    for k, c in cals.items():
        if c.test.disp.shape != ref.disp.shape or not np.allclose(c.test.force, ref.force):
            raise ValueError(f"calibration {k!r} is of test {c.test.name!r}, not {ref.name!r}: "
                             "laws are compared on the same data only")
    az = load_arviz()
    idatas = {k: c.idata for k, c in cals.items()}
    with warnings.catch_warnings(), arviz_numpy():
        warnings.simplefilter("ignore")
        loo = az.compare(idatas, ic="loo", var_name="force")
        waic = az.compare(idatas, ic="waic", var_name="force")
        loos = {k: az.loo(d, pointwise=True, var_name="force") for k, d in idatas.items()}
    krows = []
    for k, r in loos.items():
        pk = np.asarray(r.pareto_k.values, dtype=float)
        krows.append({"law": k, "k<=0.5": int(np.sum(pk <= 0.5)),
                      "0.5<k<=0.7": int(np.sum((pk > 0.5) & (pk <= 0.7))),
                      "0.7<k<=1": int(np.sum((pk > 0.7) & (pk <= 1))), "k>1": int(np.sum(pk > 1)),
                      "k_max": float(np.max(pk))})
    pareto = pd.DataFrame(krows).set_index("law")
    # leave-one-cycle-out
    lc, per_cycle = {}, []
    for k, c in cals.items():
        ll = np.asarray(c.idata.log_likelihood["force"].values, dtype=float)
        e, se, per = _loco_from_ll(ll, _labels(c), c.idata)
        lc[k] = (e, se, per)
        per_cycle.append(per.assign(law=k))
    best_lc = max(lc, key=lambda k: lc[k][0])
    lrows = []
    wts = np.array([lc[k][0] for k in lc])
    wts = np.exp(wts - wts.max())
    wts /= wts.sum()
    for (k, (e, se, per)), w in zip(lc.items(), wts):
        lrows.append({"law": k, "elpd_loco": e, "se_loco": se,
                      "dse_loco": _paired_dse(per["elpd"], lc[best_lc][2]["elpd"]),
                      "weight_loco": float(w), "k_max_loco": float(per["pareto_k"].max())})
    loco = pd.DataFrame(lrows).set_index("law").sort_values("elpd_loco", ascending=False)
    table = pd.DataFrame({
        "elpd_loo": loo["elpd_loo"], "p_loo": loo["p_loo"], "se_loo": loo["se"], "dse_loo": loo["dse"],
        "weight_loo": loo["weight"],
    })
    table = table.join(pd.DataFrame({
        "elpd_waic": waic["elpd_waic"], "p_waic": waic["p_waic"], "se_waic": waic["se"],
        "dse_waic": waic["dse"], "weight_waic": waic["weight"],
    })).join(loco).join(pareto[["k_max"]].rename(columns={"k_max": "k_max_loo"}))
    table = table.sort_values("elpd_loo", ascending=False)
    # absolute fit next to the ranking: the best of several inadequate laws is still inadequate
    from rrfrei.calibration.checks import predict

    fit = {}
    for k, c in cals.items():
        a = predict(c, c.test, seed=0).adequacy
        fit[k] = {"nrmse": a.nrmse, "systematic": a.systematic, "coverage": a.coverage,
                  "adequacy": a.level}
    table = table.join(pd.DataFrame.from_dict(fit, orient="index"))
    table.index.name = "law"
    return CompareResult(table=table, loo=loo, waic=waic, loco=loco, pareto_k=pareto,
                         loco_cycles=pd.concat(per_cycle, ignore_index=True),
                         calibrations=dict(cals), skipped=skipped)


def too_few_laws(laws: Sequence[str], skipped: Mapping[str, str]) -> str:
    """The error of a comparison left with fewer than two laws, naming the skipped ones and why."""
    why = "; ".join(f"{k}: {v}" for k, v in skipped.items())
    return (f"need at least two laws this test can run to compare, got {list(laws)}"
            + (f" (skipped {why})" if why else ""))


__all__ += ["Calibration"]
