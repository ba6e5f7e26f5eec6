"""Prediction of a (held-out) shake-table run by a calibrated building.

:func:`predict_run` takes posterior draws of the isolation-system law (a ``rrfrei.Calibration``),
puts each into the building (``building.with_isolator_params``), drives it with the run's
measured table acceleration (:func:`structures.time_history`, Newmark + Newton from rest, at the
run's sampling step) and compares, channel by channel, the posterior median and the central
95 % band of the parameter draws with the measurements:

* ``isolator_disp`` [m]: d_0, the base slab relative to the table;
* ``base_shear`` [kN]: the force of the isolation layer, measured as -sum_i m_i a_i over every
  level above the isolators (predicted: the layer force of the model, which equals the same sum);
* ``accel_<level>`` [m/s^2]: absolute acceleration of every level (base slab to roof);
* ``drift_<story>`` [m]: d_j - d_{j-1}.

Per channel: NRMSE = RMS(measured - median) / RMS(measured) (as in
``rrfrei.calibration.checks.nrmse``), the relative peak error (max|median| - max|measured|) /
max|measured|, and the coverage, the fraction of samples whose measurement lies in the band.
The band holds the *parameter* uncertainty of the isolator law only (the superstructure is held at
its identification and the measurement noise is not added), so a coverage well under 95 % says
the model's error, not the posterior's width, dominates.

Extrapolation: ``peak_ratio`` = max|d_0| of the run / max|u| of the calibration test.  Above 1
the run takes the isolators beyond any displacement the calibration saw: the law's behaviour
there (stiffening, softening, degradation) is not constrained by the data, only by its form.
"""

from __future__ import annotations

import inspect
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rrfrei.calibration.checks import nrmse
from structures.building.shear_building import ShearBuilding
from structures.dynamics.history import ConvergenceError, time_history
from structures.shake_table import ShakeTableRun

__all__ = ["RunPrediction", "predict_run"]

UNITS = {"isolator_disp": "m", "base_shear": "kN", "accel": "m/s$^2$", "drift": "m"}


def _unit(channel: str) -> str:
    return UNITS.get(channel, UNITS.get(channel.split("_")[0], "-"))


