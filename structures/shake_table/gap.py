"""The sim-to-real gap of a base-isolated building on shake-table runs (issues 15 and 27).

:func:`shake_table_gap` answers, on real runs, *does my calibrated building predict the next,
larger earthquake, where does it miss, why, and what fixes it?*  The model is the building
(:mod:`structures.shake_table.building_model`), not the isolator loop:

1. **Superstructure.** From :func:`structures.identify_superstructure` on the calibration run
   where it holds (every story R^2 >= 0.8 and k, c > 0; the best such run by its worst R^2), or
   from a building TOML.  It is identified first, so a calibration set without a usable
   superstructure is a user error reported in seconds.
2. **Loop fit (the start).** The isolation tests (d_0 against F = -sum_i m_i a_i) of the
   calibration runs, decimated to ``rate_hz``, joined in chronological order, are fitted by the
   isolator law (equation error, :class:`rrfrei.gap.model.IsolatorModel`); ``law="auto"`` keeps
   the law of :data:`AUTO_LAWS` with the highest leave-one-cycle-out elpd.  This fit starts the
   building's calibration and is reported as the comparison row (``loop_fit``).
3. **Output-error calibration and diagnosis.** :class:`structures.shake_table.building_model.BuildingModel`
   simulates the building driven by every run's measured table acceleration, in order, ``pad_s``
   seconds of rest between runs, the isolators' state carried; the law's, the superstructure's
   stiffness scale and damping, and the effects' parameters are fitted to the measured isolator
   displacement, isolation-layer force and roof acceleration (each normalised; residual model and
   posterior in that module).  The gap engine (:func:`rrfrei.gap.diagnose`) diagnoses it: every
   catalogue effect and every system effect (isolation-layer viscous damping, superstructure
   softening with amplitude) is fitted by output error on the calibration runs only and judged on
   the held-out runs' simulated responses, blocks of 10 s time windows holding every fitted
   channel (the engine's block rule: verdict, evidence, shrink with its bootstrap interval).
4. **Predictions.** Every run, calibration and held-out, is predicted by the baseline building and
   by the final one (with the named effects): per run and channel the NRMSE of the median, the
   peak error, the coverage of the predictive 95 % band (posterior draws plus the residual model)
   and its width over the measured RMS (``runs``).  Displacements are relative to each run's start.
5. **Building check.** Every candidate's optimum run once on the held-out runs.
6. **Where.** A residual table of the held-out predictions: share of the squared error by run,
   channel (isolator: ``isolator_disp``, ``isolator_force``; superstructure: ``base_shear``,
   ``roof_accel``), amplitude (|d_0| within / beyond the calibrated peak), time window (10 s) and
   frequency band.

Numerical robustness: a simulation that fails inside an optimiser is a bad point, a failed
posterior draw is left out of the bands (and counted); when the baseline cannot be fitted the
pipeline raises a :class:`rrfrei.errors.NumericalFailure` naming the law, the runs and the failure.
"""

from __future__ import annotations

import math
import os
import tempfile
import time as _time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.calibration.checks import nrmse
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.forkmap import ForkMap
from rrfrei.gap.catalogue import catalogue
from rrfrei.gap.diagnose import Checkpoint, GapReport, diagnose, loco
from rrfrei.gap.model import RETRY_SUBSTEPS, IsolatorModel, simulate_retry
from rrfrei.gap.parallel import default_workers
from rrfrei.io import ShearTest
from rrfrei.jsonable import number as _num
from rrfrei.notes import Note
from structures.building.shear_building import Isolator, ShearBuilding
from structures.shake_table import ShakeTableRun, available_runs, load_run, read_run
from structures.shake_table.building_fit import BuildingFit
from structures.shake_table.building_model import SYSTEM_EFFECTS, BuildingModel
from structures.shake_table.identify import identify_superstructure
from structures.shake_table.sequence import (
    CHANNELS,
    SequencePrediction,
    building_prediction,
    pooled,
    run_metrics,
)
from structures.shake_table.simulation import BuildingData, calibration_test
from structures.shake_table.where import residual_table

__all__ = ["AUTO_LAWS", "BNCS_ORDER", "MISFIT_NRMSE", "ShakeTableGap", "calibration_misfit", "resolve_run",
           "shake_table_gap", "simulate_law"]

BNCS_ORDER = ("CNP100", "LAC100", "ICA50", "ICA100")
"""The bundled runs in the order of the BNCS base-isolated test program (Chen et al. 2016; the
source data do not state it: this order is also the one in which the isolators' effective
stiffness falls, 4,350-5,650, 4,100-4,840, 3,990-4,560 then 3,070-3,600 kN/m)."""

