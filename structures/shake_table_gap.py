"""The sim-to-real gap of a base-isolated building on shake-table runs (issue 15, point 5).

:func:`shake_table_gap` answers, on real runs, *does my calibrated model predict the next, larger
earthquake, where does it miss, why, and what fixes it?*:

1. **Isolator law.** The isolation tests (:func:`structures.isolation_test`: d_0 against
   F = -sum_i m_i a_i) of the calibration runs, decimated to ``rate_hz`` (25 Hz by default,
   anti-aliased by :meth:`ShakeTableRun.decimate`), are joined in the order the runs are given
   (their chronological order) into one :class:`~rrfrei.io.ShearTest`, so a law's state is
   carried from run to run.  The law is fitted by the gap engine's fast fit
   (:class:`rrfrei.gap.model.IsolatorModel`: bounded least squares, then a Laplace posterior;
   the emcee run of ``rrfrei.calibrate`` does not fit the time budget).  ``law="auto"`` fits
   every OpenSees law that needs no bearing geometry (``plasticity``, ``bouc_wen``, ``hdr``;
   ``elastomeric_x`` needs the bearings' geometry, which the data do not give) and keeps the
   one with the highest leave-one-cycle-out elpd (PSIS) on the calibration data.
2. **Diagnosis.** :func:`rrfrei.gap.diagnose` on that joined test, every held-out run's
   isolation test predicted *after* the runs that precede it (:meth:`rrfrei.io.ShearTest.after`:
   the law is driven through the earlier runs' measured displacements first, so softening
   carried from run to run is visible to the effects that hold state).  Effects: the catalogue's
   (``rrfrei.gap.catalogue.catalogue()``) unless ``effects`` names some.
3. **Building.** The superstructure from :func:`structures.identify_superstructure` on the
   calibration run where it holds (every story R^2 >= 0.8 and k, c > 0; the best such run by
   its worst R^2), or from a building TOML; the isolator is the calibrated layer law (count 1,
   length scale 1).  It is identified before any isolator is fitted, so a calibration set
   without a usable superstructure (or a TOML whose story count does not fit the runs) is a
   user error reported in seconds.  Every run, calibration and held-out, is predicted by driving the building
   with the measured table accelerations of all the runs in order, separated by ``pad_s``
   seconds of rest, so the isolators' state is carried between runs as in the test program.
   Displacement channels are compared relative to their value at the start of each run (the
   records start at zero displacement).  The building runs at the runs' own rate (50 Hz for
   the bundled ones).
4. **Before / after.** The building is run with ``n_draws`` posterior draws of the baseline law
   and of the diagnosed augmented law (``base+effect``, which runs everywhere a law runs);
   per-channel NRMSE of the posterior median on the calibration and the held-out runs
   (``isolator_disp`` [m], ``isolator_force`` [kN] = -sum_i m_i a_i, ``base_shear`` [kN] =
   the story-1 shear above the base slab, ``roof_accel`` [m/s^2]), and the coverage of two
   95 % bands: the *parameter* band (draws of the law only) and the *predictive* band, the
   parameter draws plus a Gaussian error per channel whose standard deviation is the RMS
   residual of the same model on the calibration runs (the model error measured where it was
   calibrated).
5. **Building check.** Every candidate effect's optimum (and the baseline's) is also run once
   through the building: the held-out NRMSE per channel shows whether the isolation-level
   ranking carries to the building (it need not: the diagnosis scores the force given the
   measured displacement, the building feeds its own displacement back).
6. **Where.** A residual table of the held-out predictions: share of the squared error by run,
   channel, amplitude range (|d_0| within / beyond the calibrated peak), time window (10 s)
   and frequency band.

Numerical robustness: a draw whose isolator simulation fails is retried with 4 then 16
sub-increments per sample, and is left out of the bands if it still fails; a building analysis
that fails (``ConvergenceError``) is left out too.  When every draw fails the pipeline raises a
:class:`rrfrei.errors.NumericalFailure` naming the law, the run and the failure.
"""

from __future__ import annotations

import math
import tempfile
import time as _time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ground_motions import Record
from rrfrei._json import number as _num
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.calibration.checks import nrmse
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.gap.diagnose import GapReport, _Checkpoint, _loco, diagnose
from rrfrei.gap.model import (
    LEVEL,
    RETRY_SUBSTEPS,
    FitResult,
    GapModel,
    IsolatorFit,
    IsolatorModel,
    Prediction,
    gaussian_loglik,
    simulate_retry,
)
from rrfrei.io import ShearTest, concat_tests
from structures.building import Isolator, ShearBuilding
from structures.history import ConvergenceError, time_history
from structures.identify import identify_superstructure
from structures.shake_table import ShakeTableRun, available_runs, isolation_test, load_run, read_run