@dataclass(frozen=True, eq=False)
class RunPrediction:
    """Posterior prediction of a run against its measurements.

    Attributes
    ----------
    run : the :class:`ShakeTableRun` predicted.
    law : isolator law.
    time : (n,) [s].
    measured, median, lower, upper : dict channel -> (n,) arrays (band: 2.5 % and 97.5 %
        percentiles over the successful draws).
    table : one row per channel: ``channel``, ``unit``, ``nrmse``, ``peak_measured``,
        ``peak_predicted`` (of the median), ``peak_error`` (relative), ``coverage``.
    peak_ratio : max|d_0| of the run / max|u| of the calibration test.
    calibrated_peak : max|u| of the calibration test [m].
    n_draws, n_failed : draws run and draws whose analysis failed (their messages in ``failures``).
    """

    run: ShakeTableRun
    law: str
    time: np.ndarray
    measured: dict
    median: dict
    lower: dict
    upper: dict
    table: pd.DataFrame
    peak_ratio: float
    calibrated_peak: float
    n_draws: int
    n_failed: int
    failures: list = field(default_factory=list)

    @property
    def nrmse(self) -> dict[str, float]:
        return dict(zip(self.table["channel"], self.table["nrmse"].astype(float)))

    @property
    def coverage(self) -> dict[str, float]:
        return dict(zip(self.table["channel"], self.table["coverage"].astype(float)))

    @property
    def peak_error(self) -> dict[str, float]:
        return dict(zip(self.table["channel"], self.table["peak_error"].astype(float)))

    @property
    def extrapolates(self) -> bool:
        """True when the run goes beyond the calibrated displacement range."""
        return self.peak_ratio > 1.0

    def plot(self, channels: Sequence[str] | None = None, *, time_window: tuple[float, float] | None = None,
             path: str | Path | None = None, loop: bool = True):
        """Overlay of measurement, median and 95 % band per channel (one panel each, time [s]),
        plus the isolation-system loop (base shear [kN] vs isolator displacement [m]) when
        ``loop``; saved to ``path`` if given.  Returns the matplotlib Figure."""
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        chans = list(channels) if channels is not None else [
            "isolator_disp", "base_shear", f"accel_{self.run.level_names[-1]}", "drift_1"]
        for c in chans:
            if c not in self.measured:
                raise ValueError(f"unknown channel {c!r}; available: {', '.join(self.measured)}")
        t = self.time
        sel = np.ones(t.size, bool) if time_window is None else (t >= time_window[0]) & (t <= time_window[1])
        nrow = len(chans) + (1 if loop else 0)
        fig, axes = plt.subplots(nrow, 1, figsize=(9, 2.3 * nrow), squeeze=False)
        axes = axes[:, 0]
        for ax, c in zip(axes, chans):
            ax.fill_between(t[sel], self.lower[c][sel], self.upper[c][sel], color="C0", alpha=0.3,
                            lw=0, label="95 % band (isolator parameters)")
            ax.plot(t[sel], self.measured[c][sel], color="k", lw=0.8, label="measured")
            ax.plot(t[sel], self.median[c][sel], color="C0", lw=0.8, label="posterior median")
            row = self.table.set_index("channel").loc[c]
            ax.set_ylabel(f"{c} [{_unit(c)}]")
            ax.set_title(f"{c}: NRMSE {100 * row.nrmse:.1f} %, peak error {100 * row.peak_error:+.1f} %, "
                         f"coverage {100 * row.coverage:.0f} %", fontsize=9)
            ax.set_xlabel("time [s]")
        axes[0].legend(fontsize=8, loc="upper right")
        if loop:
            ax = axes[-1]
            ax.plot(self.measured["isolator_disp"], self.measured["base_shear"], color="k", lw=0.6,
                    label="measured")
            ax.plot(self.median["isolator_disp"], self.median["base_shear"], color="C0", lw=0.6,
                    label="posterior median")
            ax.set_xlabel("isolator displacement [m]")
            ax.set_ylabel("isolation-system force [kN]")
            ax.axvline(self.calibrated_peak, color="C3", ls="--", lw=0.8, label="calibrated range")
            ax.axvline(-self.calibrated_peak, color="C3", ls="--", lw=0.8)
            ax.legend(fontsize=8)
        fig.suptitle(f"{self.law} predicting {self.run.name} ({self.n_draws - self.n_failed} draws; "
                     f"peak ratio {self.peak_ratio:.2f})", fontsize=10)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def _channels_measured(run: ShakeTableRun) -> dict[str, np.ndarray]:
    out = {"isolator_disp": run.isolator_disp, "base_shear": run.isolator_force}
    for i, name in enumerate(run.level_names):
        out[f"accel_{name}"] = run.accel[:, i]
    dr = run.drift()
    for j in range(dr.shape[1]):
        out[f"drift_{j + 1}"] = dr[:, j]
    return out


def _channels_model(resp, level_names) -> dict[str, np.ndarray]:
    out = {"isolator_disp": resp.isolator_disp, "base_shear": resp.isolator_force,
           f"accel_{level_names[0]}": resp.base_accel_abs}
    for i, name in enumerate(level_names[1:]):
        out[f"accel_{name}"] = resp.floor_accel_abs[:, i]
    for j in range(resp.drift.shape[1]):
        out[f"drift_{j + 1}"] = resp.drift[:, j]
    return out


