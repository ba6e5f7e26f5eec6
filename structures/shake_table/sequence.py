"""A building's posterior prediction of shake-table runs driven one after the other, and its
per-run metrics (issues 15 and 27).

Two routes give one :class:`SequencePrediction`: :func:`predict_sequence` drives a
:class:`structures.ShearBuilding` by every row of isolator parameters through the runs, and
:func:`building_prediction` reads the posterior bands of a building fitted by output error
(:class:`structures.shake_table.building_fit.BuildingFit`).  Displacements are relative to each
run's start; channels and units in :data:`CHANNELS` and :data:`UNITS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ground_motions import Record
from rrfrei.budget import TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.calibration.checks import nrmse
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.gap.model import LEVEL
from structures.building.shear_building import ShearBuilding
from structures.dynamics.history import ConvergenceError, time_history
from structures.shake_table import ShakeTableRun
from structures.shake_table.building_fit import BuildingFit
from structures.shake_table.simulation import (
    REPORT_CHANNELS,
    BuildingData,
    concatenate_runs,
    measured_channels,
)

__all__ = ["CHANNELS", "UNITS", "SequencePrediction", "building_prediction", "coverage_interval", "pooled",
           "predict_sequence", "run_metrics"]

CHANNELS = REPORT_CHANNELS
"""The compared channels: isolator displacement [m], isolation-layer force [kN], story-1 shear
[kN] and roof absolute acceleration [m/s^2]."""

UNITS = {"isolator_disp": "m", "isolator_force": "kN", "base_shear": "kN", "roof_accel": "m/s^2"}


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
    acc, slices = concatenate_runs(runs, pad_s, dt)
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
        meas[r.name] = measured_channels(r)
        times[r.name] = np.asarray(r.time) - float(r.time[0])
        med[r.name], lo[r.name], hi[r.name], draws[r.name] = {}, {}, {}, {}
        for c in CHANNELS:
            D = np.vstack(sims[r.name][c])
            draws[r.name][c] = D
            lo[r.name][c], med[r.name][c], hi[r.name][c] = np.quantile(D, [a, 0.5, 1 - a], axis=0)
    return SequencePrediction(law=law, runs=tuple(r.name for r in runs), time=times, measured=meas,
                              median=med, lower=lo, upper=hi, draws=draws, n_draws=int(P.shape[0]),
                              n_failed=len(failures), failures=tuple(failures))


def building_prediction(fit: BuildingFit, data_of: Mapping[str, BuildingData], order: Sequence[str]
                        ) -> SequencePrediction:
    """The posterior prediction of every run of ``order`` by ``fit`` (:class:`BuildingFit`), each
    run simulated by the data that observe it (``data_of[run]``: the runs before it driven first);
    ``lower``/``upper``: the predictive 95 % band (draws plus the residual model)."""
    meas, med, lo, hi, draws, times = {}, {}, {}, {}, {}, {}
    n_ok = []
    for r in order:
        d = data_of[r]
        meas[r], med[r], lo[r], hi[r], draws[r] = {}, {}, {}, {}, {}
        times[r] = d.time(r)
        for c in CHANNELS:
            med[r][c], lo[r][c], hi[r][c] = fit.band(d, r, c)
            draws[r][c] = fit.channel_draws(d, r, c)
            meas[r][c] = d.measured(r)[c]
        n_ok.append(draws[r][CHANNELS[0]].shape[0])
    S = int(fit.X.shape[0])
    failures = (fit.note,) if fit.note and "failed" in fit.note else ()
    return SequencePrediction(law=fit.name, runs=tuple(order), time=times, measured=meas, median=med,
                              lower=lo, upper=hi, draws=draws, n_draws=S, n_failed=S - min(n_ok),
                              failures=failures)


COVERAGE_BLOCK_S = 10.0
"""Length of the blocks of the coverage's bootstrap interval [s] (the block rule's windows)."""
COVERAGE_BOOT = 2000
"""Bootstrap resamples of the coverage's interval."""
COVERAGE_LEVEL = 0.90
"""Level of the coverage's interval (that of the shrink's interval)."""