BUILDING_HZ = 50.0
"""Default rate at which the building is fitted and simulated [Hz] (:func:`shake_table_gap`'s
``building_hz``): the bundled runs' rate; it resolves the isolated building's modes (0.4-2.6 Hz
here) and the superstructure's first fixed-base mode (1.6 Hz) many times over, and a 200 Hz run
costs four times the simulations without a change to what is compared."""

AUTO_LAWS = ("plasticity", "bouc_wen", "hdr")
"""The OpenSees laws ``law="auto"`` chooses from (``elastomeric_x`` needs bearing geometry)."""

SUBSTEPS = RETRY_SUBSTEPS
"""Sub-increments per sample tried, in turn, when an isolator simulation fails."""


# ---------------------------------------------------------------------------------------------
# runs and isolation tests
# ---------------------------------------------------------------------------------------------
def resolve_run(spec: str | Path | ShakeTableRun) -> ShakeTableRun:
    """A run from a bundled name (``"ICA50"``), a folder or a CSV (:func:`structures.read_run`)."""
    if isinstance(spec, ShakeTableRun):
        return spec
    s = str(spec)
    if s in available_runs():
        return load_run(s)
    if not Path(s).exists():
        raise ValueError(f"run {s!r} is neither a bundled run ({', '.join(available_runs())}) nor an "
                         "existing folder or CSV file")
    return read_run(s)


def simulate_law(spec, p: np.ndarray, test: ShearTest) -> tuple[int, np.ndarray]:
    """Force [kN] of law ``spec`` with parameters ``p`` on ``test``'s samples, driven first
    through its ``preceding`` tests (:meth:`rrfrei.io.ShearTest.after`: the state they leave is
    carried in); a failing local solve is retried with :data:`SUBSTEPS` sub-increments per sample
    (:func:`rrfrei.gap.model.simulate_retry`).  Returns (status, force): status 0 on success."""
    status, F, _ = simulate_retry(spec, p, test)
    return status, F


