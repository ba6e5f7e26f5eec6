"""Checks of a shake-table run's channels: consistency of every acceleration with the second
derivative of its displacement (:func:`check_consistency`), and whether the levels or the masses
look listed upside down (:func:`check_level_order`)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import scipy.signal

from structures.shake_table.consistency import ConsistencyReport
from structures.shake_table.filters import derivative, lowpass, second_derivative
from structures.shake_table.run import ShakeTableRun

__all__ = ["ConsistencyWarning", "LevelOrderWarning", "MASS_ORDER_GAIN",
           "UPSIDE_DOWN_RATIO", "check_consistency", "check_level_order", "story_fit_r2"]

_MIN_FILTER_SAMPLES = 15
"""sosfiltfilt's default pad length for the 4th-order low-pass of :func:`check_consistency`."""


class ConsistencyWarning(UserWarning):
    """A run's channels disagree (acceleration vs. displacement) beyond the tolerance."""


class LevelOrderWarning(ConsistencyWarning):
    """The levels of a run look upside down, or its masses look listed in the opposite order."""


# ---------------------------------------------------------------------------------- consistency
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
    run's) [t]: how well the records follow a shear building
    (``structures.shake_table.identify`` fits the same equation, with uncertainty)."""
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