def coverage_interval(inside: Sequence[np.ndarray], times: Sequence[np.ndarray], *,
                      block_s: float = COVERAGE_BLOCK_S, boot: int = COVERAGE_BOOT,
                      level: float = COVERAGE_LEVEL, seed: int = 0) -> tuple[float, float]:
    """Block-bootstrap interval of a band's coverage: each run's samples (``inside``: whether the
    measured value lies in the band; ``times`` [s] from the run's start) cut into ``block_s``
    windows, the windows resampled with replacement within each run, the coverage of each
    resample (samples inside over samples).

    A building's residuals are smooth (AR(1) rho 0.95-0.998 at 50 Hz), so a run's samples are far
    from independent: 4,500 samples of a 90 s run hold about nine independent windows, and the
    coverage measured on one run is uncertain by several points.  The interval says by how much.
    """
    counts, sizes, strata = [], [], []
    for k, (ins, t) in enumerate(zip(inside, times)):
        ins = np.asarray(ins, dtype=bool)
        t = np.asarray(t, dtype=float)
        blk = np.floor((t - t[0]) / block_s).astype(int) if t.size else np.zeros(0, int)
        nb = int(blk.max()) + 1 if blk.size else 0
        counts.extend(np.bincount(blk, weights=ins, minlength=nb))
        sizes.extend(np.bincount(blk, minlength=nb))
        strata.extend([k] * nb)
    counts, sizes, strata = np.asarray(counts), np.asarray(sizes, float), np.asarray(strata)
    if sizes.sum() == 0:
        return math.nan, math.nan
    rng = np.random.default_rng([int(seed), 17])
    W = np.zeros((boot, counts.size))
    for s in np.unique(strata):
        idx = np.nonzero(strata == s)[0]
        pick = rng.integers(0, idx.size, size=(boot, idx.size))
        np.add.at(W, (np.arange(boot)[:, None], idx[pick]), 1.0)
    cov = (W @ counts) / (W @ sizes)
    a = (1 - level) / 2
    lo, hi = np.quantile(cov, [a, 1 - a])
    return float(lo), float(hi)


def _band_metrics(pred: SequencePrediction, runs: Sequence[str], c: str) -> dict[str, float]:
    m = np.concatenate([pred.measured[r][c] for r in runs])
    lo = np.concatenate([pred.lower[r][c] for r in runs])
    hi = np.concatenate([pred.upper[r][c] for r in runs])
    rms = float(np.sqrt(np.mean(m**2)))
    inside = [(pred.measured[r][c] >= pred.lower[r][c]) & (pred.measured[r][c] <= pred.upper[r][c])
              for r in runs]
    c_lo, c_hi = coverage_interval(inside, [pred.time[r] for r in runs])
    return {"coverage": float(np.mean((m >= lo) & (m <= hi))), "coverage_low": c_lo, "coverage_high": c_hi,
            "band_width": float(np.mean(hi - lo)) / rms if rms > 0 else math.nan}


def run_metrics(pred: SequencePrediction, run: str) -> dict[str, dict[str, float]]:
    """Per channel of ``run``: ``nrmse`` of the median, relative ``peak_error`` of the median,
    ``coverage`` of the predictive 95 % band with its 90 % block-bootstrap interval
    (``coverage_low``, ``coverage_high``: :func:`coverage_interval`) and ``band_width`` = mean band
    width / RMS of the measured channel (a band as wide as the signal is not a prediction)."""
    out = {}
    for c in CHANNELS:
        m, p = pred.measured[run][c], pred.median[run][c]
        pk_m, pk_p = float(np.max(np.abs(m))), float(np.max(np.abs(p)))
        out[c] = {"nrmse": float(nrmse(m, p)), "peak_error": (pk_p - pk_m) / pk_m if pk_m > 0 else math.nan,
                  **_band_metrics(pred, [run], c)}
    return out


def pooled(pred: SequencePrediction, runs: Sequence[str]) -> dict[str, dict[str, float]]:
    """Coverage (with its interval, :func:`coverage_interval`) and band width per channel pooled
    over ``runs``."""
    return {c: _band_metrics(pred, runs, c) for c in CHANNELS}

