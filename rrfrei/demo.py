"""The main job: every workflow of the package on the bundled data, as one HTML page.

:func:`run_demo` runs the steps below in order and writes ``DIR/index.html`` (one self-contained
page, figures embedded), ``DIR/tables/*.csv`` and ``DIR/manifest.json`` (see
:mod:`rrfrei.report`).  Each step is a function ``step(ctx, section)`` that fills its section with
tables, figures and a short reading computed from the numbers; a step that raises does not stop
the page: its section shows the error, later steps that need its result say so, and
:attr:`DemoResult.ok` is False (the ``rrfrei demo`` command then exits non-zero).

Steps (the isolator tests are SYNTHETIC RR-FREI-like tests, labelled so everywhere):

1. ``tests``        the four bundled tests: loops, per-cycle energy, k_eff and beta_eff;
2. ``calibration``  Bayesian calibration of plasticity, bouc_wen, elastomeric_x and hdr on
                    protocol 1;
3. ``comparison``   PSIS-LOO, WAIC and leave-one-cycle-out of the four laws; the best law is the
                    one with the highest LOO elpd;
4. ``validation``   the best law's predictions of the held-out protocols 2-4 (NRMSE, coverage,
                    energy per cycle);
5. ``gap``          sim-to-real gap diagnosis of the best law (where the residuals sit, which
                    unmodelled effect explains them, how far the gap shrinks);
6. ``propagation``  the best posterior through the bundled records on the 5-story example building;
7. ``rubber``       the polyurethane PRF model fitted to its protocols and to the real VHB 4910 data.

A step whose workflow is not available raises :class:`Placeholder`: its section is marked as a
placeholder, which the tests and :attr:`DemoResult.ok` do not accept.

Quick runs (``quick=True``) use fewer walkers and steps, fewer samples and records and a shorter
rubber fit; the page says so.
"""

from __future__ import annotations

import importlib
import math
import time
import traceback
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rrfrei.budget import stderr_is_tty
from rrfrei.report import Report, Section, fmt

__all__ = ["DemoResult", "DemoSettings", "Placeholder", "STEPS", "Step", "run_demo"]

LAWS = ("plasticity", "bouc_wen", "elastomeric_x", "hdr")
TESTS = ("protocol1", "protocol2", "protocol3", "protocol4")
SYNTHETIC = "SYNTHETIC"


#: Failures a demo step may meet on valid input (bad data, numerical failure, a structural
#: analysis that did not converge, a file problem); they are written into the page.  Anything
#: else is a bug and propagates.
EXPECTED_FAILURES: tuple[type[BaseException], ...] = (
    ValueError, RuntimeError, ArithmeticError, OSError, np.linalg.LinAlgError)


class Placeholder(Exception):
    """A step's workflow is not available yet: its section is a placeholder, not a result."""


def _api(module: str, attr: str | None = None) -> Any:
    """Import ``module`` (and its ``attr``), or raise :class:`Placeholder` naming what is missing."""
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and (module == exc.name or module.startswith(exc.name + ".")):
            raise Placeholder(f"the workflow {module} does not exist yet") from None
        raise
    if attr is None:
        return mod
    try:
        return getattr(mod, attr)
    except AttributeError:
        raise Placeholder(f"the workflow {module}.{attr} does not exist yet") from None


@dataclass(frozen=True)
class DemoSettings:
    """Sizes of every step (the defaults are the full run; :meth:`quick_run` the quick one)."""

    quick: bool = False
    seed: int = 0
    laws: tuple[str, ...] = LAWS
    walkers: int = 32
    steps: int | None = None  # None: until converged (>= 50 tau, stable), up to max_steps
    max_steps: int = 2000
    gap_draws: int = 200
    n_samples: int = 100
    records: tuple[str, ...] | None = None  # None: every bundled record
    scales: tuple[float, ...] = (0.5, 1.0, 1.5)
    building: str = "five_story"
    rubber_evals: int = 800
    rubber_restarts: int = 1
    predict_draws: int = 200

    @classmethod
    def full_run(cls, seed: int = 0) -> DemoSettings:
        return cls(seed=seed)

    @classmethod
    def quick_run(cls, seed: int = 0) -> DemoSettings:
        return cls(
            quick=True,
            seed=seed,
            walkers=24,
            steps=200,
            gap_draws=60,
            n_samples=16,
            records=("elcentro", "kocaeli"),
            scales=(1.0,),
            rubber_evals=300,
            rubber_restarts=1,
            predict_draws=100,
        )


@dataclass
class DemoContext:
    """What the steps share: settings, the loaded tests and the results of earlier steps."""

    settings: DemoSettings
    progress: bool = True
    tests: dict[str, Any] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    best_law: str | None = None
    results: dict[str, Any] = field(default_factory=dict)

    def need(self, what: str, step: str) -> Any:
        """The result ``what`` of an earlier step, or an error saying that step did not give it."""
        value = getattr(self, what, None) if what != "results" else self.results
        if not value:
            raise RuntimeError(f"this step needs the result of the '{step}' step, which did not finish")
        return value