__all__ = ["AUTO_LAWS", "BNCS_ORDER", "CHANNELS", "CarriedIsolatorModel", "ShakeTableGap",
           "SequencePrediction", "predict_sequence", "resolve_run", "shake_table_gap"]

BNCS_ORDER = ("CNP100", "LAC100", "ICA50", "ICA100")
"""The bundled runs in the order of the BNCS base-isolated test program (Chen et al. 2016; the
source data do not state it: this order is also the one in which the isolators' effective
stiffness falls, 4,350-5,650, 4,100-4,840, 3,990-4,560 then 3,070-3,600 kN/m)."""

AUTO_LAWS = ("plasticity", "bouc_wen", "hdr")
"""The OpenSees laws ``law="auto"`` chooses from (``elastomeric_x`` needs bearing geometry)."""

CHANNELS = ("isolator_disp", "isolator_force", "base_shear", "roof_accel")
"""The compared channels: isolator displacement [m], isolation-layer force [kN], story-1 shear
[kN] and roof absolute acceleration [m/s^2]."""

UNITS = {"isolator_disp": "m", "isolator_force": "kN", "base_shear": "kN", "roof_accel": "m/s^2"}

BANDS_HZ = ((0.0, 0.3), (0.3, 1.0), (1.0, 3.0), (3.0, 10.0), (10.0, math.inf))
"""Frequency bands of the residual table [Hz] (isolation mode ~0.4 Hz, superstructure 1.5-10 Hz)."""

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
# the gap engine's model with state carried between runs
# ---------------------------------------------------------------------------------------------
@dataclass(eq=False)
class CarriedFit(FitResult):
    """An :class:`IsolatorFit` whose failing simulations are retried with sub-increments
    (:func:`simulate_law`) instead of turning every prediction into NaN; a test's ``preceding``
    runs are driven through first, as in :class:`IsolatorFit`."""

    inner: IsolatorFit
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.inner.name

    @property
    def params(self) -> dict[str, float]:  # type: ignore[override]
        return self.inner.params

    @property
    def sigma(self) -> float:  # type: ignore[override]
        return self.inner.sigma

    @property
    def noise(self) -> float:  # type: ignore[override]
        return self.inner.noise

    @property
    def note(self) -> str:
        return self.inner.note

    @property
    def spec(self):
        return self.inner.spec

    @property
    def P(self) -> np.ndarray:
        return self.inner.P

    def predict(self, data) -> Prediction:
        key = id(data)
        if key in self._cache:
            return self._cache[key][1]
        n = len(data)
        fit = self.inner
        S = fit.P.shape[0]
        F = np.empty((S, n))
        ok = np.zeros(S, dtype=bool)
        for s in range(S):
            st, f = simulate_law(fit.spec, fit.P[s], data)
            if st == 0:
                F[s] = f
                ok[s] = True
        if not ok.any():
            st, f = simulate_law(fit.spec, fit.p_opt, data)
            if st != 0:
                raise NumericalFailure(f"law {fit.name!r} on {data.name!r}: every posterior draw and the "
                                       f"optimum fail (status {st}, also with {SUBSTEPS[-1]} sub-increments)")
            F, ok, sig = f[None, :], np.array([True]), np.array([fit.sigma])
        else:
            F, sig = F[ok], fit.sig[ok]
        rng = np.random.default_rng(fit.seed + 1)
        Y = F + rng.normal(size=F.shape) * sig[:, None]
        a = (1 - LEVEL) / 2
        lo, hi = np.quantile(Y, [a, 1 - a], axis=0)
        pred = Prediction(mean=F.mean(axis=0), lower=lo, upper=hi, draws=F, sigma=sig)
        self._cache[key] = (data, pred)
        return pred

    def loglik(self, data) -> np.ndarray:
        return gaussian_loglik(data.force, self.predict(data))