def predict_run(
    calibration,
    building,
    run: ShakeTableRun,
    *,
    n_draws: int = 100,
    seed: int = 0,
    level: float = 0.95,
    progress: bool = True,
    local_solver: str | None = None,
) -> RunPrediction:
    """Predict ``run`` with ``building`` whose isolator follows posterior draws of ``calibration``.

    Parameters
    ----------
    calibration : ``rrfrei.Calibration`` of the isolation system (its law must be the building's).
    building : :class:`structures.ShearBuilding` with as many stories as the run has levels - 1
        (e.g. ``identify_superstructure(run).building(calibration)``).
    run : the run to predict; its table acceleration drives the model at its sampling step.
    n_draws : posterior draws (chosen with ``seed``).
    level : central band probability.
    progress : tqdm bar over the draws.
    local_solver : passed to :func:`structures.time_history` when given (e.g. ``"robust"`` for
        Bouc-Wen, if that version of ``time_history`` supports it).

    A draw whose analysis fails (``ConvergenceError`` or a numerical failure) is counted in
    ``n_failed`` and left out of the bands; ValueError if every draw fails.
    """
    from tqdm.auto import tqdm  # deferred, as everywhere: only a run with a bar needs it

    if not isinstance(run, ShakeTableRun):
        raise ValueError(f"run must be a ShakeTableRun, got {type(run).__name__}")
    if not isinstance(building, ShearBuilding):
        raise ValueError(f"building must be a structures.ShearBuilding, got {type(building).__name__}")
    if building.n_stories != run.n_levels - 1:
        raise ValueError(f"building has {building.n_stories} stories but run {run.name!r} has "
                         f"{run.n_levels} levels (= {run.n_levels - 1} stories above the base slab)")
    law = getattr(calibration, "law", None)
    if law is None or not hasattr(calibration, "draws"):
        raise ValueError(f"calibration must be a rrfrei.Calibration, got {type(calibration).__name__}")
    if building.isolator.spec.name != calibration.spec.name:
        raise ValueError(f"the building's isolator law {building.isolator.law!r} differs from the "
                         f"calibration's {law!r}")
    if isinstance(n_draws, bool) or not isinstance(n_draws, (int, np.integer)) or n_draws < 2:
        raise ValueError(f"n_draws = {n_draws!r} is invalid: expected an integer >= 2")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level = {level!r} is invalid: expected 0 < level < 1")
    kwargs = {}
    if local_solver is not None:
        if "local_solver" not in inspect.signature(time_history).parameters:
            raise ValueError(f"local_solver = {local_solver!r}: this structures.time_history has no "
                             "local_solver option")
        kwargs["local_solver"] = local_solver
    draws = calibration.draws(n_draws, seed=seed)
    names = list(calibration.spec.param_names)
    P = draws[names].to_numpy(dtype=float)
    record = run.record()
    sims: dict[str, list[np.ndarray]] = {}
    failures: list[str] = []
    for i in tqdm(range(P.shape[0]), disable=not progress, desc=f"{run.name}: draws", leave=False):
        try:
            resp = time_history(building.with_isolator_params(P[i]), record, **kwargs)
        except (ConvergenceError, ArithmeticError, np.linalg.LinAlgError, ValueError) as exc:
            failures.append(f"draw {i}: {type(exc).__name__}: {str(exc)[:300]}")
            continue
        for k, v in _channels_model(resp, run.level_names).items():
            sims.setdefault(k, []).append(np.asarray(v))
    if not sims:
        raise ValueError(f"every one of the {P.shape[0]} analyses of run {run.name!r} failed; first: "
                         f"{failures[0]}")
    if failures:
        warnings.warn(f"{len(failures)} of {P.shape[0]} analyses of run {run.name!r} failed "
                      f"(left out of the bands); first: {failures[0]}", UserWarning, stacklevel=2)
    meas = _channels_measured(run)
    q = 100.0 * np.array([(1 - level) / 2, 0.5, (1 + level) / 2])
    med, lo, hi, rows = {}, {}, {}, []
    for c, m in meas.items():
        stack = np.vstack(sims[c])
        lo[c], med[c], hi[c] = np.percentile(stack, q, axis=0)
        pk_m = float(np.max(np.abs(m)))
        pk_p = float(np.max(np.abs(med[c])))
        cov = float(np.mean((m >= lo[c]) & (m <= hi[c])))
        rows.append((c, _unit(c).replace("$^2$", "^2"), nrmse(m, med[c]), pk_m, pk_p,
                     (pk_p - pk_m) / pk_m if pk_m > 0 else math.nan, cov))
    table = pd.DataFrame(rows, columns=["channel", "unit", "nrmse", "peak_measured", "peak_predicted",
                                        "peak_error", "coverage"])
    cal_peak = float(np.max(np.abs(calibration.test.disp)))
    ratio = float(np.max(np.abs(run.isolator_disp)) / cal_peak)
    if ratio > 1.0:
        warnings.warn(
            f"run {run.name!r} reaches {ratio:.2f} x the largest isolator displacement of the calibration "
            f"test ({cal_peak:.3g} m): the law is extrapolated beyond the data it was calibrated on",
            UserWarning, stacklevel=2)
    return RunPrediction(run=run, law=str(law), time=np.asarray(run.time) - float(run.time[0]),
                         measured=meas, median=med, lower=lo, upper=hi, table=table, peak_ratio=ratio,
                         calibrated_peak=cal_peak, n_draws=int(P.shape[0]), n_failed=len(failures),
                         failures=failures)