# ---------------------------------------------------------------------------------------------
# the pipeline
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ShakeTableGap:
    """Result of :func:`shake_table_gap` (see the module docstring).

    ``verdict``: the one answer (an effect, ``"none"``, ``"unexplained"`` or ``"incomplete"``,
    :attr:`rrfrei.gap.GapReport.verdict`); ``diagnosis`` is the same string (kept for old callers).
    ``gap_before`` / ``gap_after``: {"calibration": {channel: NRMSE}, "holdout": {...}} of the
    building fitted by output error without effects and with the named ones; ``runs``: run ->
    channel -> {nrmse, peak_error, coverage, coverage_low, coverage_high, band_width} of the final
    model on every calibration and held-out run (``coverage_low`` / ``coverage_high``: the 90 %
    block-bootstrap interval of the coverage, :func:`structures.shake_table.sequence.coverage_interval`);
    ``coverage`` / ``band_width`` / ``coverage_interval``: the same pooled over the held-out runs;
    ``coverage_parameter_band``: coverage of the parameter band alone; ``extrapolation``:
    held-out run -> its peak |d_0| over the calibration runs' peak; ``building_check``: held-out
    NRMSE per channel of the optimum of the baseline and of every candidate (one analysis each);
    ``loop_fit``: the comparison row, held-out NRMSE per channel of the building whose isolator is
    the loop fit (equation error) and whose superstructure is the identified one.
    """

    law: str
    final_law: str
    diagnosis: str
    combination: tuple[str, ...]
    calibrate: tuple[str, ...]
    holdout: tuple[str, ...]
    order: tuple[str, ...]
    rate_hz: float
    report: GapReport
    law_scores: pd.DataFrame
    identified_on: str
    building: ShearBuilding
    before: SequencePrediction
    after: SequencePrediction
    gap_before: dict
    gap_after: dict
    coverage: dict
    coverage_parameter_band: dict
    coverage_before: dict
    error_sd: dict
    extrapolation: dict
    calibrated_peak: float
    where: pd.DataFrame
    building_check: pd.DataFrame
    notes: tuple[str, ...]
    elapsed: float
    seconds: dict
    runs: dict = field(default_factory=dict)
    band_width: dict = field(default_factory=dict)
    coverage_interval: dict = field(default_factory=dict)
    loop_fit: dict = field(default_factory=dict)
    final_fit: BuildingFit | None = field(default=None, repr=False)
    base_fit: BuildingFit | None = field(default=None, repr=False)
    cpu_seconds: float = float("nan")
    building_hz: float = float("nan")
    """Rate at which the building was fitted and simulated [Hz] (the runs' after decimation)."""

    @property
    def verdict(self) -> str:
        return self.report.verdict or self.report.diagnosis

    def shrink(self) -> dict[str, float]:
        """Per channel, 1 - held-out NRMSE after / before."""
        b, a = self.gap_before["holdout"], self.gap_after["holdout"]
        return {c: (1.0 - a[c] / b[c]) if b[c] > 0 else math.nan for c in CHANNELS}

    def shrink_evidence(self) -> dict | None:
        """The named effect's held-out systematic-gap shrink with its block-bootstrap interval
        (:func:`rrfrei.gap.decision.shrink_ci`, all fitted channels, time-window blocks), against
        the building fitted by output error without it; None when no effect is named."""
        for s in self.report.steps[:1]:
            if s.shrink_ci is not None:
                return s.shrink_ci.as_dict()
        return None

    def building_best(self) -> dict | None:
        """The candidate of :attr:`building_check` with the lowest held-out isolator-displacement
        NRMSE and its shrink against the baseline optimum (None without held-out runs).  It is
        chosen by looking at the held-out runs: evidence for a diagnosis, not an independent test."""
        bc = self.building_check.dropna(subset=["isolator_disp"]) if len(self.building_check) else None
        if bc is None or not len(bc) or bc["effect"].iloc[0] != "baseline":
            return None
        row = bc.loc[bc["isolator_disp"].idxmin()]
        base = float(bc["isolator_disp"].iloc[0])
        return {"effect": str(row["effect"]), "law": str(row["law"]),
                "isolator_disp": float(row["isolator_disp"]), "baseline_isolator_disp": base,
                "shrink": 1.0 - float(row["isolator_disp"]) / base if base > 0 else math.nan}

    def as_dict(self) -> dict:
        """The JSON object of ``rrfrei shake-table --json``."""
        rep = self.report
        ff = self.final_fit
        return {
            "law": self.law,
            "verdict": self.verdict,
            "diagnosis": self.verdict,
            "evidence": rep.as_dict().get("evidence"),
            "combination": list(self.combination),
            "shrink": self.shrink_evidence(),
            "where": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                      for row in self.where.to_dict("records")],
            "ranking": [{"effect": e.effect, "variant": e.variant, "delta_elpd": _num(e.delta_elpd),
                         "se": _num(e.se), "delta_holdout": _num(e.delta_holdout),
                         "se_holdout": _num(e.se_holdout),
                         "shrink_calibration": _num(e.shrink_calibration),
                         "shrink_holdout": _num(e.shrink_holdout), "significant": bool(e.significant),
                         "shrink_ci": None if e.shrink_ci is None else e.shrink_ci.as_dict(), "why": e.why}
                        for e in rep.ranking],
            "extrapolation": {k: _num(v) for k, v in self.extrapolation.items()},
            "gap_before": _nums(self.gap_before),
            "gap_after": _nums(self.gap_after),
            "coverage": {k: _num(v) for k, v in self.coverage.items()},
            "band_width": {k: _num(v) for k, v in self.band_width.items()},
            "coverage_interval": {k: [_num(a), _num(b)] for k, (a, b) in self.coverage_interval.items()},
            "coverage_parameter_band": {k: _num(v) for k, v in self.coverage_parameter_band.items()},
            "shrink_holdout": {k: _num(v) for k, v in self.shrink().items()},
            "runs": {r: {c: {k: _num(v) for k, v in m.items()} for c, m in chans.items()}
                     for r, chans in self.runs.items()},
            "loop_fit": {k: ({c: _num(x) for c, x in v.items()} if isinstance(v, Mapping) else v)
                         for k, v in self.loop_fit.items()},
            "calibration": None if ff is None else {
                "method": "output error (building simulated from the table accelerations)",
                "params": {k: _num(v) for k, v in ff.params.items()},
                "residual_sd": {k: _num(v) for k, v in ff.sigma_c.items()},
                "residual_rho1": {k: _num(v) for k, v in ff.rho_c.items()},
                "importance_ess": _num(ff.ess), "draws": int(ff.X.shape[0]),
                "simulations": int(ff.nfev), "failed_simulations": int(ff.failed),
                "robust_simulations": int(getattr(ff, "robust_sims", 0))},
            "building_check": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                               for row in self.building_check.to_dict("records")],
            "building_best": (None if (bb := self.building_best()) is None
                              else {k: _num(v) if isinstance(v, float) else v for k, v in bb.items()}),
            "final_law": self.final_law,
            "calibrate": list(self.calibrate),
            "holdout": list(self.holdout),
            "order": list(self.order),
            "rate_hz": self.rate_hz,
            "building_hz": _num(self.building_hz),
            "superstructure_from": self.identified_on,
            "law_scores": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                           for row in self.law_scores.to_dict("records")],
            "isolator_gap": rep.as_dict()["gap_before"] | {"after": rep.as_dict()["gap_after"]},
            "complete": rep.complete,
            "skipped": dict(rep.skipped),
            "not_evaluated": dict(rep.not_evaluated),
            "failed_analyses": {"before": self.before.n_failed, "after": self.after.n_failed},
            "elapsed_s": _num(self.elapsed),
            "cpu_s": _num(self.cpu_seconds),
            "seconds": {k: _num(v) for k, v in self.seconds.items()},
            "notes": list(self.notes),
        }


