"""Shake-table runs of base-isolated buildings: reading, consistency checks, the isolation system.

A run (:class:`ShakeTableRun`) holds, at a constant sampling step,

* the table acceleration ``table_accel`` [m/s^2] (and its displacement ``table_disp`` [m] if
  measured),
* per level, bottom-up (column 0 = the base slab just above the isolators, last = the roof), the
  absolute acceleration ``accel`` [m/s^2] and the displacement relative to the table ``disp``
  [m]; ``disp[:, 0]`` is therefore the isolator displacement,
* the level masses ``masses`` [t] in the same order.

Two layouts are read by :func:`read_run`:

1. **Folder layout** (the BNCS data of Orozco et al. 2025): files ``a1 ... aN`` (absolute
   accelerations [m/s^2], ``a1`` the roof, ``aN`` the base slab), ``d1 ... dN`` (displacements
   relative to the table [m]), ``u`` (table acceleration [m/s^2]) and optionally ``du`` (table
   displacement [m]), whitespace-separated values (one per line, or all on one line as in some
   BNCS ``d`` files), ``.txt`` or ``.txt.gz``; the sampling rate and the
   level masses come from a TOML sidecar (``run.toml`` inside the folder or ``<folder>.toml``
   next to it) or the arguments ``rate_hz=`` and ``masses=`` / ``weights=``; ``a1=`` (sidecar
   ``[levels] a1``) says whether ``a1`` is the roof (default) or the base slab.
2. **CSV layout**: ``time_s``, ``table_accel_<unit>``, optional ``table_disp_<unit>``, and per
   level ``<LEVEL>_accel_abs_<unit>`` and ``<LEVEL>_disp_rel_<unit>`` (accelerations ``mps2``,
   ``cmps2``, ``g``; displacements ``m``, ``cm``, ``mm``), plain or gzip-compressed, with a TOML
   sidecar (``<stem>.toml`` next to it, else ``shake_table.toml`` in the same folder)::

       [levels]
       names = ["base", "floor2", "floor3", "floor4", "floor5", "roof"]   # bottom-up
       weights = [2275.1, 674.0, 703.0, 1036.3, 1078.1, 593.3]           # or masses = [...]
       weight_unit = "kN"                                                 # or mass_unit = "t"
       g = 9.81                                                           # to convert weights
       [units]                   # optional: units of columns written without a suffix
       accel = "mps2"
       disp = "m"

Every list of levels (names, masses, weights) runs base slab first unless ``level_order =
"roof-first"`` (``[levels] level_order`` or the argument ``level_order=``).  **The sidecar
format, its keys and units, an example for a raw folder and what the reader checks:
``docs/shake_table_data.md``** (command line: ``rrfrei shake-table --rate-hz --weights
--weight-unit --masses --level-order --a1``).

Consistency (:func:`check_consistency`, run by :func:`read_run`): for every level the absolute
acceleration must equal the second derivative of the relative displacement plus the table
acceleration, a_i = d''_i + a_g, and the table displacement must satisfy du'' = a_g; both sides
are low-passed identically (zero-phase Butterworth, 5 Hz by default) since double differentiation
amplifies noise.  A failing check gives a :class:`ConsistencyWarning` and is kept in
``run.consistency``; malformed input (missing file or column, bad value, unknown unit) is a
``ValueError`` naming the file, column and value.  A missing rate or masses, and channels whose
failure is that of a wrong sampling rate (one common scale (f/f')^2 between d'' and the
accelerations), raise :class:`MetadataError`.  :func:`check_level_order` warns
(:class:`LevelOrderWarning`) when the levels look upside down or the masses reversed.

The isolation system (:func:`isolation_test`): with every level above the isolators in the free
body, horizontal equilibrium gives the force the isolators apply to the building

    F_iso(t) = -sum_i m_i a_i(t)      [kN = t m/s^2]

(a_i absolute), exact for any superstructure (the story forces are internal), to be plotted
against the isolator displacement d_0 = ``disp[:, 0]``.
"""

from __future__ import annotations

import gzip
import math
import warnings
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.signal

from ground_motions import Record
from rrfrei._inputs import read_toml
from rrfrei.energy import cycle_metrics
from rrfrei.io import ShearTest

__all__ = [
    "BNCS_WEIGHTS_KN",
    "ConsistencyReport",
    "ConsistencyWarning",
    "LevelOrderWarning",
    "MetadataError",
    "ShakeTableRun",
    "available_runs",
    "check_consistency",
    "check_level_order",
    "isolation_metrics",
    "isolation_test",
    "load_run",
    "open_run",
    "read_run",
    "write_run",
]

G = 9.81
"""Gravity [m/s^2] used to turn level weights into masses (the BNCS source uses 9.81)."""

BNCS_WEIGHTS_KN = (2275.1, 674.0, 703.0, 1036.3, 1078.1, 593.3)
"""Level weights [kN] of the BNCS building, bottom-up (base slab incl. its 406.6 kN addition,
then floors 2-5 and the roof), from the source notebook; the unit kN is inferred (see
``structures/data/shake_table_bncs/PROVENANCE.md``)."""

LEVEL_ORDERS = ("base-first", "roof-first")
"""How a list of levels (masses, weights, names, CSV columns) runs: from the base slab above the
isolators up (``base-first``, the default) or from the roof down (``roof-first``)."""

A1_LEVELS = ("roof", "base")
"""Which level the files ``a1``/``d1`` of the folder layout hold (default ``roof``, the BNCS
convention: ``a1`` the roof, ``aN`` the base slab)."""

ACCEL_UNITS = {"mps2": 1.0, "cmps2": 0.01, "g": G}
DISP_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
MASS_UNITS = {"t": 1.0, "kg": 0.001}
WEIGHT_UNITS = {"kN": 1.0, "N": 0.001, "MN": 1000.0}

_DATA = Path(__file__).with_name("data") / "shake_table_bncs"
_MIN_FILTER_SAMPLES = 15
"""sosfiltfilt's default pad length for the 4th-order low-pass of :func:`check_consistency`."""


class ConsistencyWarning(UserWarning):
    """A run's channels disagree (acceleration vs. displacement) beyond the tolerance."""


class LevelOrderWarning(ConsistencyWarning):
    """The levels of a run look upside down, or its masses look listed in the opposite order."""


class MetadataError(ValueError):
    """A run's sampling rate or level masses are missing, or the channels contradict the rate.

    ``fact`` says what is wrong (with the folder or file); ``what`` names the datum, ``"rate_hz"``
    or ``"masses"`` (``"time"`` for a CSV whose time column the channels contradict);
    ``sidecar`` is the TOML file where it can be stated.  The message ends with how to give it
    from Python; the command line (``rrfrei shake-table``) words that part for its options.
    """

    def __init__(self, fact: str, hint: str, *, what: str, sidecar: str):
        super().__init__(f"{fact}: {hint}")
        self.fact, self.what, self.sidecar = fact, what, sidecar