class CarriedIsolatorModel(GapModel):
    """:class:`IsolatorModel` whose fits are :class:`CarriedFit`\\ s (held-out runs given as
    ``test.after(*earlier)`` carry the state of the earlier runs, as with :class:`IsolatorModel`;
    here a failing simulation is retried rather than lost)."""

    def __init__(self, inner: IsolatorModel) -> None:
        self.inner = inner

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.inner.name

    @property
    def spec(self):
        return self.inner.spec

    def fit(self, data, *, seed: int = 0, start=None, budget: TimeBudget | None = None) -> CarriedFit:
        return CarriedFit(self.inner.fit(data, seed=seed, start=start, budget=budget))

    def augment(self, effects: Sequence[str], variants: Mapping[str, str] | None = None
                ) -> CarriedIsolatorModel:
        return CarriedIsolatorModel(self.inner.augment(effects, variants=variants))

    def variants(self, effect: str) -> tuple[str, ...]:
        return self.inner.variants(effect)

    def observed(self, data) -> np.ndarray:
        return self.inner.observed(data)

    def groups(self, data) -> np.ndarray:
        return self.inner.groups(data)

    def cannot_judge(self, effect: str, data) -> str | None:
        return self.inner.cannot_judge(effect, data)

    def early(self, data) -> ShearTest | None:
        return self.inner.early(data)

    def checkpoint_key(self, data) -> str:
        return self.inner.checkpoint_key(data) + "|retried"

    def fit_state(self, fit: CarriedFit) -> dict[str, np.ndarray]:
        return self.inner.fit_state(fit.inner)

    def restore(self, state: Mapping[str, np.ndarray]) -> CarriedFit:
        return CarriedFit(self.inner.restore(state))


# ---------------------------------------------------------------------------------------------
# building predictions of a sequence of runs
# ---------------------------------------------------------------------------------------------
def _measured(run: ShakeTableRun) -> dict[str, np.ndarray]:
    return {"isolator_disp": np.asarray(run.isolator_disp), "isolator_force": np.asarray(run.isolator_force),
            "base_shear": np.asarray(run.story_shear()[:, 0]), "roof_accel": np.asarray(run.accel[:, -1])}


@dataclass(frozen=True, eq=False)
class SequencePrediction:
    """A building's posterior prediction of several runs driven one after the other.

    Attributes
    ----------
    law : isolator law.
    runs : run names in order.
    time : run -> (n,) time from the run's start [s].
    measured, median, lower, upper : run -> channel -> (n,) (``lower``/``upper``: the parameter
        band, central ``LEVEL``).
    draws : run -> channel -> (S_ok, n) model outputs of the successful draws.
    n_draws, n_failed : analyses run and failed (their messages in ``failures``).
    """

    law: str
    runs: tuple[str, ...]
    time: dict
    measured: dict
    median: dict
    lower: dict
    upper: dict
    draws: dict = field(repr=False)
    n_draws: int = 0
    n_failed: int = 0
    failures: tuple[str, ...] = ()

    def nrmse(self, runs: Sequence[str]) -> dict[str, float]:
        """Per channel, NRMSE of the median pooled over ``runs``."""
        out = {}
        for c in CHANNELS:
            m = np.concatenate([self.measured[r][c] for r in runs])
            p = np.concatenate([self.median[r][c] for r in runs])
            out[c] = float(nrmse(m, p))
        return out

    def residual_sd(self, runs: Sequence[str]) -> dict[str, float]:
        """Per channel, RMS of measured minus median over ``runs`` (the model error there)."""
        return {c: float(np.sqrt(np.mean(np.concatenate(
            [(self.measured[r][c] - self.median[r][c]) ** 2 for r in runs])))) for c in CHANNELS}

    def coverage(self, runs: Sequence[str], error_sd: Mapping[str, float] | None = None,
                 seed: int = 0) -> dict[str, float]:
        """Per channel, the fraction of the samples of ``runs`` inside the 95 % band: the parameter
        band (``error_sd`` None) or the predictive band, draws plus N(0, error_sd[channel])."""
        out = {}
        a = (1 - LEVEL) / 2
        for c in CHANNELS:
            inside = []
            for r in runs:
                m = self.measured[r][c]
                if error_sd is None:
                    lo, hi = self.lower[r][c], self.upper[r][c]
                else:
                    D = self.draws[r][c]
                    rng = np.random.default_rng([seed, CHANNELS.index(c)])
                    reps = max(1, int(math.ceil(200 / D.shape[0])))
                    Y = np.repeat(D, reps, axis=0)
                    Y = Y + rng.normal(size=Y.shape) * float(error_sd[c])
                    lo, hi = np.quantile(Y, [a, 1 - a], axis=0)
                inside.append((m >= lo) & (m <= hi))
            out[c] = float(np.mean(np.concatenate(inside)))
        return out

    def peak_error(self, run: str) -> dict[str, float]:
        """Per channel, (max|median| - max|measured|) / max|measured| on ``run``."""
        out = {}
        for c in CHANNELS:
            pm = float(np.max(np.abs(self.measured[run][c])))
            pp = float(np.max(np.abs(self.median[run][c])))
            out[c] = (pp - pm) / pm if pm > 0 else math.nan
        return out