MISFIT_NRMSE = 0.5
"""Calibration NRMSE of the baseline building above which its law is said not to describe it."""


def calibration_misfit(law: str, calibration_nrmse: Mapping[str, float]) -> Note | None:
    """A critical note when the building fitted by output error misses its own calibration runs.

    ``calibration_nrmse``: channel -> NRMSE of the baseline building on the calibration runs.  An
    error above :data:`MISFIT_NRMSE` of a channel's RMS on the data it was fitted to means that the
    law (with the identified superstructure) cannot follow this building, so its held-out errors
    and any effect named on top of it describe the law's failure, not the building.
    """
    bad = {c: v for c, v in calibration_nrmse.items() if not v <= MISFIT_NRMSE}
    if not bad:
        return None
    worst = ", ".join(f"{c} {v:.2f}" for c, v in bad.items())
    return Note(f"the building with {law!r} misses its own calibration runs (NRMSE {worst} > "
                f"{MISFIT_NRMSE:g}): this law cannot describe the building, so the held-out errors "
                f"and any effect named on it say little; try another law (--law auto picks by the "
                f"isolation loops)", "critical")


def _cpu() -> float:
    """CPU seconds of this process and of its ended child processes (the candidates' refits)."""
    t = os.times()
    return _time.process_time() + t.children_user + t.children_system


def _nums(d: Mapping) -> dict:
    return {k: ({c: _num(v) for c, v in sub.items()} if sub is not None else None) for k, sub in d.items()}


def _names(items) -> list[str]:
    out = []
    for x in items:
        out.extend(s.strip() for s in str(x).split(",") if s.strip())
    return out


def _pick_law(cal: ShearTest, laws: Sequence[str], draws: int, seed: int, budget: TimeBudget,
              notes: list[str], checkpoint, workers: int = 1) -> tuple[str, pd.DataFrame, dict]:
    """Fit each law in ``laws`` to the isolation loops and rank by leave-one-cycle-out elpd (PSIS)
    on ``cal``; every fit is saved in the ``checkpoint`` folder and reused as the loop fit that
    starts the output-error calibration.  ``workers`` > 1: the fits run in that many forked
    processes first (:class:`rrfrei.forkmap.ForkMap`), the same fits."""
    model = IsolatorModel(laws[0], draws=draws)
    groups = model.groups(cal)
    if workers > 1 and checkpoint is not None:
        # the laws' fits are independent: forked processes fit them into the checkpoint folder,
        # and the loop below restores them (a fit a process could not make is fitted there again)
        def prefit(law: str) -> float:
            t0 = _time.perf_counter()
            try:
                _loop_fit(law, cal, draws, seed, budget, checkpoint)
            except BaseException:  # noqa: BLE001 - fitted again below, where the failure is reported
                pass
            return _time.perf_counter() - t0

        with ForkMap(prefit, workers=workers) as fm:
            fit_s = dict(zip(laws, fm.map(list(laws))))
    else:
        fit_s = {}
    rows, fits = [], {}
    for law in laws:
        t0 = _time.perf_counter() - fit_s.get(law, 0.0)  # "seconds": the law's fit wherever it ran
        try:
            fit = _loop_fit(law, cal, draws, seed, budget, checkpoint)
            elpd = float(loco(fit.loglik(cal), groups).sum())
            nr = float(nrmse(np.asarray(cal.force), fit.predict(cal).mean))
        except BudgetExceeded:
            raise
        except NUMERICAL_ERRORS as exc:
            notes.append(f"law {law} left out of the choice: {type(exc).__name__}: {exc}")
            rows.append({"law": law, "loco_elpd": math.nan, "nrmse": math.nan,
                         "seconds": _time.perf_counter() - t0})
            continue
        fits[law] = fit
        rows.append({"law": law, "loco_elpd": elpd, "nrmse": nr, "seconds": _time.perf_counter() - t0})
    df = pd.DataFrame(rows).sort_values("loco_elpd", ascending=False, na_position="last")
    df = df.reset_index(drop=True)
    if not fits:
        raise NumericalFailure(f"no law of {', '.join(laws)} could be fitted to {cal.name!r}: "
                               + "; ".join(notes[-len(laws):]))
    return str(df["law"].iloc[0]), df, fits


