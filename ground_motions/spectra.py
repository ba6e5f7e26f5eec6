"""Linear SDOF response spectra by the exact piecewise-linear recurrence, and the ASCE 7 shape.

The oscillator is ``u'' + 2 zeta w u' + w^2 u = -a_g(t)`` (``u`` relative displacement [m],
``w = 2 pi / T``) from rest.  With ``a_g`` linear between samples, the state at step ``i+1`` is
an exact linear function of the state at ``i`` and the two end values of the load ``p = -a_g``
(Nigam & Jennings 1969, "Calculation of response spectra from strong-motion earthquake
records", BSSA 59(2); coefficients as in Chopra, *Dynamics of Structures*, 4th ed., Table 5.2.1,
written here for unit mass, ``k = w^2``)::

    u_{i+1} = A u_i + B v_i + C p_i + D p_{i+1}
    v_{i+1} = A' u_i + B' v_i + C' p_i + D' p_{i+1}

so the only error is the assumption of a linear ``a_g`` between samples (the file's own
interpolation) and peaks falling between samples. The coefficients are checked against the
matrix exponential of the augmented state-space system (``tests/test_spectra.py``).

Kernels (``@njit``): ``coefficients`` (public: the benchmark's NumPy peer reads it),
``_history`` (one period, full history) and ``_peaks`` (``prange`` over periods, peak ``|u|``
only, no allocation in the time loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .record import G, ReadOnlyArrays, Record


@njit(cache=True)
def coefficients(w: float, zeta: float, dt: float) -> tuple:
    """Nigam-Jennings coefficients (A, B, C, D, A', B', C', D') for unit mass, 0 <= zeta < 1."""
    k = w * w
    s1z = math.sqrt(1.0 - zeta * zeta)
    wd = w * s1z
    e = math.exp(-zeta * w * dt)
    s = math.sin(wd * dt)
    c = math.cos(wd * dt)
    r = zeta / s1z
    wdt = w * dt
    a = e * (r * s + c)
    b = e * s / wd
    cc = (
        2.0 * zeta / wdt
        + e * (((1.0 - 2.0 * zeta * zeta) / (wd * dt) - r) * s - (1.0 + 2.0 * zeta / wdt) * c)
    ) / k
    d = (1.0 - 2.0 * zeta / wdt + e * ((2.0 * zeta * zeta - 1.0) / (wd * dt) * s + 2.0 * zeta / wdt * c)) / k
    ap = -e * w / s1z * s
    bp = e * (c - r * s)
    cp = (-1.0 / dt + e * ((w / s1z + r / dt) * s + c / dt)) / k
    dp = (1.0 - e * (r * s + c)) / (k * dt)
    return a, b, cc, d, ap, bp, cp, dp


@njit(cache=True)
def _history(ag: np.ndarray, dt: float, w: float, zeta: float, u: np.ndarray, v: np.ndarray) -> None:
    """Fill ``u``, ``v`` (length of ``ag``) with the response from rest to ``-ag``."""
    a, b, cc, d, ap, bp, cp, dp = coefficients(w, zeta, dt)
    u[0] = 0.0
    v[0] = 0.0
    for i in range(ag.size - 1):
        p0 = -ag[i]
        p1 = -ag[i + 1]
        u[i + 1] = a * u[i] + b * v[i] + cc * p0 + d * p1
        v[i + 1] = ap * u[i] + bp * v[i] + cp * p0 + dp * p1


@njit(cache=True, parallel=True)
def _peaks(ag: np.ndarray, dt: float, omegas: np.ndarray, zeta: float, sd: np.ndarray) -> None:
    """``sd[j] = max_i |u_i|`` for each circular frequency ``omegas[j]`` (0 -> rigid, sd = 0)."""
    for j in prange(omegas.size):
        w = omegas[j]
        if w <= 0.0:
            sd[j] = 0.0
            continue
        a, b, cc, d, ap, bp, cp, dp = coefficients(w, zeta, dt)
        u = 0.0
        v = 0.0
        peak = 0.0
        for i in range(ag.size - 1):
            p0 = -ag[i]
            p1 = -ag[i + 1]
            un = a * u + b * v + cc * p0 + d * p1
            v = ap * u + bp * v + cp * p0 + dp * p1
            u = un
            if abs(u) > peak:
                peak = abs(u)
        sd[j] = peak


@dataclass(frozen=True, eq=False)
class Spectrum(ReadOnlyArrays):
    """A response spectrum (arrays read-only).

    Attributes
    ----------
    periods
        Natural periods T [s] (``T = 0`` is the rigid limit: ``psa = PGA``).
    sd
        Peak relative displacement [m].
    sv
        Pseudo-spectral velocity ``w * sd`` [m/s].
    psa
        Pseudo-spectral acceleration ``w^2 * sd`` [m/s^2].
    damping
        Ratio of critical damping.
    name
        The record's name.
    """

    periods: np.ndarray
    sd: np.ndarray
    sv: np.ndarray
    psa: np.ndarray
    damping: float = 0.05
    name: str = ""

    ARRAYS = ("periods", "sd", "sv", "psa")

    def __post_init__(self) -> None:
        self._freeze()

    def at(self, period: float | np.ndarray) -> np.ndarray:
        """PSA [m/s^2] at ``period`` [s] by linear interpolation (clamped at the ends)."""
        return np.interp(period, self.periods, self.psa)


def _check_damping(damping: float) -> float:
    z = float(damping)
    if not (0.0 <= z < 1.0):
        raise ValueError(f"damping must be a ratio in [0, 1), got {damping!r}")
    return z


def _check_periods(periods) -> np.ndarray:
    t = np.atleast_1d(np.asarray(periods, dtype=np.float64))
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"periods must be a non-empty 1-D array of seconds, got shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t) | (t < 0.0))
    if bad.size:
        raise ValueError(f"periods[{int(bad[0])}] = {float(t[bad[0]])!r}: periods must be finite and >= 0 s")
    return t


def response_spectrum(record: Record, periods, damping: float = 0.05) -> Spectrum:
    """Linear elastic response spectrum of ``record`` by the exact piecewise-linear recurrence.

    Parameters
    ----------
    record
        Ground motion (``accel`` [m/s^2], ``dt`` [s]).
    periods
        Natural periods [s], each ``>= 0`` (0 gives the rigid limit ``psa = PGA``, ``sd = 0``).
    damping
        Ratio of critical damping, ``0 <= damping < 1``.

    Returns
    -------
    Spectrum
        ``sd = max|u|`` [m], ``sv = w sd`` [m/s], ``psa = w^2 sd`` [m/s^2] (pseudo quantities).

    Notes
    -----
    The response is evaluated at the record's samples only, so a peak between samples is missed;
    for ``T < 10 dt`` resample the record first (``record.resampled(dt / k)``) if that matters.
    """
    if not isinstance(record, Record):
        raise ValueError(f"record must be a ground_motions.Record, got {type(record).__name__}")
    t = _check_periods(periods)
    z = _check_damping(damping)
    w = np.where(t > 0.0, 2.0 * np.pi / np.where(t > 0.0, t, 1.0), 0.0)
    sd = np.empty(t.size)
    _peaks(np.ascontiguousarray(record.accel), record.dt, w, z, sd)
    psa = np.where(t > 0.0, w * w * sd, record.pga)
    return Spectrum(t, sd, w * sd, psa, z, record.name)


def sdof_response(record: Record, period: float, damping: float = 0.05) -> tuple[np.ndarray, ...]:
    """Full response of one oscillator from rest: ``(u [m], v [m/s], a_abs [m/s^2])``.

    ``a_abs = u'' + a_g = -(2 zeta w v + w^2 u)`` is the absolute acceleration.
    """
    t = _check_periods(period)
    if t.size != 1 or t[0] <= 0.0:
        raise ValueError(f"period must be one value > 0 s, got {period!r}")
    z = _check_damping(damping)
    w = 2.0 * np.pi / t[0]
    u = np.empty(record.npts)
    v = np.empty(record.npts)
    _history(np.ascontiguousarray(record.accel), record.dt, w, z, u, v)
    return u, v, -(2.0 * z * w * v + w * w * u)


def design_spectrum(sds: float, sd1: float, tl: float, periods, *, units: str = "g") -> np.ndarray:
    """ASCE 7-22 Two-Period Design Response Spectrum (Section 11.4; the shape of ASCE 7-16 Fig. 11.4-1).

    ASCE 7-22 also defines a Multi-Period spectrum (from USGS values at 22 periods), required for
    modal and response-history analysis; this function gives the two-period shape only.

    With ``T0 = 0.2 SD1/SDS`` and ``TS = SD1/SDS``::

        Sa = SDS (0.4 + 0.6 T/T0)   for T < T0
        Sa = SDS                    for T0 <= T <= TS
        Sa = SD1 / T                for TS < T <= TL
        Sa = SD1 TL / T^2           for T > TL

    Parameters
    ----------
    sds, sd1
        Design spectral accelerations at short periods and at 1 s [g], > 0.
    tl
        Long-period transition period [s].
    periods
        Periods [s], ``>= 0``.
    units
        ``"g"`` (default: same units as ``sds``/``sd1``) or ``"m/s^2"`` (times 9.80665).

    Returns
    -------
    numpy.ndarray
        Sa at ``periods`` in ``units``.
    """
    for label, x in (("sds", sds), ("sd1", sd1), ("tl", tl)):
        if not (math.isfinite(float(x)) and float(x) > 0.0):
            raise ValueError(f"design_spectrum: {label} must be finite and > 0, got {x!r}")
    if units not in ("g", "m/s^2"):
        raise ValueError(f"design_spectrum: units must be 'g' or 'm/s^2', got {units!r}")
    t = _check_periods(periods)
    ts = sd1 / sds
    t0 = 0.2 * ts
    tsafe = np.where(t > 0.0, t, 1.0)
    sa = np.where(
        t < t0,
        sds * (0.4 + 0.6 * t / t0),
        np.where(t <= ts, sds, np.where(t <= tl, sd1 / tsafe, sd1 * tl / tsafe**2)),
    )
    return sa * (G if units == "m/s^2" else 1.0)