def predict_sequence(building: ShearBuilding, P: np.ndarray, runs: Sequence[ShakeTableRun], *,
                     pad_s: float = 10.0, progress: bool = False, budget: TimeBudget | None = None
                     ) -> SequencePrediction:
    """Drive ``building`` (isolator parameters = each row of ``P``) with the table accelerations
    of ``runs`` one after the other, ``pad_s`` seconds of rest between them, and compare each
    run's :data:`CHANNELS` with its measurements (displacements from the start of each run).

    All runs must share one sampling step (the building runs at it).
    """
    runs = list(runs)
    dt = runs[0].dt
    for r in runs[1:]:
        if abs(r.dt - dt) > 1e-9 * dt:
            raise ValueError(f"runs {runs[0].name!r} ({1 / dt:g} Hz) and {r.name!r} ({r.rate_hz:g} Hz) have "
                             "different sampling rates; resample them to one rate")
    npad = int(round(pad_s / dt))
    parts, slices, i0 = [], {}, 0
    for r in runs:
        if parts:
            parts.append(np.zeros(npad))
            i0 += npad
        a = np.asarray(r.table_accel, dtype=float)
        parts.append(a)
        slices[r.name] = slice(i0, i0 + a.size)
        i0 += a.size
    acc = np.concatenate(parts)
    record = Record("+".join(r.name for r in runs), dt, np.concatenate([[0.0], acc]))  # start at rest
    sims: dict[str, dict[str, list]] = {r.name: {c: [] for c in CHANNELS} for r in runs}
    failures: list[str] = []
    law = building.isolator.law
    bar = progress_bar(P.shape[0], f"{law}: building", enabled=progress, unit="draw")
    with bar:
        for i in range(P.shape[0]):
            if budget is not None:
                budget.check()
            try:
                resp = time_history(building.with_isolator_params(P[i]), record)
            except (ConvergenceError, ArithmeticError, *NUMERICAL_ERRORS) as exc:
                failures.append(f"draw {i}: {type(exc).__name__}: {str(exc)[:300]}")
                bar.update()
                continue
            for r in runs:
                s = slices[r.name]
                s1 = slice(s.start + 1, s.stop + 1)  # the record has a leading zero
                ud = np.asarray(resp.isolator_disp)
                u0 = float(ud[s.start])  # at rest just before the run starts
                ch = {"isolator_disp": ud[s1] - u0, "isolator_force": np.asarray(resp.isolator_force)[s1],
                      "base_shear": np.asarray(resp.base_shear)[s1],
                      "roof_accel": np.asarray(resp.floor_accel_abs)[s1, -1]}
                for c in CHANNELS:
                    sims[r.name][c].append(ch[c])
            bar.update()
    if not sims[runs[0].name][CHANNELS[0]]:
        raise NumericalFailure(f"building with isolator law {law!r} driven by "
                               f"{' then '.join(r.name for r in runs)}: every one of the {P.shape[0]} "
                               f"analyses failed; first: {failures[0]}")
    a = (1 - LEVEL) / 2
    meas, med, lo, hi, draws, times = {}, {}, {}, {}, {}, {}
    for r in runs:
        meas[r.name] = _measured(r)
        times[r.name] = np.asarray(r.time) - float(r.time[0])
        med[r.name], lo[r.name], hi[r.name], draws[r.name] = {}, {}, {}, {}
        for c in CHANNELS:
            D = np.vstack(sims[r.name][c])
            draws[r.name][c] = D
            lo[r.name][c], med[r.name][c], hi[r.name][c] = np.quantile(D, [a, 0.5, 1 - a], axis=0)
    return SequencePrediction(law=law, runs=tuple(r.name for r in runs), time=times, measured=meas,
                              median=med, lower=lo, upper=hi, draws=draws, n_draws=int(P.shape[0]),
                              n_failed=len(failures), failures=tuple(failures))


