"""Orientation-independent spectra of a pair of horizontal components: RotD50 and RotD100.

Boore (2010), "Orientation-independent, nongeometric-mean measures of seismic intensity from
two horizontal components of motion", BSSA 100(4), 1830-1835.  For each oscillator period the
relative-displacement histories ``u1(t)``, ``u2(t)`` of the two recorded components are computed
once; the response of the same oscillator to the ground motion along the direction ``theta``
(measured from component 1 towards component 2) is their projection (Boore 2010, Eq. 1)::

    u(t; theta) = u1(t) cos(theta) + u2(t) sin(theta)

because the oscillator is linear.  ``SD(theta) = max_t |u(t; theta)|``; ``RotDnn`` is the
``nn``-th percentile of ``SD(theta)`` over the ``n_angles`` angles ``0, 180/n, ..., 180 - 180/n``
deg (``|u(theta + 180)| = |u(theta)|``, so half a turn covers every direction).  RotD100 is the
maximum over angles (the *maximum-direction* spectrum of ASCE 7-16/7-22), RotD50 the median
(NumPy's linear-interpolation percentile: for 180 angles the mean of the 90th and 91st sorted
values), RotD00 the minimum.  ``PSA = w^2 SD`` and ``PSV = w SD`` as for one component
(:mod:`ground_motions.spectra`); ``T = 0`` is the rigid limit: the percentile of
``max_t |a1 cos(theta) + a2 sin(theta)|``.

The SDOF recursion is the exact piecewise-linear one of :mod:`ground_motions.spectra`
(Nigam & Jennings 1969; the kernel ``spectra._history`` is called, not copied), so a pair whose
second component is zero has RotD100 equal, sample for sample, to the first component's
spectrum.  With a discrete set of angles, RotD100 is within a factor ``cos(90 deg / n_angles)``
of the continuous maximum ``max_t sqrt(u1^2 + u2^2)`` (3.8e-5 for 180 angles).

Kernels (``@njit``): ``_angle_peaks`` (peak of every projection, one pass over time) and
``_rotd_peaks`` (``prange`` over periods; two response histories per period).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .pairs import RecordPair
from .record import ReadOnlyArrays
from .spectra import Spectrum, _check_damping, _check_periods, _history, response_spectrum


@njit(cache=True)
def _angle_peaks(x1: np.ndarray, x2: np.ndarray, c: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """``out[k] = max_i |x1[i] c[k] + x2[i] s[k]|`` (one pass over time, angles inner)."""
    for k in range(out.size):
        out[k] = 0.0
    for i in range(x1.size):
        a = x1[i]
        b = x2[i]
        for k in range(out.size):
            y = abs(a * c[k] + b * s[k])
            if y > out[k]:
                out[k] = y


@njit(cache=True, parallel=True)
def _rotd_peaks(
    ag1: np.ndarray, ag2: np.ndarray, dt: float, omegas: np.ndarray, zeta: float,
    c: np.ndarray, s: np.ndarray, out: np.ndarray,
) -> None:
    """``out[j, k] = max_t |u1 c[k] + u2 s[k]|`` for circular frequency ``omegas[j]`` (0 -> 0)."""
    n = ag1.size
    for j in prange(omegas.size):
        w = omegas[j]
        if w <= 0.0:
            for k in range(c.size):
                out[j, k] = 0.0
            continue
        u1 = np.empty(n)
        u2 = np.empty(n)
        v = np.empty(n)
        _history(ag1, dt, w, zeta, u1, v)
        _history(ag2, dt, w, zeta, u2, v)
        _angle_peaks(u1, u2, c, s, out[j])


def rotate(pair: RecordPair, theta_deg: float) -> RecordPair:
    """The pair with both axes turned by ``theta_deg`` (see :meth:`RecordPair.rotated`)."""
    if not isinstance(pair, RecordPair):
        raise ValueError(f"rotate: pair must be a ground_motions.RecordPair, got {type(pair).__name__}")
    return pair.rotated(theta_deg)


def _angles(n_angles: int) -> np.ndarray:
    n = int(n_angles)
    if n != n_angles or n < 1:
        raise ValueError(f"n_angles must be a whole number >= 1, got {n_angles!r}")
    return np.arange(n) * (180.0 / n)


def _percentiles(percentile) -> tuple[float, ...]:
    pcts = tuple(float(p) for p in np.atleast_1d(np.asarray(percentile, dtype=np.float64)))
    if not pcts or any(not (0.0 <= p <= 100.0) for p in pcts):
        raise ValueError(f"percentile must be one or more values in [0, 100], got {percentile!r}")
    return pcts


@dataclass(frozen=True, eq=False)
class RotDSpectrum(ReadOnlyArrays):
    """RotDnn spectra of a pair (arrays read-only).

    Attributes
    ----------
    periods
        Natural periods T [s].
    percentiles
        The ``nn`` of each row (e.g. ``(50.0, 100.0)``).
    sd
        ``(len(percentiles), len(periods))`` RotDnn spectral displacement [m] (0 at T = 0).
    psa
        Same shape: pseudo-spectral acceleration ``w^2 sd`` [m/s^2] (T = 0: RotDnn of PGA).
    angles
        The angles [deg] from component 1 towards component 2.
    angle_sd
        ``(len(periods), len(angles))``: peak ``|u(theta)|`` [m] for every angle.
    damping, name
        Ratio of critical damping; the pair's name.
    """

    periods: np.ndarray
    percentiles: tuple[float, ...]
    sd: np.ndarray
    psa: np.ndarray
    angles: np.ndarray
    angle_sd: np.ndarray
    damping: float = 0.05
    name: str = ""

    ARRAYS = ("periods", "sd", "psa", "angles", "angle_sd")

    def __post_init__(self) -> None:
        self._freeze()
        object.__setattr__(self, "percentiles", tuple(float(p) for p in self.percentiles))

    def _row(self, nn: float) -> int:
        for i, p in enumerate(self.percentiles):
            if p == float(nn):
                return i
        raise ValueError(f"RotD{nn:g} was not computed; percentiles: {self.percentiles}")

    def spectrum(self, nn: float) -> Spectrum:
        """The RotD``nn`` spectrum as a :class:`Spectrum` named ``"<name> RotD<nn>"``."""
        i = self._row(nn)
        t = self.periods
        w = np.where(t > 0.0, 2.0 * np.pi / np.where(t > 0.0, t, 1.0), 0.0)
        return Spectrum(t, self.sd[i], w * self.sd[i], self.psa[i], self.damping, f"{self.name} RotD{nn:g}")

    @property
    def rotd50(self) -> Spectrum:
        """The median over angles (requires 50 among ``percentiles``)."""
        return self.spectrum(50.0)

    @property
    def rotd100(self) -> Spectrum:
        """The maximum over angles: the maximum-direction spectrum (requires 100)."""
        return self.spectrum(100.0)


def rotd_spectrum(
    pair: RecordPair,
    periods,
    damping: float = 0.05,
    percentile=(50, 100),
    n_angles: int = 180,
) -> RotDSpectrum:
    """RotDnn spectra of a pair of horizontal components (Boore 2010; module docstring).

    Parameters
    ----------
    pair
        The two horizontal components (``accel`` [m/s^2]).
    periods
        Natural periods [s], each ``>= 0``.
    damping
        Ratio of critical damping, ``0 <= damping < 1``.
    percentile
        One value or several in ``[0, 100]``: 50 -> RotD50, 100 -> RotD100, 0 -> RotD00.
    n_angles
        Number of angles over half a turn (step ``180 / n_angles`` deg; Boore uses 1 deg).

    Returns
    -------
    RotDSpectrum
        ``sd`` [m] and ``psa`` [m/s^2] per percentile, and the peak per angle.
    """
    if not isinstance(pair, RecordPair):
        raise ValueError(
            f"rotd_spectrum: pair must be a ground_motions.RecordPair, got {type(pair).__name__}"
        )
    t = _check_periods(periods)
    z = _check_damping(damping)
    pcts = _percentiles(percentile)
    ang = _angles(n_angles)
    rad = np.radians(ang)
    c, s = np.cos(rad), np.sin(rad)
    w = np.where(t > 0.0, 2.0 * np.pi / np.where(t > 0.0, t, 1.0), 0.0)
    a1 = np.ascontiguousarray(pair.accel[:, 0])
    a2 = np.ascontiguousarray(pair.accel[:, 1])
    peaks = np.empty((t.size, ang.size))
    _rotd_peaks(a1, a2, pair.dt, w, z, c, s, peaks)
    sd = np.percentile(peaks, pcts, axis=1)
    psa = (w * w)[None, :] * sd
    if np.any(t == 0.0):
        pga = np.empty(ang.size)
        _angle_peaks(a1, a2, c, s, pga)
        psa[:, t == 0.0] = np.percentile(pga, pcts)[:, None]
    return RotDSpectrum(t, pcts, sd, psa, ang, peaks, z, pair.name)


def component_spectra(pair: RecordPair, periods, damping: float = 0.05) -> tuple[Spectrum, Spectrum]:
    """The two components' own spectra (:func:`ground_motions.response_spectrum`), named by component."""
    out = []
    for rec, comp in zip((pair.first, pair.second), pair.components):
        sp = response_spectrum(rec, periods, damping)
        out.append(Spectrum(sp.periods, sp.sd, sp.sv, sp.psa, sp.damping,
                            f"{pair.name} {comp}".strip() if comp else rec.name))
    return out[0], out[1]