@dataclass(frozen=True)
class Step:
    key: str
    title: str
    func: Callable[[DemoContext, Section], None]


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _figure(nrows: int = 1, ncols: int = 1, *, size: tuple[float, float] = (7.0, 4.2), **kw):
    """A matplotlib Figure not managed by pyplot (no GUI backend, nothing global)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def _pct(x: float) -> str:
    """A share as a percentage (two significant digits below 0.1 %, so small shares are not 0.0 %)."""
    v = 100 * float(x)
    return f"{v:.2g} %" if 0 < abs(v) < 0.1 else f"{v:.1f} %"


def _finite_df(df: pd.DataFrame) -> pd.DataFrame:
    """Drop rows whose numeric cells are not all finite (reported, not hidden: caller decides)."""
    num = df.select_dtypes(include=[np.number])
    return df[np.isfinite(num.to_numpy(dtype=float)).all(axis=1)]


# ---------------------------------------------------------------------------------------------
# step 1: the tests
# ---------------------------------------------------------------------------------------------
def step_tests(ctx: DemoContext, sec: Section) -> None:
    load_test = _api("rrfrei.io", "load_test")
    cycle_metrics = _api("rrfrei.energy", "cycle_metrics")
    rows, cyc = [], []
    fig, axes = _figure(2, 2, size=(9.0, 6.5))
    for ax, name in zip(axes.ravel(), TESTS):
        t = load_test(name)
        ctx.tests[name] = t
        d_mm = 1e3 * np.asarray(t.disp)
        f = np.asarray(t.force)
        m = cycle_metrics(t.disp, t.force)
        m.insert(0, "test", name)
        cyc.append(m)
        rows.append(
            {
                "test": name,
                "points": int(d_mm.size),
                "duration_s": float(t.time[-1] - t.time[0]) if t.has_time else float("nan"),
                "disp_max_mm": float(d_mm.max()),
                "disp_min_mm": float(d_mm.min()),
                "force_max_kN": float(f.max()),
                "force_min_kN": float(f.min()),
                "full_cycles": len(m),
                "energy_total_kNm": float(m["energy"].sum()) if len(m) else 0.0,
            }
        )
        ax.plot(d_mm, f, lw=0.7, color="0.25")
        ax.set_title(f"{name} ({SYNTHETIC})", fontsize=9)
        ax.set_xlabel("shear displacement [mm]")
        ax.set_ylabel("shear force [kN]")
        ax.grid(alpha=0.3)
    summary = pd.DataFrame(rows)
    cycles = pd.concat(cyc, ignore_index=True)
    sec.add_table("tests", summary, "One row per bundled SYNTHETIC test.")
    sec.add_table("cycles", cycles, "Per full cycle: dissipated energy [kN m], k_eff [kN/m], beta_eff.")
    sec.add_figure("loops", fig, "Force-displacement loops of the four SYNTHETIC tests.")

    p1 = cycles[cycles["test"] == "protocol1"]
    big = p1.loc[p1["energy"].idxmax()] if len(p1) else None
    first = p1.iloc[0] if len(p1) else None
    reading = (
        f"The four isolator tests are {SYNTHETIC}: made by an independent model with noise, standing "
        f"in for the scaled RR-FREI specimens (no real test data are public). Protocol 1 spans "
        f"{fmt(summary.loc[0, 'disp_min_mm'], 3)} to {fmt(summary.loc[0, 'disp_max_mm'], 3)} mm and "
        f"{fmt(summary.loc[0, 'force_min_kN'], 3)} to {fmt(summary.loc[0, 'force_max_kN'], 3)} kN "
        f"in {len(p1)} full cycles."
    )
    if big is not None and first is not None:
        reading += (
            f" Its largest cycle dissipates {fmt(big['energy'], 3)} kN m with an effective stiffness "
            f"of {fmt(big['k_eff'], 3)} kN/m and effective damping {_pct(big['beta_eff'])}; the first "
            f"small cycle is {'stiffer' if first['k_eff'] > big['k_eff'] else 'softer'} "
            f"(k_eff {fmt(first['k_eff'], 3)} kN/m), the usual softening of rubber bearings with "
            f"amplitude."
        )
    sec.reading = reading


# ---------------------------------------------------------------------------------------------
# step 2: calibration
# ---------------------------------------------------------------------------------------------
def step_calibrate(ctx: DemoContext, sec: Section) -> None:
    calibrate = _api("rrfrei.calibration", "calibrate")
    predict = _api("rrfrei.calibration.checks", "predict")
    tests = ctx.need("tests", "tests")
    s = ctx.settings
    test = tests["protocol1"]
    summaries, fit_rows = [], []
    fig, axes = _figure(2, 2, size=(9.0, 6.5))
    failed: dict[str, str] = {}
    for ax, law in zip(axes.ravel(), s.laws):
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # convergence is reported in the table instead
                cal = calibrate(test, law, walkers=s.walkers, steps=s.steps, max_steps=s.max_steps,
                                seed=s.seed, progress=ctx.progress)
        except EXPECTED_FAILURES as exc:  # one law failing must not hide the others (bugs do show)
            failed[law] = f"{type(exc).__name__}: {exc}"
            ax.set_title(f"{law}: calibration failed", fontsize=9)
            ax.set_axis_off()
            continue
        ctx.calibrations[law] = cal
        summ = cal.summary.reset_index()
        summ.insert(0, "law", law)
        summaries.append(summ)
        pred = predict(cal, test, n=s.predict_draws, seed=s.seed)
        fit_rows.append({"law": law, "nrmse": float(pred.nrmse), "nrmse_map": float(pred.nrmse_map),
                         "coverage": float(pred.coverage), "sigma_kN": float(cal.sigma),
                         "converged": bool(cal.converged),
                         "acceptance": float(np.mean(cal.diagnostics.get("acceptance", np.nan))),
                         "max_rhat": float(cal.summary["R-hat"].max()),
                         "min_ess": float(cal.summary["ESS"].min()),
                         "seconds": time.perf_counter() - t0})
        _plot_prediction(ax, test, pred, f"{law} on protocol1 ({SYNTHETIC})")
    if not fit_rows:
        raise RuntimeError("every calibration failed: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    fits = pd.DataFrame(fit_rows)
    ctx.results["calibration_nrmse"] = dict(zip(fits["law"], fits["nrmse"]))
    sec.add_table("fit", fits, "Fit on protocol 1 per law: NRMSE of the posterior mean and of the MAP, "
                  "coverage of the 95 % band with noise, noise sd, convergence diagnostics.")
    sec.add_table("posteriors", pd.concat(summaries, ignore_index=True),
                  "Posterior summaries (mean, MAP, sd, 95 % interval, ESS, R-hat) per law.")
    sec.add_figure("fits", fig, "Measured loop (grey), posterior mean and 95 % band (with noise) per law.")
    best = fits.loc[fits["nrmse"].idxmin()]
    worst = fits.loc[fits["nrmse"].idxmax()]
    n_conv = int(fits["converged"].sum())
    reading = (
        f"{len(fits)} laws were calibrated on protocol 1 ({SYNTHETIC}). The closest fit is "
        f"{best['law']} (NRMSE {_pct(best['nrmse'])}, noise sd {fmt(best['sigma_kN'], 3)} kN, band "
        f"coverage {_pct(best['coverage'])}); the loosest is {worst['law']} (NRMSE "
        f"{_pct(worst['nrmse'])}). {n_conv} of {len(fits)} chains met the convergence rule (>= 50 "
        f"autocorrelation times, R-hat < 1.05)"
    )
    if n_conv < len(fits):
        bad = ", ".join(fits.loc[~fits["converged"], "law"])
        reading += f"; {bad} did not"
        reading += ", as expected of the short chains of a quick run" if s.quick else ""
    sec.reading = reading + "."
    if failed:
        sec.reading += (f" The calibration of {', '.join(failed)} failed (below); the other steps go on "
                        "without it.")
        raise RuntimeError("calibration failed for " + "; ".join(f"{k}: {v}" for k, v in failed.items()))


def _plot_prediction(ax, test, pred: Any, title: str) -> None:
    """Loop of the test, the posterior mean and the band (its edges, as the loop is not monotonic)."""
    d_mm = 1e3 * np.asarray(test.disp)
    ax.plot(d_mm, test.force, lw=0.6, color="0.55", label="test")
    ax.plot(d_mm, pred.lower, lw=0.4, color="tab:blue", alpha=0.45, label="95 % band")
    ax.plot(d_mm, pred.upper, lw=0.4, color="tab:blue", alpha=0.45)
    ax.plot(d_mm, pred.mean, lw=0.9, color="tab:red", label="posterior mean")
    ax.set_title(f"{title}: NRMSE {_pct(pred.nrmse)}", fontsize=9)
    ax.set_xlabel("shear displacement [mm]")
    ax.set_ylabel("shear force [kN]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


# ---------------------------------------------------------------------------------------------
# step 3: comparison
# ---------------------------------------------------------------------------------------------
def step_compare(ctx: DemoContext, sec: Section) -> None:
    compare = _api("rrfrei.calibration", "compare")
    cals = ctx.need("calibrations", "calibration")
    res = compare(dict(cals))
    table = res.table.reset_index()
    ctx.best_law = res.best
    ctx.results["comparison"] = res
    sec.add_table("criteria", table, "elpd (higher is better), effective parameters p, standard error se, "
                  "se of the difference to the best dse and stacking weights, for PSIS-LOO, WAIC and "
                  "leave-one-cycle-out (LOCO); k_max: largest Pareto k.")
    sec.add_table("pareto_k", res.pareto_k.reset_index(), "Pareto k counts of PSIS-LOO per law.")
    sec.add_table("loco_cycles", res.loco_cycles, "Leave-one-cycle-out elpd per cycle and law.")
    sec.add_figure("elpd", res.figure(), "elpd +- se per law and criterion.")
    t = res.table
    best, second = t.index[0], t.index[1]
    diff = float(t.loc[best, "elpd_loo"] - t.loc[second, "elpd_loo"])
    dse = float(t.loc[second, "dse_loo"])
    ratio = diff / dse if dse > 0 else float("inf")
    verdict = ("a clear difference" if ratio > 2 else
               "within about two standard errors: the data hardly separate them")
    loco_best = str(t["elpd_loco"].idxmax())
    waic_best = str(t["elpd_waic"].idxmax())
    worst_k = float(t["k_max_loo"].max())
    reading = (
        f"PSIS-LOO ranks {best} first (elpd {fmt(t.loc[best, 'elpd_loo'], 5)} +- "
        f"{fmt(t.loc[best, 'se_loo'], 3)}), ahead of {second} by {fmt(diff, 3)} with a standard error "
        f"of the difference of {fmt(dse, 3)} ({fmt(ratio, 2)} se: {verdict}). WAIC "
        f"{'agrees' if waic_best == best else f'prefers {waic_best}'}, and leave-one-cycle-out, which "
        f"holds out whole cycles and so judges prediction of unseen loops, "
        f"{'agrees' if loco_best == best else f'prefers {loco_best}'}. "
    )
    reading += (f"The largest Pareto k is {fmt(worst_k, 3)}"
                + (" (above 0.7: some LOO estimates are unreliable)." if worst_k > 0.7
                   else " (below 0.7: the LOO estimates are reliable)."))
    reading += f" The best law, {best}, is carried into the next steps."
    sec.reading = reading


# ---------------------------------------------------------------------------------------------
# step 4: validation
# ---------------------------------------------------------------------------------------------
def step_validate(ctx: DemoContext, sec: Section) -> None:
    predict = _api("rrfrei.calibration.checks", "predict")
    tests = ctx.need("tests", "tests")
    best = ctx.best_law
    if best is None:
        raise RuntimeError("this step needs the best law from the 'comparison' step, which did not finish")
    cal = ctx.calibrations[best]
    s = ctx.settings
    rows, cycles = [], []
    fig, axes = _figure(1, 3, size=(11.0, 3.8))
    for ax, name in zip(axes.ravel(), TESTS[1:]):
        pred = predict(cal, tests[name], n=s.predict_draws, seed=s.seed)
        d = pred.as_dict()
        rows.append({"test": name, "nrmse": float(pred.nrmse), "nrmse_map": float(pred.nrmse_map),
                     "coverage": float(pred.coverage), "coverage_param": float(pred.coverage_param),
                     "energy_test_kNm": d["energy_test"] if len(pred.cycles) else 0.0,
                     "energy_map_kNm": d["energy_map"] if len(pred.cycles) else 0.0,
                     "cycles": len(pred.cycles)})
        if len(pred.cycles):
            cycles.append(pred.cycles.assign(test=name))
        _plot_prediction(ax, tests[name], pred, f"{best}: {name} held out")
    table = pd.DataFrame(rows)
    sec.add_table("holdout", table, f"Held-out predictions of {best} calibrated on protocol 1 "
                  f"({SYNTHETIC} tests): NRMSE, coverage of the 95 % band with noise (and of the "
                  "parameter-only band), energy dissipated over full cycles (test, MAP).")
    if cycles:
        sec.add_table("holdout_cycles", pd.concat(cycles, ignore_index=True),
                      "Per held-out cycle: energy, k_eff and beta_eff of the test, the MAP and the band.")
    sec.add_figure("holdout", fig, "Held-out tests (grey) against the posterior mean and 95 % band.")
    worst = table.loc[table["nrmse"].idxmax()]
    cal_nrmse = ctx.results.get("calibration_nrmse", {}).get(best)
    reading = (
        f"{best}, calibrated on protocol 1 only, predicts the held-out {SYNTHETIC} protocols 2-4 with "
        f"NRMSE between {_pct(table['nrmse'].min())} and {_pct(table['nrmse'].max())}; the hardest is "
        f"{worst['test']}"
    )
    if cal_nrmse is not None:
        ratio = float(table["nrmse"].mean()) / cal_nrmse
        reading += (f", and on average the error is {fmt(ratio, 2)} times the calibration error "
                    f"({_pct(cal_nrmse)})")
    lo, hi = float(table["coverage"].min()), float(table["coverage"].max())
    reading += (
        f". The 95 % band holds {_pct(lo)} to {_pct(hi)} of the held-out points: "
        + ("about the nominal 95 %, so the uncertainty is honest." if lo >= 0.9 else
           "below the nominal 95 %, so the law misses something the held-out tests show (see the gap "
           "step).")
    )
    e = table[table["cycles"] > 0]
    if len(e):
        err = (e["energy_map_kNm"] - e["energy_test_kNm"]) / e["energy_test_kNm"]
        k = int(np.argmax(np.abs(err.to_numpy())))
        reading += (f" The MAP {'over' if err.iloc[k] > 0 else 'under'}estimates the energy dissipated "
                    f"in {e['test'].iloc[k]} by {_pct(abs(err.iloc[k]))}.")
    sec.reading = reading


# ---------------------------------------------------------------------------------------------
# step 5: gap
# ---------------------------------------------------------------------------------------------
def step_gap(ctx: DemoContext, sec: Section) -> None:
    diagnose_gap = _api("rrfrei.gap", "diagnose_gap")
    gap_figures = _api("rrfrei.gap.report", "figures")
    tests = ctx.need("tests", "tests")
    best = ctx.best_law
    if best is None:
        raise RuntimeError("this step needs the best law from the 'comparison' step, which did not finish")
    s = ctx.settings
    holdout = [tests[n] for n in TESTS[1:]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = diagnose_gap(tests["protocol1"], best, holdout=holdout, draws=s.gap_draws, seed=s.seed,
                           progress=ctx.progress)
    ctx.results["gap"] = rep
    rows = []
    for e in rep.ranking:
        rows.append({"effect": e.effect, "law": e.law, "screen": e.screen, "delta_elpd": e.delta_elpd,
                     "se": e.se, "delta_holdout": e.delta_holdout, "se_holdout": e.se_holdout,
                     "gap_calibration": e.calibration.gap, "systematic_calibration": e.calibration.systematic,
                     "gap_holdout": e.holdout.gap if e.holdout is not None else float("nan"),
                     "shrink_calibration": e.shrink_calibration, "shrink_holdout": e.shrink_holdout,
                     "significant": bool(e.significant), "note": e.note or "-"})
    ranking = _na_as_text(pd.DataFrame(rows), ("screen", "delta_holdout", "se_holdout", "gap_holdout",
                                                "shrink_calibration", "shrink_holdout"))
    metrics = []
    for label, (m_cal, m_hold) in (("baseline " + best, rep.baseline),
                                   ("final " + "+".join([best, *rep.combination]), rep.final)):
        for on, m in (("calibration (protocol1)", m_cal), ("held out (protocols 2-4)", m_hold)):
            if m is not None:
                metrics.append({"model": label, "on": on, **m.as_dict()})
    metrics_df = _na_as_text(pd.DataFrame(metrics), ("energy_error",))
    where = _na_as_text(rep.where.reset_index(drop=True), ("energy_error", "coverage", "bias"))
    sec.add_table("gap", metrics_df, "Gap = NRMSE, its systematic part sqrt(max(MSE - sigma^2, 0)) / "
                  "RMS(measured), energy-per-cycle error and band coverage, before and after the effects.")
    sec.add_table("ranking", ranking, "Each catalogue effect added to the baseline: residual screen, "
                  "leave-one-cycle-out elpd gain (se), held-out score gain, gaps and shrink of the "
                  "systematic gap.")
    sec.add_table("where", where, "Where the baseline misses: segments of protocol 1 ranked by excess "
                  "error over the noise.")
    for name, fig in gap_figures(rep).items():
        sec.add_figure(name.removesuffix(".png"), fig)
    b_cal, b_hold = rep.baseline
    f_cal, f_hold = rep.final
    top = rep.where.iloc[0] if len(rep.where) else None
    reading = f"Baseline {best} on protocol 1 ({SYNTHETIC}): gap (NRMSE) {_pct(b_cal.gap)}, of which the " \
              f"systematic part is {_pct(b_cal.systematic)}"
    if b_hold is not None:
        reading += f"; on the held-out protocols 2-4 the gap is {_pct(b_hold.gap)}"
    reading += "."
    if top is not None:
        reading += (f" The residuals concentrate in the {top['axis']} segment '{top['segment']}' "
                    f"({_pct(top['error_share'])} of the squared error, {fmt(top['rms_over_noise'], 3)} "
                    f"times the noise level).")
    if rep.diagnosis == "none":
        reading += (" No catalogue effect improves the expected predictive accuracy significantly: the "
                    "diagnosis is 'none'.")
    else:
        winner = next(e for e in rep.ranking if e.effect == rep.diagnosis)
        reading += (f" The diagnosis is '{rep.diagnosis}': adding it gains {fmt(winner.delta_elpd, 3)} "
                    f"(se {fmt(winner.se, 3)}) in leave-one-cycle-out elpd")
        if math.isfinite(winner.shrink_holdout):
            reading += f" and shrinks the held-out systematic gap by {_pct(winner.shrink_holdout)}"
        reading += "."
        if len(rep.combination) > 1:
            reading += f" The greedy combination is {' + '.join(rep.combination)}."
        reading += f" With it the calibration gap goes from {_pct(b_cal.gap)} to {_pct(f_cal.gap)}"
        if b_hold is not None and f_hold is not None:
            reading += f" and the held-out gap from {_pct(b_hold.gap)} to {_pct(f_hold.gap)}"
        reading += "."
    for note in rep.notes:
        sec.notes.append(note)
    sec.reading = reading


def _na_as_text(df: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """Write 'n/a' (not applicable) instead of NaN in the given columns, leaving them as text.

    Used only where a NaN means 'not defined' (e.g. the energy error of a segment without a full
    cycle, a held-out score without held-out tests); every other column must hold finite numbers.
    """
    out = df.copy()
    for c in columns:
        if c in out.columns and out[c].isna().any():
            out[c] = [fmt(v) for v in out[c]]
    return out


# ---------------------------------------------------------------------------------------------
# step 6: propagation
# ---------------------------------------------------------------------------------------------
def step_propagate(ctx: DemoContext, sec: Section) -> None:
    propagate = _api("structures.propagate", "propagate")
    load_building = _api("structures", "load_building")
    Isolator = _api("structures", "Isolator")
    available = _api("ground_motions", "available")
    best = ctx.best_law
    if best is None:
        raise RuntimeError("this step needs the best law from the 'comparison' step, which did not finish")
    cal = ctx.calibrations[best]
    s = ctx.settings
    example = load_building(s.building)
    iso = example.isolator
    # the example building's bearings (count, similitude scale), now following the best law
    building = replace(example, isolator=Isolator(best, cal.map_params(), count=iso.count,
                                                  length_scale=iso.length_scale))
    records = tuple(s.records) if s.records is not None else tuple(available())
    rs = propagate(cal, building, records, n_samples=s.n_samples, scales=s.scales, seed=s.seed,
                   progress=ctx.progress)
    summary = rs.summary()
    split = rs.variance_split()
    exceed = rs.exceedance()
    sec.add_table("runs", rs.table, f"One row per analysis: {s.n_samples} posterior draws of {best} x "
                  f"{len(records)} records x {len(s.scales)} scale(s); prototype units (m, m/s^2, kN, kN m).")
    sec.add_table("percentiles", summary, "Median, 16/84 and 2.5/97.5 percentiles per record and over all "
                  "records, per scale (converged runs).")
    split_ok = split.dropna(subset=["share_params"])
    sec.add_table("variance_split", split_ok, "Share of Var(ln demand) explained by the isolator parameters "
                  "vs. the records (law of total variance); demands that are zero in some run have no "
                  "logarithm and are left out.")
    sec.add_table("exceedance", exceed, "P(demand > limit) per record and over all records.")
    if len(s.scales) > 1:
        frs = rs.fragility()
        sec.add_table("fragility", pd.DataFrame(
            [{"demand": f.demand, "limit": f.limit, "theta": f.theta, "beta": f.beta,
              "stripes": len(f.im), "note": f.note} for f in frs if np.isfinite(f.theta)]),
            "Lognormal fragility curves fitted across the scales (maximum likelihood, Baker 2015); "
            "curves that cannot be fitted (no or all runs exceeding) are left out.")
        sec.add_figure("fragility", rs.plot_fragility(), "Fragility curves.")
    sec.add_figure("distributions", rs.plot_distributions("iso_disp_peak_m", scale=1.0 if 1.0 in s.scales
                                                          else s.scales[0]),
                   "Peak isolator displacement per record over the posterior draws.")
    sec.add_figure("exceedance", rs.plot_exceedance("iso_disp_peak_m", scale=1.0 if 1.0 in s.scales
                                                    else s.scales[0]),
                   "Exceedance curves of the peak isolator displacement.")
    scale = 1.0 if 1.0 in s.scales else s.scales[0]
    row = summary[(summary["demand"] == "iso_disp_peak_m") & (summary["record"] == "all records")
                  & (summary["scale"] == scale)].iloc[0]
    drift = summary[(summary["demand"] == "drift_ratio_max") & (summary["record"] == "all records")
                    & (summary["scale"] == scale)].iloc[0]
    per_rec = summary[(summary["demand"] == "iso_disp_peak_m") & (summary["record"] != "all records")
                      & (summary["scale"] == scale)]
    worst_rec = per_rec.loc[per_rec["median"].idxmax()]
    lim = rs.limits.get("iso_disp_peak_m")
    p_ex = exceed[(exceed["demand"] == "iso_disp_peak_m") & (exceed["record"] == "all records")
                  & (exceed["scale"] == scale)]["p_exceed"]
    sp = split[(split["demand"] == "iso_disp_peak_m") & (split["scale"] == scale)]["share_params"]
    n_conv = int(rs.table["converged"].astype(bool).sum())
    reading = (
        f"{len(rs.table)} analyses of the {s.building.replace('_', '-')} example building with its "
        f"{iso.count} bearings following the {best} posterior ({n_conv} converged). At scale "
        f"{fmt(scale)} the peak isolator displacement has a median of {fmt(1e3 * row['median'], 3)} mm "
        f"over all records (16-84 %: {fmt(1e3 * row['p16'], 3)}-{fmt(1e3 * row['p84'], 3)} mm); "
        f"{worst_rec['record']} drives it hardest (median {fmt(1e3 * worst_rec['median'], 3)} mm). "
        f"The median peak story drift ratio is {_pct(drift['median'])}."
    )
    if lim is not None and len(p_ex):
        pe = float(p_ex.iloc[0])
        beyond = f"beyond {fmt(1e3 * lim, 3)} mm (the largest displacement tested, at prototype scale)"
        reading += (f" None of the runs takes the isolator {beyond}" if pe == 0 else
                    f" The chance that the isolator goes {beyond} is {_pct(pe)}")
        ext = rs.extrapolated_share()
        reading += (f"; {_pct(ext)} of the runs leave the calibrated range, where the law extrapolates."
                    if np.isfinite(ext) else ".")
    if len(sp) and np.isfinite(sp.iloc[0]):
        reading += (f" The isolator parameters explain {_pct(float(sp.iloc[0]))} of the variance of the "
                    f"log peak isolator displacement; the records explain most of the rest"
                    if float(sp.iloc[0]) < 0.5 else
                    f" The isolator parameters explain {_pct(float(sp.iloc[0]))} of the variance of the "
                    f"log peak isolator displacement, more than the records")
        reading += " (law of total variance)."
    sec.reading = reading


# ---------------------------------------------------------------------------------------------
# step 7: rubber
# ---------------------------------------------------------------------------------------------
def step_rubber(ctx: DemoContext, sec: Section) -> None:
    rubber = _api("rubber")
    fit = _api("rubber", "fit")
    synthetic_test = _api("rubber.study", "synthetic_test")
    load_vhb = _api("rubber.io", "load_vhb4910")
    s = ctx.settings
    truth = rubber.PRESETS["A"]
    noise = 0.01  # MPa
    p1 = synthetic_test(truth, "p1", noise=noise, seed=s.seed)
    p2 = synthetic_test(truth, "p2", noise=noise, seed=s.seed + 1)
    vhb = load_vhb()
    kw = {"seed": s.seed, "restarts": s.rubber_restarts, "max_evals": s.rubber_evals}
    jobs = {"both protocols": ([p1, p2], {}), "VHB 4910 (real)": ([vhb], {"bounds": "auto"})}
    if not s.quick:  # the cross-prediction study: each protocol alone too
        jobs = {"protocol 1": ([p1], {}), "protocol 2": ([p2], {}), **jobs}
    fits = {}
    for label in _tqdm(list(jobs), ctx.progress, desc="rubber fits", unit="fit", leave=False):
        tests, extra = jobs[label]
        fits[label] = fit(tests, **kw, **extra)
    # every synthetic fit on every synthetic protocol (cross-prediction); the VHB fit on its data
    objective = _api("rubber", "objective")
    rows = []
    for label, r in fits.items():
        on = [vhb] if label.startswith("VHB") else [p1, p2]
        for t in on:
            f = float(objective(r.params, [t])[0])
            rows.append({"fit": label, "evaluated_on": t.name, "data": "real" if t is vhb else SYNTHETIC,
                         "fitted_to_it": t.name in r.f, "f": f, "rms_error": math.sqrt(f),
                         "evaluations": int(r.evaluations)})
    table = pd.DataFrame(rows)
    params = pd.DataFrame({label: r.params.as_dict() for label, r in fits.items()})
    params.insert(0, "truth (preset A, synthetic)", pd.Series(truth.as_dict()))
    params.index.name = "parameter"
    combos = pd.DataFrame({label: r.combinations for label, r in fits.items()})
    combos.index.name = "combination"
    ident = pd.DataFrame({label: pd.Series(r.rel_sigma, dtype=float) for label, r in fits.items()})
    ident.index.name = "parameter"
    sec.add_table("fits", table, "Objective f = sum (s_exp - s_pred)^2 / sum s_exp^2 per test; rms_error = "
                  "sqrt(f per test), the relative RMS misfit.")
    sec.add_table("parameters", params.reset_index(), "Fitted PRF parameters (MPa, s) and the preset the "
                  "synthetic protocols were made from.")
    sec.add_table("combinations", combos.reset_index(), "Identifiable combinations: small-strain moduli per "
                  "chain [MPa], flow thresholds [MPa], equilibrium stress at three stretches [MPa].")
    sec.add_table("identifiability", ident.reset_index(), "Relative change of each free parameter that "
                  "raises f by 1e-4 with the others re-optimised: above 1, practically unidentifiable.")
    fig, axes = _figure(1, 3, size=(12.0, 3.8))
    both = fits["both protocols"]
    for ax, t, r, title in ((axes[0, 0], p1, both, f"protocol 1 ({SYNTHETIC})"),
                            (axes[0, 1], p2, both, f"protocol 2 ({SYNTHETIC})"),
                            (axes[0, 2], vhb, fits["VHB 4910 (real)"], "VHB 4910 (real data)")):
        model = rubber.simulate(r.params, t.time, t.stretch).nominal
        ax.plot(t.time, t.stress, lw=0.8, color="0.45", label="data")
        ax.plot(t.time, model, lw=0.9, color="tab:red", label="PRF fit")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("nominal stress [MPa]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    sec.add_figure("fits", fig, "Stress histories: data against the fitted PRF model.")
    def rms(fit_label: str, test_name: str) -> float:
        row = table[(table["fit"] == fit_label) & (table["evaluated_on"] == test_name)]
        return float(row["rms_error"].iloc[0])

    both_rms = math.sqrt(both.f_total / len(both.f))
    unident = sorted(n for n, v in both.rel_sigma.items() if v is not None and v > 1)
    mu_true = _api("rubber.fit", "combinations")(truth)
    mu_err = max(abs(both.combinations[k] / mu_true[k] - 1) for k in ("mu0_A", "mu0_B", "mu0_C"))
    reading = (
        f"The polyurethane (PRF) model fitted to both {SYNTHETIC} protocols (made from preset A with "
        f"{fmt(noise)} MPa noise) misfits them by {_pct(both_rms)} RMS; its small-strain chain moduli are "
        f"within {_pct(mu_err)} of the truth"
    )
    reading += (f", while {', '.join(unident)} {'is' if len(unident) == 1 else 'are'} practically "
                "unidentifiable from these data." if unident else ".")
    if "protocol 1" in fits:
        cross = rms("protocol 1", p2.name) / max(rms("protocol 2", p2.name), 1e-300)
        reading += (f" Fitted to protocol 1 alone, it predicts protocol 2 with {fmt(cross, 3)} times the "
                    f"RMS error of a fit to protocol 2 itself.")
    reading += (f" On the real VHB 4910 data (Miles et al.) the fit reaches an RMS misfit of "
                f"{_pct(rms('VHB 4910 (real)', vhb.name))}.")
    if s.quick:
        reading += " (Quick run: one short CMA-ES run per fit.)"
    sec.reading = reading


STEPS: tuple[Step, ...] = (
    Step("tests", f"The bundled isolator tests ({SYNTHETIC})", step_tests),
    Step("calibration", "Calibration of four laws on protocol 1", step_calibrate),
    Step("comparison", "Which law? LOO, WAIC and leave-one-cycle-out", step_compare),
    Step("validation", "The best law on held-out protocols 2-4", step_validate),
    Step("gap", "Sim-to-real gap: where, which effect, how much it shrinks", step_gap),
    Step("propagation", "The best posterior on the 5-story example building", step_propagate),
    Step("rubber", "Polyurethane (PRF) model fits", step_rubber),
)


# ---------------------------------------------------------------------------------------------
# the pipeline
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DemoResult:
    """Where the page is, the report object and the status of every step."""

    page: Path
    report: Report
    seconds: float

    @property
    def ok(self) -> bool:
        return self.report.ok

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(s.key for s in self.report.sections if s.status != "ok")


def run_step(step: Step, ctx: DemoContext) -> Section:
    """Run one step into a fresh section; errors and placeholders are caught into the section."""
    sec = Section(step.key, step.title)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        step.func(ctx, sec)
        if not sec.reading:
            raise RuntimeError(f"step {step.key!r} produced no reading")
    except Placeholder as exc:
        sec.placeholder = True
        sec.reading = f"Placeholder: {exc}."
    except EXPECTED_FAILURES as exc:  # a failing step must not kill the page; a bug (TypeError,
        # AttributeError, ...) is not caught: it must show, not hide in a page
        tb = traceback.extract_tb(exc.__traceback__)[-3:]
        where = "".join(traceback.format_list(tb))
        sec.error = f"{type(exc).__name__}: {exc}\n\nWhere:\n{where}"
    sec.seconds = time.perf_counter() - t0
    sec.cpu_seconds = time.process_time() - c0
    return sec


def run_demo(
    out: str | Path = "rrfrei-report",
    *,
    quick: bool = False,
    seed: int = 0,
    progress: bool = True,
    settings: DemoSettings | None = None,
    steps: Sequence[Step] | None = None,
) -> DemoResult:
    """Run every step and write the page ``out/index.html`` with its tables and manifest.

    Parameters
    ----------
    out : folder to write (created if needed).
    quick : fewer walkers/steps, samples, records and a shorter rubber fit (the page says so).
    seed : seed of every stochastic step.
    progress : show tqdm progress bars on the long steps.
    settings : explicit step sizes (overrides ``quick``/``seed``).
    steps : the steps to run (default :data:`STEPS`).

    Returns
    -------
    DemoResult with ``ok`` False when a step failed or is a placeholder.
    """
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    if settings is None:
        settings = DemoSettings.quick_run(int(seed)) if quick else DemoSettings.full_run(int(seed))
    else:
        settings = replace(settings)
    steps = STEPS if steps is None else tuple(steps)
    import rrfrei

    report = Report(
        "rrfrei: from isolator tests to building response",
        intro=(
            "Every workflow of rrfrei run on the bundled data: calibration of four isolator laws on a "
            "cyclic shear test, model comparison, validation on held-out tests, sim-to-real gap "
            "diagnosis, propagation of the posterior through ground motions on an example "
            "building, and the polyurethane model fits. Every reading below is computed from the "
            "numbers of this run."
        ),
    )
    report.banner(
        f"The isolator tests are {SYNTHETIC} RR-FREI-like tests (made by an independent model with "
        "noise); no real RR-FREI test data are public.",
        "synthetic",
    )
    if settings.quick:
        report.banner(
            "This is a QUICK run (--quick): short chains, few samples and records, a short rubber "
            "fit. Numbers are indicative only; run without --quick for the full analysis.",
            "note",
        )
    report.meta.update(
        {
            "rrfrei version": rrfrei.__version__,
            "run": "quick" if settings.quick else "full",
            "seed": settings.seed,
            "date": time.strftime("%Y-%m-%d %H:%M"),
        }
    )
    # inner bars (optimiser, sampler, gap, propagation, fits) only on a terminal: in a log every
    # tqdm refresh is a new line, and the step bar below says enough
    inner = progress and stderr_is_tty()
    ctx = DemoContext(settings=settings, progress=inner)
    t0 = time.perf_counter()
    bar = _tqdm(steps, progress, desc="rrfrei demo", unit="step")
    for step in bar:
        if hasattr(bar, "set_postfix_str"):
            bar.set_postfix_str(step.key)
        report.add(run_step(step, ctx))
    seconds = time.perf_counter() - t0
    report.meta["total time"] = f"{seconds:.0f} s"
    page = report.write(out)
    return DemoResult(page=page, report=report, seconds=seconds)


def _tqdm(iterable, progress: bool, **kw):
    if not progress:
        return iterable
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return iterable
    return tqdm(iterable, **kw)