# ---------------------------------------------------------------------------------------------
# where the held-out gap lies
# ---------------------------------------------------------------------------------------------
def residual_table(pred: SequencePrediction, runs: Sequence[str], calibrated_peak: float, *,
                   window_s: float = 10.0) -> pd.DataFrame:
    """Where the prediction of ``runs`` misses: one row per (axis, segment) with ``run``,
    ``channel``, ``n`` samples, ``error_share`` (share of the channel's squared error over
    ``runs``, normalised by the channel's measured RMS so channels compare) and ``nrmse`` of the
    segment.  Axes: ``run``, ``channel``, ``amplitude`` (|d_0| within or beyond the calibrated
    peak), ``time window`` (``window_s`` s, the worst 5 per run and channel) and ``frequency``
    (:data:`BANDS_HZ`, share of the residual's power)."""
    rows = []
    for c in CHANNELS:
        rms = float(np.sqrt(np.mean(np.concatenate([pred.measured[r][c] for r in runs]) ** 2))) or 1.0
        tot = float(sum(np.sum(((pred.measured[r][c] - pred.median[r][c]) / rms) ** 2) for r in runs)) or 1.0
        rows.append({"axis": "channel", "segment": c, "run": "all", "channel": c,
                     "n": int(sum(pred.measured[r][c].size for r in runs)),
                     "error_share": 1.0, "nrmse": pred.nrmse(runs)[c]})
        for r in runs:
            m, p, t = pred.measured[r][c], pred.median[r][c], pred.time[r]
            e = ((m - p) / rms) ** 2
            if len(runs) > 1:
                rows.append({"axis": "run", "segment": r, "run": r, "channel": c, "n": int(m.size),
                             "error_share": float(e.sum() / tot), "nrmse": float(nrmse(m, p))})
            d = np.abs(pred.measured[r]["isolator_disp"])
            for lab, sel in ((f"|d0| <= {calibrated_peak:.3f} m (calibrated)", d <= calibrated_peak),
                             (f"|d0| > {calibrated_peak:.3f} m (beyond)", d > calibrated_peak)):
                if sel.any():
                    rows.append({"axis": "amplitude", "segment": lab, "run": r, "channel": c,
                                 "n": int(sel.sum()), "error_share": float(e[sel].sum() / tot),
                                 "nrmse": float(nrmse(m[sel], p[sel])) if np.any(m[sel] != 0) else math.nan})
            wins = []
            for w0 in np.arange(0.0, float(t[-1]) + 1e-9, window_s):
                sel = (t >= w0) & (t < w0 + window_s)
                if sel.sum() > 1:
                    wins.append({"axis": "time window", "segment": f"{w0:.0f}-{w0 + window_s:.0f} s",
                                 "run": r, "channel": c, "n": int(sel.sum()),
                                 "error_share": float(e[sel].sum() / tot),
                                 "nrmse": float(nrmse(m[sel], p[sel])) if np.any(m[sel] != 0) else math.nan})
            rows.extend(sorted(wins, key=lambda x: -x["error_share"])[:5])
            res = m - p
            spec = np.abs(np.fft.rfft(res)) ** 2
            f = np.fft.rfftfreq(res.size, d=float(t[1] - t[0]))
            share_run = float(e.sum() / tot)
            ps = float(spec.sum()) or 1.0
            for lo, hi in BANDS_HZ:
                sel = (f >= lo) & (f < hi)
                if sel.any():
                    lab = f"{lo:g}-{hi:g} Hz" if math.isfinite(hi) else f"> {lo:g} Hz"
                    rows.append({"axis": "frequency", "segment": lab, "run": r, "channel": c,
                                 "n": int(sel.sum()), "nrmse": math.nan,
                                 "error_share": share_run * float(spec[sel].sum()) / ps})
    df = pd.DataFrame(rows)
    order = {"channel": 0, "run": 1, "amplitude": 2, "frequency": 3, "time window": 4}
    df["_o"] = df["axis"].map(order)
    return df.sort_values(["_o", "channel", "error_share"], ascending=[True, True, False]) \
        .drop(columns="_o").reset_index(drop=True)