def _loop_fit(law: str, cal: ShearTest, draws: int, seed: int, budget: TimeBudget | None, checkpoint):
    """The isolator law fitted to the isolation loops (equation error), read from or saved to the
    ``checkpoint`` folder."""
    m = IsolatorModel(law, draws=draws)
    ck = Checkpoint(checkpoint, m, cal, seed)
    fit = ck.get("baseline")
    if fit is None:
        fit = m.fit(cal, seed=seed, budget=budget)
        ck.put("baseline", m, fit)
    return fit


def _superstructure(cal_runs: Sequence[ShakeTableRun], building_toml, seed: int, notes: list[str]):
    """(identification run name or TOML path, identification or ShearBuilding) of the superstructure."""
    if building_toml is not None:
        b = ShearBuilding.from_toml(building_toml, isolator_params=None) \
            if not isinstance(building_toml, ShearBuilding) else building_toml
        return str(getattr(b, "name", "") or building_toml) if isinstance(building_toml, ShearBuilding) \
            else str(building_toml), b
    best, best_r2 = None, -math.inf
    for r in cal_runs:
        if r.rate_hz < 30.0:
            notes.append(f"superstructure not identified on {r.name}: {r.rate_hz:g} Hz is too slow for the "
                         "1-15 Hz band")
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = identify_superstructure(r, seed=seed, n_boot=20)
        ok = bool(np.all(ident.stiffness > 0) and np.all(ident.damping >= 0) and np.all(ident.r2 >= 0.8))
        if not ok:
            notes.append(f"superstructure not identified on {r.name}: story R^2 "
                         f"{np.round(ident.r2, 2).tolist()}, "
                         f"k {np.round(ident.stiffness / 1e3, 1).tolist()} MN/m "
                         "(needs R^2 >= 0.8 and k, c > 0 on every story)")
            continue
        if float(ident.r2.min()) > best_r2:
            best, best_r2 = ident, float(ident.r2.min())
    if best is None:
        raise ValueError("no calibration run gives a shear-building superstructure ("
                         + "; ".join(notes[-len(cal_runs):]) + "): calibrate on a run where the "
                         "identification holds (ICA50, ICA100 of the bundled ones) or give --building TOML")
    return best.run, best