# ---------------------------------------------------------------------------------- filtering
def lowpass(x: np.ndarray, cutoff_hz: float, fs: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass along axis 0 (``sosfiltfilt``)."""
    sos = scipy.signal.butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """First derivative along axis 0 [unit/s]: five-point central stencil
    (-x[i+2] + 8 x[i+1] - 8 x[i-1] + x[i-2]) / (12 dt), amplitude error (w dt)^4 / 30 (0.04 % at
    2.6 Hz and 50 Hz sampling); ``np.gradient`` at the two samples at each end."""
    x = np.asarray(x, dtype=float)
    out = np.gradient(x, dt, axis=0)
    if x.shape[0] >= 5:
        out[2:-2] = (-x[4:] + 8.0 * x[3:-1] - 8.0 * x[1:-3] + x[:-4]) / (12.0 * dt)
    return out


def second_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """Second derivative along axis 0 [unit/s^2]: five-point central stencil
    (-x[i+2] + 16 x[i+1] - 30 x[i] + 16 x[i-1] - x[i-2]) / (12 dt^2), amplitude error
    (w dt)^4 / 90; repeated ``np.gradient`` at the two samples at each end."""
    x = np.asarray(x, dtype=float)
    out = np.gradient(np.gradient(x, dt, axis=0), dt, axis=0)
    if x.shape[0] >= 5:
        out[2:-2] = (-x[4:] + 16.0 * x[3:-1] - 30.0 * x[2:-2] + 16.0 * x[1:-3] - x[:-4]) / (12.0 * dt * dt)
    return out


# ---------------------------------------------------------------------------------- consistency
@dataclass(frozen=True)
class ConsistencyReport:
    """Agreement of each acceleration with the derivative of its displacement.

    ``table`` has one row per check: ``check`` (``"a_i = d_i'' + a_g"`` per level or
    ``"du'' = a_g"``), ``channel``, ``correlation``, ``amplitude_ratio`` (RMS of the derived
    over the measured, after the low-pass), ``rel_error`` (RMS of the difference over the RMS of
    the measured), ``passed`` (``rel_error <= tol``), and the sampling-rate evidence: ``scale``,
    the least-squares factor c in  measured ~ c x derived  of the accelerations *relative to the
    table* (a_i - a_g against d_i''; a_g against du''), and ``scale_correlation``, their
    correlation.  A second derivative taken at a rate f' instead of the true f is (f'/f)^2 times
    too large, so a wrong rate shows as a common scale c = (f/f')^2 with a high correlation;
    :attr:`implied_rate_hz` is f' sqrt(c).
    """

    table: pd.DataFrame
    cutoff_hz: float
    tol: float
    rate_hz: float = math.nan

    @property
    def ok(self) -> bool:
        return bool(self.table["passed"].all())

    @property
    def scale(self) -> float:
        """Median of the per-check ``scale`` (NaN when no check has signal)."""
        c = self.table["scale"].to_numpy(dtype=float)
        c = c[np.isfinite(c) & (c > 0)]
        return float(np.median(c)) if c.size else math.nan

    @property
    def scale_correlation(self) -> float:
        """Smallest ``scale_correlation`` over the checks with signal."""
        r = self.table["scale_correlation"].to_numpy(dtype=float)
        r = r[np.isfinite(r)]
        return float(r.min()) if r.size else math.nan

    @property
    def implied_rate_hz(self) -> float:
        """The sampling rate [Hz] at which the displacements' second derivative matches the
        accelerations: rate_hz x sqrt(scale)."""
        return self.rate_hz * math.sqrt(self.scale) if self.scale > 0 else math.nan

    def rate_looks_wrong(self, *, rate_tol: float = 0.1, min_correlation: float = 0.9) -> bool:
        """True when most checks fail and every channel shows one common scale (correlation >=
        ``min_correlation``) whose implied rate is more than ``rate_tol`` away from the stated one:
        the signature of a wrong sampling rate (or of displacements in another unit)."""
        n_fail = int((~self.table["passed"]).sum())
        if n_fail * 2 <= len(self.table) or not self.scale_correlation >= min_correlation:
            return False
        return abs(math.sqrt(self.scale) - 1.0) > rate_tol

    @property
    def failures(self) -> list[str]:
        """One line per failing check."""
        bad = self.table[~self.table["passed"]]
        return [f"{r.check} ({r.channel}): relative error {r.rel_error:.3g} > {self.tol:g}, "
                f"correlation {r.correlation:.4f}, amplitude ratio {r.amplitude_ratio:.3f}"
                for r in bad.itertuples()]

    def __str__(self) -> str:
        worst = float(self.table["rel_error"].max())
        head = (f"consistency after a {self.cutoff_hz:g} Hz low-pass: "
                f"{int(self.table['passed'].sum())}/{len(self.table)} checks pass "
                f"(worst relative error {worst:.3g}, tolerance {self.tol:g})")
        lines = [head, *self.failures]
        if not self.ok and self.scale_correlation >= 0.9 and abs(math.sqrt(self.scale) - 1.0) > 0.02:
            lines.append(f"every channel shows one scale (d'' is {1 / self.scale:.3g} x the accelerations, "
                         f"correlation >= {self.scale_correlation:.4f}): the data match a sampling rate of "
                         f"about {self.implied_rate_hz:.3g} Hz, not {self.rate_hz:.3g} Hz (or displacements "
                         "in another unit)")
        return "\n".join(lines)


def _scale(derived: np.ndarray, measured: np.ndarray) -> tuple[float, float]:
    """(c, correlation) of the least-squares fit measured ~ c x derived."""
    xx = float(np.dot(derived, derived))
    yy = float(np.dot(measured, measured))
    if xx == 0.0 or yy == 0.0:
        return math.nan, math.nan
    xy = float(np.dot(derived, measured))
    return xy / xx, xy / math.sqrt(xx * yy)


def _agreement(derived: np.ndarray, measured: np.ndarray) -> tuple[float, float, float]:
    sd_m = float(np.sqrt(np.mean(measured**2)))
    sd_d = float(np.sqrt(np.mean(derived**2)))
    if sd_m == 0.0:
        return math.nan, math.nan, (0.0 if sd_d == 0.0 else math.inf)
    corr = float(np.corrcoef(derived, measured)[0, 1]) if sd_d > 0 else 0.0
    err = float(np.sqrt(np.mean((derived - measured) ** 2)) / sd_m)
    return corr, sd_d / sd_m, err


def check_consistency(run: ShakeTableRun, *, cutoff_hz: float = 5.0, tol: float = 0.1) -> ConsistencyReport:
    """Check a_i = d_i'' + a_g for every level and du'' = a_g (if ``table_disp`` is present).

    Both sides are low-passed at ``cutoff_hz`` (zero-phase 4th-order Butterworth) before they
    are compared, since the second difference amplifies high-frequency noise.  A check passes
    when RMS(derived - measured) / RMS(measured) <= ``tol``.  On the four BNCS runs the relative
    error is 0.004-0.04.
    """
    fs = run.rate_hz
    if not 0.0 < cutoff_hz < fs / 2:
        raise ValueError(f"cutoff_hz = {cutoff_hz!r} is invalid: expected 0 < cutoff < {fs / 2:g} Hz "
                         "(the Nyquist frequency of the run)")
    ag = run.table_accel
    rel_d = lowpass(second_derivative(run.disp, run.dt), cutoff_hz, fs)  # d_i''
    lo_ag = lowpass(ag, cutoff_hz, fs)
    lo_d = rel_d + lo_ag[:, None]
    lo_a = lowpass(run.accel, cutoff_hz, fs)
    rows = []
    for i, name in enumerate(run.level_names):
        c, r, e = _agreement(lo_d[:, i], lo_a[:, i])
        rows.append(("a_i = d_i'' + a_g", name, c, r, e, *_scale(rel_d[:, i], lo_a[:, i] - lo_ag)))
    if run.table_disp is not None:
        du2 = lowpass(second_derivative(run.table_disp, run.dt), cutoff_hz, fs)
        c, r, e = _agreement(du2, lo_ag)
        rows.append(("du'' = a_g", "table", c, r, e, *_scale(du2, lo_ag)))
    df = pd.DataFrame(rows, columns=["check", "channel", "correlation", "amplitude_ratio", "rel_error",
                                     "scale", "scale_correlation"])
    df["passed"] = df["rel_error"] <= tol
    return ConsistencyReport(df, float(cutoff_hz), float(tol), float(fs))


# ---------------------------------------------------------------------------------- level order
UPSIDE_DOWN_RATIO = 0.98
"""The levels look upside down when the RMS displacement relative to the table AND the RMS
absolute acceleration of the level read as the roof are below this fraction of the base slab's,
each profile falling on at least half of its steps."""

MASS_ORDER_GAIN = 1.25
"""The masses look listed in the opposite order when, with them reversed, every story but the top
one fits V_j = k_j delta_j + c_j delta_j' better and the summed unexplained variance falls by this
factor (the top story's shear is one mass times one acceleration: a scale, no evidence)."""


def _bandpass(x: np.ndarray, band: tuple[float, float], fs: float) -> np.ndarray:
    sos = scipy.signal.butter(4, band, btype="band", fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def story_fit_r2(run: ShakeTableRun, masses: np.ndarray | None = None, *,
                 band_hz: tuple[float, float] = (1.0, 15.0)) -> np.ndarray:
    """(L-1,) R^2 of each story's least-squares fit V_j = k_j delta_j + c_j delta_j' (both sides
    band-passed ``band_hz``, zero phase), V_j = -sum_{i>=j} m_i a_i with ``masses`` (default the
    run's) [t]: how well the records follow a shear building (``structures.identify`` fits the same
    equation, with uncertainty)."""
    m = run.masses if masses is None else np.asarray(masses, dtype=float)
    fs = run.rate_hz
    band = (band_hz[0], min(band_hz[1], 0.45 * fs))
    V = -np.cumsum((run.accel * m)[:, ::-1], axis=1)[:, ::-1][:, 1:]
    Vb = _bandpass(V, band, fs)
    db = _bandpass(np.diff(run.disp, axis=1), band, fs)
    vb = derivative(db, run.dt)
    out = np.full(V.shape[1], math.nan)
    for j in range(V.shape[1]):
        X = np.column_stack([db[:, j], vb[:, j]])
        var = float(np.var(Vb[:, j]))
        if var > 0 and np.any(X):
            coef, *_ = np.linalg.lstsq(X, Vb[:, j], rcond=None)
            out[j] = 1.0 - float(np.var(Vb[:, j] - X @ coef)) / var
    return out


def check_level_order(run: ShakeTableRun) -> list[str]:
    """Physical checks that the levels are bottom-up and the masses listed in the same order.

    1. **Levels upside down.**  In a base-isolated building the isolation mode carries most of the
       displacement, and in it the inertia of the superstructure bends every story the same way as
       the isolators: each level's displacement relative to the table is the isolator's plus the
       drifts below it, so it grows from the base slab (the isolator displacement, the smallest) to
       the roof (the largest), and so, in the RMS, does the absolute acceleration.  When both the
       RMS displacement and the RMS acceleration of the level read as the roof are below
       :data:`UPSIDE_DOWN_RATIO` of the base slab's (each profile falling on at least half of its
       steps), the levels are upside down.  (The peak acceleration is not used: higher modes can
       make it largest at the base slab.)
    2. **Masses in the opposite order.**  The masses do not show their own order (a heavy base slab
       is usual, not proof), but the story shears V_j = -sum_{i>=j} m_i a_i do: with the right
       masses they follow the drifts of a shear building (:func:`story_fit_r2`).  When every story
       below the top fits better with the masses reversed, the reversed fit holds (R^2 >= 0.8) and
       the unexplained variance falls by :data:`MASS_ORDER_GAIN`, the masses look listed in the
       opposite order.  Needs 3 levels or more, asymmetric masses and a rate above 10 Hz.

    Returns one message per failed check (empty: nothing found); :func:`read_run` issues them as
    :class:`LevelOrderWarning`.
    """
    L = run.n_levels
    if L < 2:
        return []
    out = []
    names = run.level_names
    d = np.sqrt(np.mean((run.disp - run.disp.mean(axis=0)) ** 2, axis=0))
    a = np.sqrt(np.mean((run.accel - run.accel.mean(axis=0)) ** 2, axis=0))
    if np.all(d > 0) and np.all(a > 0):
        falls = (d[-1] < UPSIDE_DOWN_RATIO * d[0] and a[-1] < UPSIDE_DOWN_RATIO * a[0]
                 and np.mean(np.diff(d) < 0) >= 0.5 and np.mean(np.diff(a) < 0) >= 0.5)
        if falls:
            if run.meta.get("layout") == "folder":
                fix = ("if a1/d1 hold the base slab in this folder, state it: [levels] a1 = \"base\" in "
                       "its run.toml (--a1 base on the command line)")
            else:
                fix = ("check which column holds which level (the columns named for the base slab seem to "
                       "hold the roof's record); [levels] names run base slab first unless [levels] "
                       "level_order = \"roof-first\" (--level-order on the command line)")
            out.append(
                f"the levels look upside down: the RMS displacement relative to the table falls from "
                f"{1e3 * d[0]:.1f} mm at {names[0]!r} (read as the base slab) to {1e3 * d[-1]:.1f} mm at "
                f"{names[-1]!r} (read as the roof), and the RMS absolute acceleration from {a[0]:.3g} to "
                f"{a[-1]:.3g} m/s^2; in a base-isolated building both grow from the base slab to the roof. "
                f"The isolator displacement, isolator force and story shears are wrong until fixed: {fix}")
            return out
    m = run.masses
    if L >= 3 and run.rate_hz > 10.0 and not np.allclose(m, m[::-1], rtol=1e-6) and run.time.size > 200:
        given = story_fit_r2(run)[:-1]
        rev = story_fit_r2(run, m[::-1])[:-1]
        if (np.all(np.isfinite(given)) and np.all(np.isfinite(rev)) and np.all(rev > given)
                and np.min(rev) >= 0.8 and np.sum(1 - given) >= MASS_ORDER_GAIN * np.sum(1 - rev)):
            src = run.meta.get("masses_source", "")
            out.append(
                "the level masses look listed in the opposite order"
                + (f" (from {src}, read {run.meta.get('level_order', 'base-first')})" if src else "")
                + ": the story shears -sum m_i a_i follow the story drifts better with them reversed "
                f"(R^2 of stories 1-{L - 2}: {np.round(given, 3).tolist()} as read, "
                f"{np.round(rev, 3).tolist()} reversed, 1-15 Hz); as read, the base slab {names[0]!r} "
                f"has {m[0]:.4g} t and the roof {names[-1]!r} {m[-1]:.4g} t. List the masses or weights "
                "base slab first, or state [levels] level_order = \"roof-first\" (--level-order "
                "roof-first on the command line)")
    return out


def open_run(spec: str | Path, **read: Any) -> ShakeTableRun:
    """A run from a bundled name (``"ICA50"``, :func:`available_runs`), a folder or a CSV, read by
    :func:`read_run` with the keyword arguments ``read`` (rate, masses, level order ...)."""
    s = str(spec)
    if s in available_runs() and not Path(s).exists():
        return read_run(_DATA / f"{s}.csv.gz", **read)
    if not Path(s).exists():
        raise ValueError(f"run {s!r} is neither a bundled run ({', '.join(available_runs())}) nor an "
                         "existing folder or CSV file")
    return read_run(s, **read)


# ---------------------------------------------------------------------------------- the run
@dataclass(frozen=True, eq=False)
class ShakeTableRun:
    """One shake-table run of a building on isolators (arrays read-only).

    Attributes
    ----------
    name : label (``"ICA50"``).
    time : (n,) time [s], constant step.
    table_accel : (n,) table acceleration [m/s^2].
    accel : (n, L) absolute level accelerations [m/s^2], bottom-up (column 0 = base slab above
        the isolators, last = roof).
    disp : (n, L) level displacements relative to the table [m], same order; ``disp[:, 0]`` is
        the isolator displacement.
    masses : (L,) level masses [t], same order.
    level_names : (L,) labels, same order.
    table_disp : (n,) table displacement [m] or None.
    source : file or folder read ("" when built in memory).
    meta : anything else (rate, decimation, units read).
    consistency : :class:`ConsistencyReport` from reading, or None.
    """

    name: str
    time: np.ndarray
    table_accel: np.ndarray
    accel: np.ndarray
    disp: np.ndarray
    masses: np.ndarray
    level_names: tuple[str, ...]
    table_disp: np.ndarray | None = None
    source: str = ""
    meta: dict = field(default_factory=dict)
    consistency: ConsistencyReport | None = None

    def __post_init__(self) -> None:
        where = f"run {self.name!r}" + (f" ({self.source})" if self.source else "")

        def arr(key, value, ndim):
            try:
                a = np.array(value, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"{where}: {key} must be numeric, got {type(value).__name__}") from None
            if a.ndim != ndim:
                raise ValueError(f"{where}: {key} must be {ndim}-D, got shape {a.shape}")
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                idx = tuple(int(i) for i in bad[0])
                raise ValueError(f"{where}: {key}{list(idx)} = {a[idx]!r} is not finite")
            a.setflags(write=False)
            object.__setattr__(self, key, a)
            return a

        t = arr("time", self.time, 1)
        n = t.size
        if n < 10:
            raise ValueError(f"{where}: {n} samples; at least 10 are needed")
        dt = np.diff(t)
        if not np.all(dt > 0):
            i = int(np.flatnonzero(dt <= 0)[0])
            raise ValueError(f"{where}: time must increase; sample {i + 1} is {t[i + 1]} s after {t[i]} s")
        h = (t[-1] - t[0]) / (n - 1)
        j = int(np.argmax(np.abs(dt - h)))
        if abs(dt[j] - h) > 1e-6 * h + 1e-9:
            raise ValueError(f"{where}: the time step must be constant (mean {h:g} s), but sample {j + 1} "
                             f"follows after {dt[j]:g} s")
        ag = arr("table_accel", self.table_accel, 1)
        a = arr("accel", self.accel, 2)
        d = arr("disp", self.disp, 2)
        m = arr("masses", self.masses, 1)
        if ag.size != n or a.shape[0] != n or d.shape[0] != n:
            raise ValueError(f"{where}: time, table_accel, accel and disp must have the same number of "
                             f"samples; got {n}, {ag.size}, {a.shape[0]}, {d.shape[0]}")
        nl = m.size
        if nl < 1 or a.shape[1] != nl or d.shape[1] != nl:
            raise ValueError(f"{where}: accel {a.shape}, disp {d.shape} and masses ({nl},) must agree on "
                             "the number of levels")
        for i, x in enumerate(m):
            if not x > 0:
                raise ValueError(f"{where}: masses[{i}] = {x:g} t is invalid: expected > 0")
        names = tuple(str(s) for s in self.level_names)
        if len(names) != nl or len(set(names)) != nl:
            raise ValueError(f"{where}: level_names {names!r} must be {nl} distinct labels (bottom-up)")
        object.__setattr__(self, "level_names", names)
        if self.table_disp is not None:
            td = arr("table_disp", self.table_disp, 1)
            if td.size != n:
                raise ValueError(f"{where}: table_disp has {td.size} samples, expected {n}")

    # ---- basic quantities
    @property
    def n_levels(self) -> int:
        return int(self.masses.size)

    @property
    def dt(self) -> float:
        """Sampling step [s]."""
        return float((self.time[-1] - self.time[0]) / (self.time.size - 1))

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.dt

    @property
    def isolator_disp(self) -> np.ndarray:
        """(n,) isolator displacement [m] (base slab relative to the table)."""
        return self.disp[:, 0]

    @property
    def isolator_force(self) -> np.ndarray:
        """(n,) force of the isolation system on the building [kN]: F = -sum_i m_i a_i."""
        return -(self.accel @ self.masses)

    def story_shear(self) -> np.ndarray:
        """(n, L-1) shear in each story [kN], story j between levels j-1 and j (j = 1..L-1):
        V_j = -sum_{i >= j} m_i a_i (the inertia of the levels above, with a minus)."""
        inertia = self.accel * self.masses
        return -np.cumsum(inertia[:, ::-1], axis=1)[:, ::-1][:, 1:]

    def drift(self) -> np.ndarray:
        """(n, L-1) story drifts d_j - d_{j-1} [m]."""
        return np.diff(self.disp, axis=1)

    def record(self):
        """The table acceleration as a ``ground_motions.Record`` (to drive a model)."""
        return Record(self.name, self.dt, np.asarray(self.table_accel), meta={"source": self.source})

    # ---- transformations
    def decimate(self, rate_hz: float) -> ShakeTableRun:
        """The run resampled to ``rate_hz`` (an integer divisor of the current rate).

        Anti-alias first: zero-phase 8th-order Butterworth low-pass at 0.4 x the new rate (80 % of
        the new Nyquist frequency) on every channel, then every q-th sample.  Zero phase keeps
        the channels' mutual relations (a_i = d_i'' + a_g) intact.
        """
        q_float = self.rate_hz / float(rate_hz)
        q = int(round(q_float))
        if q < 1 or abs(q - q_float) > 1e-6 * q_float:
            raise ValueError(f"rate_hz = {rate_hz!r} is invalid for run {self.name!r}: expected the run's "
                             f"rate {self.rate_hz:g} Hz divided by an integer")
        if q == 1:
            return self
        cut = 0.4 * rate_hz

        def dec(x):
            return np.ascontiguousarray(lowpass(np.asarray(x), cut, self.rate_hz, order=8)[::q])

        meta = dict(self.meta, decimated_from_hz=self.rate_hz, anti_alias_hz=cut)
        return replace(self, time=self.time[::q].copy(), table_accel=dec(self.table_accel),
                       accel=dec(self.accel), disp=dec(self.disp),
                       table_disp=None if self.table_disp is None else dec(self.table_disp),
                       meta=meta, consistency=None)

    def window(self, start_s: float, end_s: float) -> ShakeTableRun:
        """The samples with start_s <= t <= end_s (time kept as is)."""
        keep = (self.time >= start_s) & (self.time <= end_s)
        idx = np.flatnonzero(keep)
        if idx.size < 10:
            raise ValueError(f"window [{start_s}, {end_s}] s of run {self.name!r} holds {idx.size} samples; "
                             "at least 10 are needed")
        s = slice(idx[0], idx[-1] + 1)
        return replace(self, time=self.time[s], table_accel=self.table_accel[s], accel=self.accel[s],
                       disp=self.disp[s], table_disp=None if self.table_disp is None else self.table_disp[s],
                       consistency=None)

    def to_frame(self) -> pd.DataFrame:
        """The CSV layout: ``time_s``, ``table_accel_mps2``, (``table_disp_m``,) then per level
        ``<LEVEL>_accel_abs_mps2`` and ``<LEVEL>_disp_rel_m``."""
        cols: dict[str, np.ndarray] = {"time_s": self.time, "table_accel_mps2": self.table_accel}
        if self.table_disp is not None:
            cols["table_disp_m"] = self.table_disp
        for i, name in enumerate(self.level_names):
            cols[f"{name}_accel_abs_mps2"] = self.accel[:, i]
            cols[f"{name}_disp_rel_m"] = self.disp[:, i]
        return pd.DataFrame(cols)


# ---------------------------------------------------------------------------------- reading
def _sidecar_levels(data: Mapping[str, Any], where: str) -> tuple[list[str] | None, np.ndarray | None]:
    lv = data.get("levels", {})
    if not isinstance(lv, Mapping):
        raise ValueError(f"{where}: [levels] must be a table")
    known = {"names", "masses", "mass_unit", "weights", "weight_unit", "g", "level_order", "a1"}
    extra = sorted(set(lv) - known)
    if extra:
        raise ValueError(f"{where}: unknown [levels] key(s) {', '.join(extra)}; "
                         f"accepted: {', '.join(sorted(known))}")
    names = None
    if "names" in lv:
        names = lv["names"]
        if not isinstance(names, list) or not names or not all(isinstance(x, str) for x in names):
            raise ValueError(f"{where}: [levels] names = {names!r} is invalid: expected a non-empty list of "
                             "strings (bottom-up)")
        if len(set(names)) != len(names):
            raise ValueError(f"{where}: [levels] names = {names!r} repeats a label; expected distinct names")
    if "masses" in lv and "weights" in lv:
        raise ValueError(f"{where}: give [levels] masses or weights, not both")
    masses = None
    if "masses" in lv:
        unit = str(lv.get("mass_unit", "t"))
        if unit not in MASS_UNITS:
            raise ValueError(f"{where}: mass_unit = {unit!r} is unknown; "
                             f"expected one of {', '.join(MASS_UNITS)}")
        masses = _numbers(lv["masses"], f"{where}: [levels] masses") * MASS_UNITS[unit]
    elif "weights" in lv:
        unit = str(lv.get("weight_unit", ""))
        if unit not in WEIGHT_UNITS:
            raise ValueError(f"{where}: weight_unit = {unit!r} is missing or unknown; expected one of "
                             f"{', '.join(WEIGHT_UNITS)} (weights need a stated unit)")
        g = lv.get("g", G)
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not (math.isfinite(g) and g > 0):
            raise ValueError(f"{where}: [levels] g = {g!r} is invalid: expected a finite number > 0 [m/s^2]")
        masses = _numbers(lv["weights"], f"{where}: [levels] weights") * WEIGHT_UNITS[unit] / g
    return names, masses


def _numbers(values: Any, what: str) -> np.ndarray:
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a list of numbers, got {values!r}") from None
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{what} must be a non-empty list of numbers, got {values!r}")
    for i, x in enumerate(a):
        if not (math.isfinite(x) and x > 0):
            raise ValueError(f"{what}[{i}] = {x!r} is invalid: expected a finite number > 0")
    return a


def _option(value: Any, key: str, allowed: tuple[str, ...], where: str) -> str | None:
    """A string option of the sidecar or an argument, checked against ``allowed``."""
    if value is None:
        return None
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{where}: {key} = {value!r} is invalid: expected one of "
                         f"{', '.join(repr(a) for a in allowed)}")
    return value


def _order(level_order, side: Mapping[str, Any], where: str) -> tuple[str, str]:
    """(level order, where it was stated): the argument, else [levels] level_order, else base-first."""
    arg = _option(level_order, "level_order", LEVEL_ORDERS, "level_order")
    lv = side.get("levels", {})
    side_order = _option(lv.get("level_order") if isinstance(lv, Mapping) else None,
                         "[levels] level_order", LEVEL_ORDERS, where)
    if arg is not None:
        return arg, "the argument level_order"
    if side_order is not None:
        return side_order, where
    return "base-first", "the default"


def _level_masses(masses, weights, weight_unit: str, side_masses, n_levels: int, where: str,
                  *, sidecar: str = "run.toml") -> np.ndarray:
    if masses is not None and weights is not None:
        raise ValueError("give masses= or weights=, not both")
    if masses is not None:
        m = _numbers(masses, "masses [t]")
    elif weights is not None:
        if weight_unit not in WEIGHT_UNITS:
            raise ValueError(f"weight_unit = {weight_unit!r} is unknown; "
                             f"expected one of {', '.join(WEIGHT_UNITS)}")
        m = _numbers(weights, f"weights [{weight_unit}]") * WEIGHT_UNITS[weight_unit] / G
    elif side_masses is not None:
        m = side_masses
    else:
        raise MetadataError(
            f"{where}: no level masses",
            "give masses= [t] or weights= (base slab first unless level_order='roof-first'), or "
            f"[levels] masses/weights in {sidecar} (docs/shake_table_data.md; for the BNCS building: "
            "weights=structures.shake_table.BNCS_WEIGHTS_KN)", what="masses", sidecar=sidecar)
    if m.size != n_levels:
        raise ValueError(f"{where}: {m.size} level masses for {n_levels} levels")
    return m


def _load_column_file(path: Path) -> np.ndarray:
    try:
        if path.suffix == ".gz":
            with gzip.open(path, "rt", encoding="utf-8") as fh:
                text = fh.read()
        else:
            text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file (byte {exc.start} is not UTF-8 text: a binary "
                         "file, or another encoding); expected one column of numbers") from None
    except (OSError, EOFError, zlib.error) as exc:  # a corrupt .gz: BadGzipFile, EOFError or zlib.error
        raise ValueError(f"{path}: cannot be read as one column of numbers ({exc})") from None
    values: list[float] = []
    for i, line in enumerate(text.splitlines(), start=1):  # one value per line, or rows of values
        for tok in line.split("#", 1)[0].split():
            try:
                x = float(tok)
            except ValueError:
                raise ValueError(f"{path}, line {i}: {tok[:40]!r} is not a number") from None
            if not math.isfinite(x):
                raise ValueError(f"{path}, line {i}: value {tok!r} is not finite")
            values.append(x)
    if not values:
        raise ValueError(f"{path}: no values (empty file); expected numbers, one per line")
    return np.asarray(values, dtype=float)


def _find(folder: Path, stem: str) -> Path | None:
    for ext in (".txt", ".txt.gz", ".gz", ""):
        p = folder / f"{stem}{ext}"
        if p.is_file():
            return p
    return None


def _folder_sidecar(folder: Path) -> dict:
    for p in (folder / "run.toml", folder.with_suffix(".toml")):
        if p.is_file():
            return read_toml(p) | {"_path": str(p)}
    return {}


def _read_folder(folder: Path, name, rate_hz, masses, weights, weight_unit, level_order, a1):
    side = _folder_sidecar(folder)
    where = side.get("_path", str(folder))
    sidecar = side.get("_path", str(folder / "run.toml"))
    order_name, order_from = _order(level_order, side, where)
    lv = side.get("levels", {})
    a1_arg = _option(a1, "a1", A1_LEVELS, "a1")
    a1_side = _option(lv.get("a1") if isinstance(lv, Mapping) else None, "[levels] a1", A1_LEVELS, where)
    a1_level = a1_arg or a1_side or "roof"
    n = 0
    while _find(folder, f"a{n + 1}") is not None:
        n += 1
    if n == 0:
        raise ValueError(f"{folder}: no acceleration files a1, a2, ... (.txt or .txt.gz) in this folder")
    chans: dict[str, np.ndarray] = {}
    files: dict[str, Path] = {}
    for stem in [*(f"a{i}" for i in range(1, n + 1)), *(f"d{i}" for i in range(1, n + 1)), "u"]:
        p = _find(folder, stem)
        if p is None:
            raise ValueError(f"{folder}: file {stem}.txt(.gz) is missing "
                             f"(folder layout: a1..a{n}, d1..d{n}, u, du)")
        chans[stem], files[stem] = _load_column_file(p), p
    p = _find(folder, "du")
    if p is not None:
        chans["du"], files["du"] = _load_column_file(p), p
    lengths = {k: v.size for k, v in chans.items()}
    if len(set(lengths.values())) != 1:
        ref = chans["u"].size
        odd = next(k for k, v in lengths.items() if v != ref)
        raise ValueError(f"{folder}: file {files[odd].name} has {lengths[odd]} values but {files['u'].name} "
                         f"has {ref}; all channels must have the same length")
    rate = rate_hz if rate_hz is not None else side.get("rate_hz")
    if rate is None:
        raise MetadataError(
            f"{folder}: the sampling rate is not stated",
            f"give rate_hz= [Hz] or rate_hz = ... in {sidecar} (docs/shake_table_data.md; the raw BNCS "
            "runs: 200)", what="rate_hz", sidecar=sidecar)
    try:
        if isinstance(rate, bool):
            raise TypeError
        rate = float(rate)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: rate_hz = {rate!r} is invalid: expected a number [Hz]") from None
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"{where}: rate_hz = {rate!r} is invalid: expected a finite number > 0 Hz")
    side_names, side_masses = _sidecar_levels(side, where)
    m = _level_masses(masses, weights, weight_unit, side_masses, n, where, sidecar=sidecar)
    if side_names is not None and len(side_names) != n:
        raise ValueError(f"{where}: [levels] names has {len(side_names)} labels but the folder has {n} "
                         f"levels (a1..a{n})")
    if order_name == "roof-first":  # the lists were given roof first: put them bottom-up
        m = m[::-1].copy()
        side_names = None if side_names is None else side_names[::-1]
    # bottom-up: aN (base slab) ... a1 (roof), or a1 ... aN when a1 is the base slab
    order = list(range(n, 0, -1)) if a1_level == "roof" else list(range(1, n + 1))
    names = side_names or [f"a{i}" for i in order]
    nt = chans["u"].size
    return ShakeTableRun(
        name=name or str(side.get("name", folder.name)),
        time=np.arange(nt) / rate,
        table_accel=chans["u"],
        accel=np.column_stack([chans[f"a{i}"] for i in order]),
        disp=np.column_stack([chans[f"d{i}"] for i in order]),
        masses=m,
        level_names=tuple(names),
        table_disp=chans.get("du"),
        source=str(folder),
        meta={"layout": "folder", "rate_hz": rate,
              "rate_source": "the argument rate_hz" if rate_hz is not None else where,
              "level_order": order_name, "level_order_source": order_from, "a1": a1_level, "sidecar": sidecar,
              "masses_source": ("the argument masses" if masses is not None else
                                "the argument weights" if weights is not None else where)},
    )


def _csv_sidecar(path: Path) -> dict:
    stem = path.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    for p in (path.with_name(f"{stem}.toml"), path.with_name("shake_table.toml")):
        if p.is_file():
            return read_toml(p) | {"_path": str(p)}
    return {}


def _unit_of(col: str, kind: str, table: dict[str, float], side_units: Mapping[str, Any],
             where: str) -> float:
    """Factor to SI of a column ``<base>_<unit>`` (or without a suffix: the sidecar's [units])."""
    suffix = col.rsplit("_", 1)[-1]
    if suffix in table:
        return table[suffix]
    unit = side_units.get(kind)
    if unit is None:
        raise ValueError(f"{where}: column {col!r} has no {kind} unit suffix ({', '.join(table)}) and the "
                         f"sidecar has no [units] {kind}")
    if unit not in table:
        raise ValueError(f"{where}: [units] {kind} = {unit!r} is unknown; expected one of {', '.join(table)}")
    return table[unit]


def _read_csv(path: Path, name, masses, weights, weight_unit, level_order, rate_hz):
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError, EOFError, zlib.error) as exc:
        raise ValueError(f"{path}: cannot be read as CSV ({exc})") from None
    side = _csv_sidecar(path)
    where = str(path)
    units = side.get("units", {})
    if not isinstance(units, Mapping):
        raise ValueError(f"{side['_path']}: [units] must be a table (accel = ..., disp = ...), got {units!r}")
    cols = [str(c).strip() for c in df.columns]
    df.columns = cols

    def column(col: str) -> np.ndarray:
        s = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(s))
        if bad.size:
            v = df[col].iloc[bad[0]]
            shown = repr(v) if isinstance(v, str) else repr(float(v))
            raise ValueError(f"{where}: column {col!r}, row {bad[0] + 2}: value {shown} is not a finite "
                             "number")
        return s

    def pick(prefix: str, required: bool) -> str | None:
        hits = [c for c in cols if c == prefix or c.startswith(prefix + "_")]
        if not hits:
            if required:
                raise ValueError(f"{where}: column {prefix}_<unit> is missing; columns are {', '.join(cols)}")
            return None
        return hits[0]

    tcol = pick("time", True)
    tfac = {"s": 1.0, "ms": 1e-3}.get(tcol.rsplit("_", 1)[-1], None) if "_" in tcol else 1.0
    if tfac is None:
        raise ValueError(f"{where}: column {tcol!r}: unknown time unit; expected time_s or time_ms")
    agcol = pick("table_accel", True)
    tdcol = pick("table_disp", False)
    side_names, side_masses = _sidecar_levels(side, side.get("_path", where))
    order_name, order_from = _order(level_order, side, side.get("_path", where))
    lv = side.get("levels", {})
    if isinstance(lv, Mapping) and "a1" in lv:
        raise ValueError(f"{side['_path']}: [levels] a1 is for the folder layout (files a1..aN); a CSV "
                         "names its levels by column")
    found = []
    for c in cols:
        if "_accel_abs" in c:
            found.append(c.split("_accel_abs")[0])
    if side_names is None:
        if not found:
            raise ValueError(f"{where}: no <LEVEL>_accel_abs_<unit> columns; columns are {', '.join(cols)}")
        side_names = found  # file order, taken in the stated level order
    else:
        for lvl in side_names:
            for kind in ("accel_abs", "disp_rel"):
                if pick(f"{lvl}_{kind}", False) is None:
                    raise ValueError(f"{where}: no column {lvl}_{kind}_<unit> for level {lvl!r} of [levels] "
                                     f"names in {side['_path']}; columns are {', '.join(cols)}")
    accel, disp = [], []
    for lvl in side_names:
        ac = pick(f"{lvl}_accel_abs", True)
        dc = pick(f"{lvl}_disp_rel", True)
        accel.append(column(ac) * _unit_of(ac, "accel", ACCEL_UNITS, units, where))
        disp.append(column(dc) * _unit_of(dc, "disp", DISP_UNITS, units, where))
    m = _level_masses(masses, weights, weight_unit, side_masses, len(side_names), side.get("_path", where),
                      sidecar=side.get("_path", str(path.with_name(path.name.split(".")[0] + ".toml"))))
    if order_name == "roof-first":  # the lists were given roof first: put them bottom-up
        m = m[::-1].copy()
        side_names = side_names[::-1]
        accel, disp = accel[::-1], disp[::-1]
    stem = path.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    meta = {"layout": "csv", **{k: v for k, v in side.items() if k not in ("levels", "units", "_path")},
            "level_order": order_name, "level_order_source": order_from,
            "masses_source": ("the argument masses" if masses is not None else
                              "the argument weights" if weights is not None else side.get("_path", where))}
    time = column(tcol) * tfac
    t_rate = (time.size - 1) / (time[-1] - time[0]) if time.size > 1 and time[-1] > time[0] else math.nan
    stated = ((rate_hz, "the argument rate_hz"), (side.get("rate_hz"), f"rate_hz in {side.get('_path')}"))
    for value, given in stated:
        if value is not None and math.isfinite(t_rate) and not (
                isinstance(value, (int, float)) and abs(t_rate - float(value)) <= 1e-6 * t_rate):
            raise ValueError(f"{where}: {given} = {value!r} Hz disagrees with its column {tcol!r} "
                             f"({t_rate:.6g} Hz); a CSV's sampling rate is its time column")
    meta["rate_source"] = f"its column {tcol!r}"
    return ShakeTableRun(
        name=name or str(side.get("name", stem)),
        time=time,
        table_accel=column(agcol) * _unit_of(agcol, "accel", ACCEL_UNITS, units, where),
        accel=np.column_stack(accel),
        disp=np.column_stack(disp),
        masses=m,
        level_names=tuple(side_names),
        table_disp=(None if tdcol is None
                    else column(tdcol) * _unit_of(tdcol, "disp", DISP_UNITS, units, where)),
        source=str(path),
        meta=meta,
    )