# ---------------------------------------------------------------------------------------------
# the pipeline
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ShakeTableGap:
    """Result of :func:`shake_table_gap` (see the module docstring).

    ``gap_before`` / ``gap_after``: {"calibration": {channel: NRMSE}, "holdout": {...}} of the
    building with the baseline law and with the diagnosed augmented law (the same as before when
    the diagnosis is no effect); ``coverage``: held-out predictive-band coverage per channel (of
    the final model); ``coverage_parameter_band``: the same for the parameter band only;
    ``extrapolation``: held-out run -> its peak |d_0| over the calibration runs' peak;
    ``building_check``: held-out NRMSE per channel of the building with the optimum of the
    baseline and of every candidate effect (one analysis each), whether or not it was diagnosed.
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

    def shrink(self) -> dict[str, float]:
        """Per channel, 1 - held-out NRMSE after / before."""
        b, a = self.gap_before["holdout"], self.gap_after["holdout"]
        return {c: (1.0 - a[c] / b[c]) if b[c] > 0 else math.nan for c in CHANNELS}

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
        return {
            "law": self.law,
            "diagnosis": self.diagnosis,
            "verdict": rep.verdict or rep.diagnosis,
            "evidence": rep.as_dict().get("evidence"),
            "combination": list(self.combination),
            "where": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                      for row in self.where.to_dict("records")],
            "ranking": [{"effect": e.effect, "variant": e.variant, "delta_elpd": _num(e.delta_elpd),
                         "se": _num(e.se), "delta_holdout": _num(e.delta_holdout),
                         "se_holdout": _num(e.se_holdout),
                         "shrink_calibration": _num(e.shrink_calibration),
                         "shrink_holdout": _num(e.shrink_holdout), "significant": bool(e.significant)}
                        for e in rep.ranking],
            "extrapolation": {k: _num(v) for k, v in self.extrapolation.items()},
            "gap_before": _nums(self.gap_before),
            "gap_after": _nums(self.gap_after),
            "coverage": {k: _num(v) for k, v in self.coverage.items()},
            "coverage_parameter_band": {k: _num(v) for k, v in self.coverage_parameter_band.items()},
            "shrink_holdout": {k: _num(v) for k, v in self.shrink().items()},
            "building_check": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                               for row in self.building_check.to_dict("records")],
            "building_best": (None if (bb := self.building_best()) is None
                              else {k: _num(v) if isinstance(v, float) else v for k, v in bb.items()}),
            "final_law": self.final_law,
            "calibrate": list(self.calibrate),
            "holdout": list(self.holdout),
            "order": list(self.order),
            "rate_hz": self.rate_hz,
            "superstructure_from": self.identified_on,
            "law_scores": [{k: _num(v) if isinstance(v, float) else v for k, v in row.items()}
                           for row in self.law_scores.to_dict("records")],
            "isolator_gap": rep.as_dict()["gap_before"] | {"after": rep.as_dict()["gap_after"]},
            "complete": rep.complete,
            "skipped": dict(rep.skipped),
            "not_evaluated": dict(rep.not_evaluated),
            "failed_analyses": {"before": self.before.n_failed, "after": self.after.n_failed},
            "elapsed_s": _num(self.elapsed),
            "seconds": {k: _num(v) for k, v in self.seconds.items()},
            "notes": list(self.notes),
        }


def _nums(d: Mapping) -> dict:
    return {k: ({c: _num(v) for c, v in sub.items()} if sub is not None else None) for k, sub in d.items()}


def _names(items) -> list[str]:
    out = []
    for x in items:
        out.extend(s.strip() for s in str(x).split(",") if s.strip())
    return out


def _pick_law(cal: ShearTest, laws: Sequence[str], draws: int, seed: int, budget: TimeBudget,
              notes: list[str], checkpoint) -> tuple[str, pd.DataFrame, dict]:
    """Fit each law in ``laws`` and rank by leave-one-cycle-out elpd (PSIS) on ``cal``; every fit is
    saved in the ``checkpoint`` folder as the diagnosis's baseline, so the chosen law's is reused."""
    model = IsolatorModel(laws[0], draws=draws)
    groups = model.groups(cal)
    rows, fits = [], {}
    for law in laws:
        t0 = _time.perf_counter()
        try:
            m = CarriedIsolatorModel(IsolatorModel(law, draws=draws))
            ck = _Checkpoint(checkpoint, m, cal, seed)
            fit = ck.get("baseline")
            if fit is None:
                fit = m.fit(cal, seed=seed, budget=budget)
                ck.put("baseline", m, fit)
            elpd = float(_loco(fit.loglik(cal), groups).sum())
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


def _superstructure(cal_runs: Sequence[ShakeTableRun], building_toml, seed: int, notes: list[str]):
    """(identification run name or TOML path, masses, stiffness, zeta, heights) of the superstructure."""
    if building_toml is not None:
        b = ShearBuilding.from_toml(building_toml, isolator_params=None) \
            if not isinstance(building_toml, ShearBuilding) else building_toml
        return str(building_toml), b
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
    effects: Sequence[str] | None = None,
    draws: int = 60,
    n_draws: int = 40,
    pad_s: float = 10.0,
    seed: int = 0,
    time_budget: float | TimeBudget | None = 170.0,
    progress: bool = False,
    checkpoint: str | Path | None = None,
) -> ShakeTableGap:
    """Calibrate, diagnose and predict a base-isolated building on shake-table runs.

    Parameters
    ----------
    runs : the runs in chronological order (bundled names, folders, CSVs or
        :class:`ShakeTableRun`\\ s); default :data:`BNCS_ORDER`.
    calibrate, holdout : run names (as loaded) to calibrate on and to hold out; default every run
        but the last, and the last.  A name may hold several, comma-separated.
    law : base isolator law, or ``"auto"`` (best leave-one-cycle-out elpd of :data:`AUTO_LAWS`).
    building : TOML of a :class:`ShearBuilding` (or one) whose superstructure is used instead of
        the identified one (its isolator is replaced by the calibrated law).
    rate_hz : rate of the isolation tests the law is fitted on [Hz] (the runs' rate divided by an
        integer).
    effects : catalogue effects to try (default all).
    draws : Laplace posterior draws per fit; ``n_draws`` of them drive the building.
    pad_s : rest between runs in the building's record [s].
    time_budget : wall-clock limit of the whole pipeline [s]; the diagnosis gets what the law
        choice leaves minus a reserve for the building runs, and stops with the effects it has.
    checkpoint : folder where every finished isolator fit is saved and reused by a rerun (as in
        :func:`rrfrei.gap.diagnose`); None: a temporary folder, so that the law choice's fit of
        the chosen law is the diagnosis's baseline.

    Raises
    ------
    ValueError : unknown run or law, a run in both sets, rates that do not divide, no
        superstructure.
    NumericalFailure : the baseline cannot be fitted, or every building analysis fails.
    """
    t_start = _time.perf_counter()
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
    if not isinstance(n_draws, (int, np.integer)) or isinstance(n_draws, bool) or n_draws < 2:
        raise ValueError(f"n_draws = {n_draws!r} is invalid: expected an integer >= 2")
    if n_draws > draws:
        raise ValueError(f"n_draws = {n_draws} is invalid: expected at most draws = {draws}")
    fs = loaded[0].rate_hz
    for r in loaded:
        if abs(r.rate_hz - fs) > 1e-6 * fs:
            raise ValueError(f"runs {loaded[0].name!r} ({fs:g} Hz) and {r.name!r} ({r.rate_hz:g} Hz) have "
                             "different sampling rates; give runs at one rate")
    # 1. isolation tests, chronological, decimated
    t0 = _time.perf_counter()
    tests = {n: isolation_test(by_name[n].decimate(rate_hz)) for n in order}
    cal_seq = [n for n in order if n in cal_names]
    cal = concat_tests([tests[n] for n in cal_seq], name="+".join(cal_seq))
    # each held-out run after every run before it in the order (its state carried in)
    held = [tests[h].after(*[tests[n] for n in order[:order.index(h)]]) for h in ho_names]
    cal_peak = float(np.max(np.abs(cal.disp)))
    extrapolation = {h: float(np.max(np.abs(by_name[h].isolator_disp)) / cal_peak) for h in ho_names}
    seconds["isolation tests"] = _time.perf_counter() - t0
    # 2. the superstructure first: a run that cannot give one (or a building TOML that does not
    # fit the runs) is reported in seconds, before the minutes of isolator fits
    t0 = _time.perf_counter()
    cal_runs = [by_name[n] for n in order if n in cal_names]
    src, sup = _superstructure(cal_runs, building, seed, notes)
    if isinstance(sup, ShearBuilding) and sup.n_stories != loaded[0].n_levels - 1:
        raise ValueError(f"building {src!r} has {sup.n_stories} stories but the runs have "
                         f"{loaded[0].n_levels} levels ({loaded[0].n_levels - 1} stories)")
    seconds["superstructure"] = _time.perf_counter() - t0
    # 3. law
    t0 = _time.perf_counter()
    tmp = None
    if checkpoint is None:
        tmp = tempfile.TemporaryDirectory(prefix="rrfrei-shake-")
        checkpoint = tmp.name
    if law == "auto":
        base_law, law_scores, _ = _pick_law(cal, AUTO_LAWS, draws, seed, budget, notes, checkpoint)
    else:
        base_law, law_scores = str(law), pd.DataFrame(columns=["law", "loco_elpd", "nrmse", "seconds"])
    seconds["law choice"] = _time.perf_counter() - t0
    # 4. diagnosis
    t0 = _time.perf_counter()
    # reserve for the building runs (about 0.03 s per draw and run each, twice) and the report
    reserve = 15.0 + 0.1 * n_draws * len(order)
    diag_budget = TimeBudget(None if budget.seconds is None else max(budget.remaining - reserve, 1.0),
                             what="shake-table diagnosis", option="--time-budget")
    model = CarriedIsolatorModel(IsolatorModel(base_law, draws=draws))
    try:
        rep = diagnose(model, cal, held, effects=effects, seed=seed, progress=progress,
                       time_budget=diag_budget, checkpoint=checkpoint)
    except BudgetExceeded as exc:
        raise NumericalFailure(f"the baseline fit of {base_law!r} did not finish within the time budget: "
                               f"{exc}") from None
    finally:
        if tmp is not None:
            tmp.cleanup()
    seconds["diagnosis"] = _time.perf_counter() - t0
    # 5. building: every run with the baseline and the final law
    t0 = _time.perf_counter()
    base_fit = rep.fits[rep.law]
    final_name = "+".join([rep.law, *rep.combination])
    final_fit = rep.fits.get(final_name, base_fit)
    rng = np.random.default_rng(seed)

    def build(fit) -> ShearBuilding:
        iso = Isolator(fit.spec.name, fit.params)
        if isinstance(sup, ShearBuilding):
            from dataclasses import replace

            return replace(sup, isolator=iso)
        return sup.building(iso)

    pick = np.sort(rng.choice(base_fit.P.shape[0], size=n_draws, replace=False))
    seq = [by_name[n] for n in order]
    before = predict_sequence(build(base_fit), base_fit.P[pick], seq, pad_s=pad_s, progress=progress)
    if final_fit is base_fit:
        after = before
    else:
        pick_f = np.sort(rng.choice(final_fit.P.shape[0], size=n_draws, replace=False))
        after = predict_sequence(build(final_fit), final_fit.P[pick_f], seq, pad_s=pad_s, progress=progress)
    # every candidate's optimum in the building (one analysis each): does the isolation-level
    # ranking carry to the building's held-out channels?
    check_rows = []
    ho_seq = [n for n in order if n in ho_names]
    if ho_seq:
        cands = [("baseline", base_fit)] + [(e.effect, rep.fits[e.law]) for e in rep.ranking
                                            if e.law in rep.fits]
        for label, fit in cands:
            try:
                pm = predict_sequence(build(fit), np.asarray(fit.inner.p_opt)[None, :], seq, pad_s=pad_s)
                row = pm.nrmse(ho_seq)
            except NUMERICAL_ERRORS as exc:
                notes.append(f"building check of {fit.name}: {type(exc).__name__}: {str(exc)[:200]}")
                row = {c: math.nan for c in CHANNELS}
            check_rows.append({"effect": label, "law": fit.name, **row})
    building_check = pd.DataFrame(check_rows)
    seconds["building"] = _time.perf_counter() - t0
    cal_order = [n for n in order if n in cal_names]
    ho_order = [n for n in order if n in ho_names]
    gap_before = {"calibration": before.nrmse(cal_order),
                  "holdout": before.nrmse(ho_order) if ho_order else None}
    gap_after = {"calibration": after.nrmse(cal_order),
                 "holdout": after.nrmse(ho_order) if ho_order else None}
    err_after = after.residual_sd(cal_order)
    err_before = before.residual_sd(cal_order)
    cov = after.coverage(ho_order, err_after, seed=seed) if ho_order else {}
    cov_p = after.coverage(ho_order) if ho_order else {}
    cov_b = before.coverage(ho_order, err_before, seed=seed) if ho_order else {}
    where = residual_table(after, ho_order, cal_peak) if ho_order else pd.DataFrame()
    for p in ((before,) if after is before else (before, after)):
        if p.n_failed:
            notes.append(f"{p.n_failed} of {p.n_draws} building analyses with {p.law} failed "
                         f"(left out of the bands); first: {p.failures[0]}")
    notes.extend(rep.notes)
    return ShakeTableGap(
        law=rep.law, final_law=final_fit.name,
        diagnosis=rep.verdict or rep.diagnosis, combination=tuple(rep.combination),
        calibrate=tuple(cal_order), holdout=tuple(ho_order), order=tuple(order), rate_hz=float(rate_hz),
        report=rep, law_scores=law_scores, identified_on=src, building=build(final_fit), before=before,
        after=after, gap_before=gap_before, gap_after=gap_after, coverage=cov, coverage_parameter_band=cov_p,
        coverage_before=cov_b, error_sd=err_after, extrapolation=extrapolation, calibrated_peak=cal_peak,
        where=where, building_check=building_check, notes=tuple(notes),
        elapsed=_time.perf_counter() - t_start, seconds=seconds)