def shake_table_gap(
    runs: Sequence[str | Path | ShakeTableRun] | None = None,
    *,
    calibrate: Sequence[str] | None = None,
    holdout: Sequence[str] | None = None,
    law: str = "auto",
    building: str | Path | ShearBuilding | None = None,
    rate_hz: float = 25.0,
    building_hz: float | None = BUILDING_HZ,
    effects: Sequence[str] | None = None,
    draws: int = 30,
    n_draws: int | None = None,
    pad_s: float = 10.0,
    seed: int = 0,
    time_budget: float | TimeBudget | None = None,
    progress: bool = False,
    checkpoint: str | Path | None = None,
    workers: int | None = None,
) -> ShakeTableGap:
    """Calibrate a base-isolated building by output error on shake-table runs, diagnose its gap to
    the held-out runs, and predict every run: the public entry point (module docstring).

    Parameters
    ----------
    runs : the runs in chronological order (bundled names, folders, CSVs or
        :class:`ShakeTableRun`\\ s, e.g. runs of a simulated building); default :data:`BNCS_ORDER`.
    calibrate, holdout : run names (as loaded) to calibrate on and to hold out; default every run
        but the last, and the last.  A name may hold several, comma-separated.
    law : base isolator law, or ``"auto"`` (best leave-one-cycle-out elpd of :data:`AUTO_LAWS` on
        the isolation loops).
    building : TOML of a :class:`ShearBuilding` (or one) whose superstructure (masses, story
        stiffness, damping) is used instead of the identified one; its isolator is replaced.
    rate_hz : rate of the isolation loops of the loop fit (the start) [Hz].
    building_hz : rate at which the building is fitted and simulated [Hz]: runs recorded at an
        integer multiple of it are decimated to it first (:meth:`ShakeTableRun.decimate`: zero-phase
        anti-alias low-pass at 0.4 x ``building_hz``, then every q-th sample), so that the raw 200 Hz
        folders and the bundled 50 Hz runs made from them give one answer; runs at another rate are
        kept as recorded (a note says so).  None: always as recorded.
    effects : candidates of the diagnosis (default: every catalogue effect and every system
        effect, :data:`structures.shake_table.building_model.SYSTEM_EFFECTS`); ``[]``: calibration only.
    draws : posterior draws per building fit (each is a simulation of the runs).
    n_draws : accepted for compatibility (the number of draws is ``draws``).
    pad_s : rest between runs in the building's record [s].
    time_budget : wall-clock limit [s] of the diagnosis; None: none.
    checkpoint : folder where every finished fit (loop fits and building fits) is saved and reused.
    workers : processes for the candidates' refits (:class:`rrfrei.gap.parallel.SharedRefits`); None:
        two on a machine with two or more cores.  The result is the same for any number.

    Returns
    -------
    ShakeTableGap : ``verdict``, ``shrink_evidence()`` (shrink with its interval), ``runs``
        (per-run, per-channel nrmse, peak_error, coverage, band_width), ``report`` (the
        :class:`rrfrei.gap.GapReport` of the building-level diagnosis).

    Raises
    ------
    ValueError : unknown run or law, a run in both sets, rates that do not match, no
        superstructure.
    NumericalFailure : the baseline cannot be fitted, or every building analysis fails.
    """
    t_start = _time.perf_counter()
    c_start = _cpu()
    if workers is None:
        workers = default_workers()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers = {workers!r} is invalid: expected an integer >= 1")
    seconds: dict[str, float] = {}
    budget = TimeBudget.of(time_budget, "shake-table gap", option="--time-budget")
    notes: list[str] = []
    loaded = [resolve_run(r) for r in (BNCS_ORDER if runs is None else runs)]
    names = [r.name for r in loaded]
    if len(set(names)) != len(names):
        raise ValueError(f"runs {names} repeat a name; every run must appear once")
    by_name = dict(zip(names, loaded))
    cal_names = _names(calibrate) if calibrate else names[:-1]
    ho_names = _names(holdout) if holdout is not None else [n for n in names[-1:] if n not in cal_names]
    for n in [*cal_names, *ho_names]:
        if n not in by_name:
            raise ValueError(f"run {n!r} of --calibrate/--holdout is not among the runs given "
                             f"({', '.join(names)})")
    if not cal_names:
        raise ValueError("--calibrate names no run; give at least one")
    both = sorted(set(cal_names) & set(ho_names))
    if both:
        raise ValueError(f"run(s) {', '.join(both)} are both calibrated on and held out")
    order = [n for n in names if n in cal_names or n in ho_names]
    unused = [n for n in names if n not in order]
    if unused:
        notes.append(f"runs {', '.join(unused)} are neither calibrated on nor held out: left out")
    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 4:
        raise ValueError(f"draws = {draws!r} is invalid: expected an integer >= 4")
    fs = loaded[0].rate_hz
    for r in loaded:
        if abs(r.rate_hz - fs) > 1e-6 * fs:
            raise ValueError(f"runs {loaded[0].name!r} ({fs:g} Hz) and {r.name!r} ({r.rate_hz:g} Hz) have "
                             "different sampling rates; give runs at one rate")
    if building_hz is not None:
        real = isinstance(building_hz, (int, float, np.integer, np.floating))
        if isinstance(building_hz, bool) or not (real and building_hz > 0):
            raise ValueError(f"building_hz = {building_hz!r} is invalid: expected a rate > 0 [Hz] or None")
        q = fs / float(building_hz)
        if fs > building_hz and abs(q - round(q)) <= 1e-6 * q:
            loaded = [r.decimate(float(building_hz)) for r in loaded]
            by_name = dict(zip(names, loaded))
            notes.append(f"runs recorded at {fs:g} Hz, decimated to {float(building_hz):g} Hz for the "
                         f"building (zero-phase anti-alias low-pass at {0.4 * float(building_hz):g} Hz)")
            fs = float(building_hz)
        elif fs > building_hz:
            notes.append(f"runs recorded at {fs:g} Hz, not a multiple of {float(building_hz):g} Hz: the "
                         "building is fitted and simulated at the recorded rate")
    known = (*catalogue(), *SYSTEM_EFFECTS)
    for e in effects or ():
        if e not in known:
            raise ValueError(f"unknown effect {e!r}; available: {', '.join(known)}")
    # 1. isolation tests, chronological, decimated (the loop fit: start and comparison row)
    t0 = _time.perf_counter()
    cal_seq = [n for n in order if n in cal_names]
    ho_seq = [n for n in order if n in ho_names]
    cal = calibration_test([by_name[n] for n in cal_seq], rate_hz)
    cal_peak = float(np.max(np.abs(np.concatenate([by_name[n].isolator_disp for n in cal_seq]))))
    extrapolation = {h: float(np.max(np.abs(by_name[h].isolator_disp)) / cal_peak) for h in ho_seq}
    seconds["isolation tests"] = _time.perf_counter() - t0
    # 2. the superstructure first: a run that cannot give one (or a building TOML that does not
    # fit the runs) is reported in seconds, before the minutes of fits
    t0 = _time.perf_counter()
    cal_runs = [by_name[n] for n in cal_seq]
    src, sup = _superstructure(cal_runs, building, seed, notes)
    if isinstance(sup, ShearBuilding) and sup.n_stories != loaded[0].n_levels - 1:
        raise ValueError(f"building {src!r} has {sup.n_stories} stories but the runs have "
                         f"{loaded[0].n_levels} levels ({loaded[0].n_levels - 1} stories)")
    seconds["superstructure"] = _time.perf_counter() - t0
    # 3. the loop fit (law choice with "auto")
    t0 = _time.perf_counter()
    tmp = None
    if checkpoint is None:
        tmp = tempfile.TemporaryDirectory(prefix="rrfrei-shake-")
        checkpoint = tmp.name
    try:
        loop_draws = 20
        if law == "auto":
            base_law, law_scores, loop_fits = _pick_law(cal, AUTO_LAWS, loop_draws, seed, budget, notes,
                                                        checkpoint, workers)
            loop = loop_fits[base_law]
        else:
            base_law = str(law)
            law_scores = pd.DataFrame(columns=["law", "loco_elpd", "nrmse", "seconds"])
            try:
                loop = _loop_fit(base_law, cal, loop_draws, seed, budget, checkpoint)
            except BudgetExceeded as exc:
                raise NumericalFailure(f"the loop fit of {base_law!r} did not finish within the time budget: "
                                       f"{exc}") from None
        seconds["loop fit"] = _time.perf_counter() - t0
        # 4. the building: output-error calibration and the diagnosis on the simulated runs
        t0 = _time.perf_counter()
        seq = tuple(by_name[n] for n in order)
        cal_data = BuildingData(seq, observed=tuple(cal_seq), pad_s=pad_s)
        ho_data = [BuildingData(seq, observed=(h,), pad_s=pad_s) for h in ho_seq]
        data_of = {n: cal_data for n in cal_seq} | {h: d for h, d in zip(ho_seq, ho_data)}
        scales = {c: float(np.sqrt(np.mean(np.concatenate([cal_data.measured(n)[c] for n in cal_seq]) ** 2)))
                  for c in CHANNELS}
        a_ref = max(cal_data.peak_table_accel(n) for n in cal_seq)
        model = BuildingModel(base_law, sup, cal, scales, draws=draws, loop_fit=loop, a_ref=a_ref)
        cands = list(model.candidate_effects) if effects is None else list(effects)
        try:
            rep = diagnose(model, cal_data, ho_data, effects=cands, seed=seed, progress=progress,
                           time_budget=budget, checkpoint=checkpoint, combine=True, max_combination=2,
                           workers=workers)
        except BudgetExceeded as exc:
            raise NumericalFailure(f"the output-error fit of the building with {base_law!r} did not finish "
                                   f"within the time budget: {exc}") from None
    finally:
        if tmp is not None:
            tmp.cleanup()
    seconds["building fits and diagnosis"] = _time.perf_counter() - t0
    # 5. predictions of every run, baseline and final
    t0 = _time.perf_counter()
    base_fit = rep.fits[model.name]
    final_fit = base_fit
    if rep.combination:
        # the combination's fit, with the variant each effect was fitted as (a history effect's
        # runs from the virgin state: "bouc_wen+rate+mullins (recovering)")
        variants = {s.effect: s.variant for s in rep.steps if s.variant}
        final_fit = rep.fits[model.augment(list(rep.combination), variants=variants or None).name]
    before = building_prediction(base_fit, data_of, order)
    after = before if final_fit is base_fit else building_prediction(final_fit, data_of, order)
    check_rows = []
    if ho_seq:
        cands_fit = [("baseline", base_fit)] + [(e.label, rep.fits[e.law]) for e in rep.ranking
                                                if e.law in rep.fits]
        for label, fit in cands_fit:
            row = {}
            for c in CHANNELS:
                m_all, p_all, ok = [], [], True
                for h, d in zip(ho_seq, ho_data):
                    st, out = fit.model.simulate(fit.x_opt, d)
                    if st != 0:
                        ok = False
                        break
                    m_all.append(d.measured(h)[c])
                    p_all.append(out[h][c])
                row[c] = float(nrmse(np.concatenate(m_all), np.concatenate(p_all))) if ok else math.nan
            check_rows.append({"effect": label, "law": fit.name, **row})
    building_check = pd.DataFrame(check_rows)
    # the comparison row: the loop fit's law in the identified building (no output error)
    loop_row: dict = {"law": loop.name, "params": {k: _num(v) for k, v in loop.params.items()}}
    lm = BuildingModel(base_law, sup, cal, scales, draws=draws, loop_fit=loop, a_ref=a_ref)
    x_loop = np.array([{**loop.params, "k_scale": 1.0, "zeta": lm.sup.zeta}.get(n, 0.0)
                       for n in lm.layout.names])
    for part, runs_ in (("calibration", cal_seq), ("holdout", ho_seq)):
        vals = {}
        try:
            outs = {r: lm.simulate(x_loop, data_of[r]) for r in runs_}
            if runs_ and all(st == 0 for st, _ in outs.values()):
                for c in CHANNELS:
                    vals[c] = float(nrmse(np.concatenate([data_of[r].measured(r)[c] for r in runs_]),
                                          np.concatenate([outs[r][1][r][c] for r in runs_])))
        except NUMERICAL_ERRORS as exc:
            notes.append(f"loop-fit comparison: {type(exc).__name__}: {exc}")
        loop_row[part] = vals or None
    seconds["predictions"] = _time.perf_counter() - t0
    gap_before = {"calibration": before.nrmse(cal_seq), "holdout": before.nrmse(ho_seq) if ho_seq else None}
    misfit = calibration_misfit(base_law, gap_before["calibration"])
    if misfit:
        notes.append(misfit)
    gap_after = {"calibration": after.nrmse(cal_seq), "holdout": after.nrmse(ho_seq) if ho_seq else None}
    held = pooled(after, ho_seq) if ho_seq else {}
    cov = {c: v["coverage"] for c, v in held.items()}
    bw = {c: v["band_width"] for c, v in held.items()}
    cov_ci = {c: (v["coverage_low"], v["coverage_high"]) for c, v in held.items()}
    cov_b = {c: v["coverage"] for c, v in pooled(before, ho_seq).items()} if ho_seq else {}
    cov_p = {}
    if ho_seq:
        for c in CHANNELS:
            inside = []
            for r in ho_seq:
                lo, hi = np.quantile(after.draws[r][c], [0.025, 0.975], axis=0)
                m = after.measured[r][c]
                inside.append((m >= lo) & (m <= hi))
            cov_p[c] = float(np.mean(np.concatenate(inside)))
    err_sd = {c: float(final_fit.sigma_c[c]) * scales[c] for c in CHANNELS}
    where = residual_table(after, ho_seq, cal_peak) if ho_seq else pd.DataFrame()
    runs_metrics = {r: run_metrics(after, r) for r in order}
    for p in ((before,) if after is before else (before, after)):
        if p.n_failed:
            notes.append(f"{p.n_failed} of {p.n_draws} building analyses with {p.law} failed "
                         f"(left out of the bands)")
    notes.extend(rep.notes)
    params = final_fit.params
    iso = Isolator(final_fit.model.spec.name, final_fit.law_params)
    if isinstance(sup, ShearBuilding):
        from dataclasses import replace

        final_building = replace(sup, isolator=iso)
    else:
        final_building = sup.building(iso)
    from dataclasses import replace as _replace

    k_fin = tuple(np.asarray(final_building.story_stiffness) * params["k_scale"])
    final_building = _replace(final_building, story_stiffness=k_fin, damping_ratio=float(params["zeta"]))
    return ShakeTableGap(
        law=base_law, final_law=final_fit.name, diagnosis=rep.verdict or rep.diagnosis,
        combination=tuple(rep.combination), calibrate=tuple(cal_seq), holdout=tuple(ho_seq),
        order=tuple(order),
        rate_hz=float(rate_hz), building_hz=float(fs), report=rep, law_scores=law_scores, identified_on=src,
        building=final_building,
        before=before, after=after, gap_before=gap_before, gap_after=gap_after, coverage=cov,
        coverage_parameter_band=cov_p, coverage_before=cov_b, error_sd=err_sd, extrapolation=extrapolation,
        calibrated_peak=cal_peak, where=where, building_check=building_check, notes=tuple(notes),
        elapsed=_time.perf_counter() - t_start, seconds=seconds, runs=runs_metrics, band_width=bw,
        coverage_interval=cov_ci,
        loop_fit=loop_row, final_fit=final_fit, base_fit=base_fit,
        cpu_seconds=_cpu() - c_start)