def read_run(
    path: str | Path,
    *,
    name: str | None = None,
    rate_hz: float | None = None,
    masses: Sequence[float] | None = None,
    weights: Sequence[float] | None = None,
    weight_unit: str = "kN",
    level_order: str | None = None,
    a1: str | None = None,
    check: bool = True,
    cutoff_hz: float = 5.0,
    tol: float = 0.1,
) -> ShakeTableRun:
    """Read a shake-table run (folder layout or CSV layout, see the module docstring).

    Parameters
    ----------
    path : a folder of ``a1..aN``, ``d1..dN``, ``u``, ``du`` files, or a CSV (``.csv`` /
        ``.csv.gz``) with a TOML sidecar.
    name : label (default: the sidecar's ``name`` or the file/folder name).
    rate_hz : sampling rate of the folder layout [Hz] (default: ``rate_hz`` in its sidecar); for a
        CSV it must agree with the time column.
    masses, weights : level masses [t] or weights [``weight_unit``], in ``level_order``; override
        the sidecar.  Weights are divided by g = 9.81 m/s^2.
    level_order : ``"base-first"`` or ``"roof-first"``: how every list of levels runs (masses,
        weights, sidecar names, the CSV's columns when no names are given); overrides
        ``[levels] level_order`` of the sidecar; default base-first.
    a1 : folder layout: the level of the files ``a1``/``d1``, ``"roof"`` (default, the BNCS
        convention) or ``"base"``; overrides ``[levels] a1`` of the sidecar.
    check : run :func:`check_consistency` (``cutoff_hz``, ``tol``) and :func:`check_level_order`,
        warn on failures, and raise when the failure is that of a wrong sampling rate.

    The sidecar format, its keys and units: ``docs/shake_table_data.md``.

    Raises
    ------
    MissingMetadataError : the sampling rate or the level masses are not stated.
    ValueError : missing file/column, malformed value (names file, column/line and value),
        unknown unit, masses of the wrong count, a sampling rate the channels contradict
        (:meth:`ConsistencyReport.rate_looks_wrong`: "the sampling rate ... looks wrong").

    Warns
    -----
    ConsistencyWarning : a consistency check failed (the report is in ``run.consistency``).
    LevelOrderWarning : the levels look upside down, or the masses listed in the opposite order
        (:func:`check_level_order`).
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"shake-table run {str(p)!r} does not exist (a folder or a CSV file)")
    if p.is_dir():
        run = _read_folder(p, name, rate_hz, masses, weights, weight_unit, level_order, a1)
    else:
        if a1 is not None:
            raise ValueError(f"{p}: a1 is for the folder layout (files a1..aN); a CSV names its levels "
                             "by column")
        run = _read_csv(p, name, masses, weights, weight_unit, level_order, rate_hz)
    if check:
        if run.time.size <= _MIN_FILTER_SAMPLES:
            raise ValueError(f"{run.source}: {run.time.size} samples are too few for the consistency check "
                             f"(the low-pass needs more than {_MIN_FILTER_SAMPLES}); pass check=False")
        try:
            rep = check_consistency(run, cutoff_hz=cutoff_hz, tol=tol)
        except ValueError as exc:
            rate = (f" (rate_hz = {run.meta['rate_hz']!r} Hz from {run.meta['rate_source']})"
                    if "rate_source" in run.meta else "")
            raise ValueError(f"{run.source}{rate}: {exc}") from None
        run = replace(run, consistency=rep)
        if rep.rate_looks_wrong():
            raise _wrong_rate_error(run, rep)
        if not rep.ok:
            warnings.warn(f"run {run.name!r} ({run.source}): " + str(rep), ConsistencyWarning, stacklevel=2)
        for msg in check_level_order(run):
            warnings.warn(f"run {run.name!r} ({run.source}): {msg}", LevelOrderWarning, stacklevel=2)
    return run


def _wrong_rate_error(run: ShakeTableRun, rep: ConsistencyReport) -> MetadataError:
    src = run.meta.get("rate_source", "")
    folder = run.meta.get("layout") == "folder"
    stated = f"{run.rate_hz:.6g} Hz" + (f" ({src})" if src else "")
    n_pass = int(rep.table["passed"].sum())
    unit = "in m" if folder else "in the unit their column names"
    fact = (f"{run.source}: the sampling rate {stated} looks wrong: at {run.rate_hz:.6g} Hz the second "
            f"derivative of the displacements is {1 / rep.scale:.3g} times the measured accelerations "
            f"relative to the table (median of {len(rep.table)} channels, correlation >= "
            f"{rep.scale_correlation:.4f} after a {rep.cutoff_hz:g} Hz low-pass; {n_pass} of "
            f"{len(rep.table)} consistency checks pass), which a rate of about "
            f"{rep.implied_rate_hz:.3g} Hz would explain (or displacements not {unit})")
    if folder:
        sidecar = str(run.meta.get("sidecar") or Path(run.source) / "run.toml")
        hint = f"give the recorder's rate: rate_hz= or rate_hz in {sidecar} (docs/shake_table_data.md)"
        return MetadataError(fact, hint, what="rate_hz", sidecar=sidecar)
    return MetadataError(fact, "check the time column and the unit suffixes (docs/shake_table_data.md)",
                         what="time", sidecar="")


def write_run(run: ShakeTableRun, path: str | Path, *, float_format: str = "%.7g",
              extra: Mapping[str, Any] | None = None) -> Path:
    """Write ``run`` in the CSV layout (gzip if ``path`` ends in ``.gz``) and its TOML sidecar
    ``<stem>.toml`` (level names and masses [t], ``rate_hz`` and ``extra`` keys)."""
    p = Path(path)
    run.to_frame().to_csv(p, index=False, float_format=float_format,
                          compression="gzip" if p.suffix == ".gz" else None)
    stem = p.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    lines = [f'name = "{run.name}"', f"rate_hz = {run.rate_hz:.12g}"]
    for k, v in (extra or {}).items():
        lines.append(f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"')
    lines += ["", "[levels]  # bottom-up: the base slab above the isolators first, the roof last",
              "names = [" + ", ".join(f'"{s}"' for s in run.level_names) + "]",
              "masses = [" + ", ".join(f"{m:.10g}" for m in run.masses) + "]", 'mass_unit = "t"', ""]
    p.with_name(f"{stem}.toml").write_text("\n".join(lines))
    return p


# ---------------------------------------------------------------------------------- bundled runs
def available_runs() -> tuple[str, ...]:
    """Names of the bundled BNCS runs (``CNP100``, ``ICA100``, ``ICA50``, ``LAC100``)."""
    return tuple(sorted(p.name.removesuffix(".csv.gz") for p in _DATA.glob("*.csv.gz")))


def load_run(name: str, *, check: bool = True) -> ShakeTableRun:
    """A bundled BNCS run (50 Hz, anti-alias filtered; see the PROVENANCE.md next to the data)."""
    names = available_runs()
    if name not in names:
        raise ValueError(f"unknown shake-table run {name!r}; bundled: {', '.join(names)}")
    return read_run(_DATA / f"{name}.csv.gz", check=check)


# ---------------------------------------------------------------------------------- isolation system
def isolation_test(run: ShakeTableRun, *, name: str | None = None):
    """The isolation system of ``run`` as a :class:`rrfrei.io.ShearTest`.

    disp = isolator displacement d_0 [m] (base slab relative to the table); force =
    F_iso = -sum_i m_i a_i [kN] over every level above the isolators (base slab included), the
    force the whole isolation layer applies to the building (all bearings together, their
    viscous part included); time [s].  ``rrfrei.calibrate``, ``compare`` and ``diagnose_gap``
    take it unchanged; a law calibrated on it is the *layer* law (count 1, length scale 1).
    """
    return ShearTest(
        name=name or run.name,
        time=np.asarray(run.time) - float(run.time[0]),
        disp=run.isolator_disp,
        force=run.isolator_force,
        has_time=True,
        source=run.source,
        meta={"run": run.name, "force": "-sum_i m_i a_i (all levels above the isolators)",
              "masses_t": [float(x) for x in run.masses], "rate_hz": run.rate_hz},
    )


def _zero_cross_force(u: np.ndarray, f: np.ndarray, i: int) -> float:
    """Force at the zero crossing of u between samples i and i+1 (linear interpolation)."""
    du = u[i + 1] - u[i]
    w = 0.0 if du == 0 else -u[i] / du
    return float(f[i] + w * (f[i + 1] - f[i]))


def isolation_metrics(run: ShakeTableRun, *, eps_frac: float = 0.02) -> pd.DataFrame:
    """Per-cycle metrics of the isolation system of ``run``.

    The columns of :func:`rrfrei.energy.cycle_metrics` (energy EDC [kN m], d+/d- [m], F+/F- [kN],
    k_eff = (F+ - F-)/(d+ - d-) [kN/m], beta_eff = EDC / (2 pi k_eff d^2)) plus ``qd`` [kN], the
    characteristic strength, half the gap between the loading and unloading branches at zero
    displacement: Qd = (F(u = 0, u rising) - F(u = 0, u falling)) / 2, and ``run``.
    """
    u = run.isolator_disp
    f = run.isolator_force
    df = cycle_metrics(u, f, eps_frac=eps_frac)
    qd = []
    for s, e in zip(df["start"], df["end"]):
        f_up = _zero_cross_force(u, f, s) if s + 1 < u.size and u[s] <= 0 < u[s + 1] else float(f[s])
        seg = u[s:e + 1]
        down = np.flatnonzero((seg[:-1] > 0) & (seg[1:] <= 0))
        qd.append(0.5 * (f_up - _zero_cross_force(u, f, s + int(down[0]))) if down.size else math.nan)
    df["qd"] = qd
    df.insert(0, "run", run.name)
    return df
