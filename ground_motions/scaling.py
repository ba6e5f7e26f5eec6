"""Amplitude scaling of records: to a target PGA, or to a target spectrum over a period range."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from .record import Record
from .spectra import Spectrum, response_spectrum

Target = Spectrum | Callable[[np.ndarray], np.ndarray] | tuple[np.ndarray, np.ndarray]


def scale_to_pga(record: Record, pga: float) -> Record:
    """A copy of ``record`` scaled so that its PGA equals ``pga`` [m/s^2] (factor in ``meta``)."""
    target = float(pga)
    if not (math.isfinite(target) and target > 0.0):
        raise ValueError(f"scale_to_pga: pga must be finite and > 0 m/s^2, got {pga!r}")
    if record.pga == 0.0:
        raise ValueError(f"scale_to_pga: record {record.name!r} has zero PGA and cannot be scaled")
    return record.scaled(target / record.pga)


def target_psa(target: Target, periods: np.ndarray, where: str = "scale_to_spectrum") -> np.ndarray:
    """The target spectrum's PSA [m/s^2] at ``periods`` [s]: from a :class:`Spectrum`, a callable
    T -> PSA, or a (periods, psa) pair (linear interpolation; it must cover ``periods``: never
    extrapolated).  ValueError, prefixed by ``where``, for anything else or a PSA <= 0."""
    if isinstance(target, Spectrum):
        values = target.at(periods)
    elif callable(target):
        values = np.asarray(target(periods), dtype=np.float64)
    else:
        try:
            tp, tv = (np.asarray(x, dtype=np.float64) for x in target)
        except (TypeError, ValueError):
            raise ValueError(
                f"{where}: target must be a Spectrum, a callable T -> PSA [m/s^2] (e.g. "
                f"ground_motions.mcer_target(sds, sd1, tl)) or a (periods, psa) pair, got "
                f"{type(target).__name__}"
            ) from None
        if tp.ndim != 1 or tp.shape != tv.shape or tp.size < 2 or np.any(np.diff(tp) <= 0):
            raise ValueError(
                f"{where}: a (periods, psa) target needs two 1-D arrays of equal length >= 2 "
                "with increasing periods"
            )
        if periods[0] < tp[0] or periods[-1] > tp[-1]:
            raise ValueError(
                f"{where}: the target is given for T = {tp[0]:g}..{tp[-1]:g} s, not over the periods "
                f"{periods[0]:g}..{periods[-1]:g} s"
            )
        values = np.interp(periods, tp, tv)
    values = np.broadcast_to(values, periods.shape)
    ok = np.isfinite(values) & (values > 0.0)
    if not np.all(ok):
        i = int(np.flatnonzero(~ok)[0])
        raise ValueError(
            f"{where}: target PSA at T = {periods[i]:g} s is {float(values[i])!r}; must be finite "
            "and > 0 m/s^2"
        )
    return np.array(values, dtype=np.float64)


def scale_to_spectrum(
    records: Sequence[Record],
    target: Target,
    period_range: tuple[float, float],
    damping: float = 0.05,
    *,
    method: str = "log-ls",
    n_periods: int = 50,
) -> list[tuple[Record, float]]:
    """Scale each record to a target spectrum over ``period_range``.

    Parameters
    ----------
    records
        The ground motions.
    target
        Target PSA in m/s^2: a :class:`Spectrum`, a callable ``T -> PSA`` (e.g.
        ``lambda T: design_spectrum(sds, sd1, tl, T, units="m/s^2")``) or a ``(periods, psa)``
        pair (interpolated linearly).
    period_range
        ``(T_lo, T_hi)`` [s], ``0 < T_lo < T_hi``; compared on ``n_periods`` log-spaced periods.
    damping
        Ratio of critical damping of the spectra.
    method
        ``"log-ls"``: each factor minimises ``sum_T (ln(f PSA(T)) - ln target(T))^2``, i.e.
        ``f = exp(mean(ln target - ln PSA))`` (the geometric-mean match; records keep their
        spectral shape). ``"asce7"``: the log-ls factors, then one common factor so that the
        suite's mean spectrum is nowhere below 90 % of the target in the range (the ASCE 7-22
        Section 16.2.3 rule, applied to single components).

    Returns
    -------
    list of (Record, float)
        The scaled copy of each record and its factor, in input order.
    """
    if method not in ("log-ls", "asce7"):
        raise ValueError(f"scale_to_spectrum: method must be 'log-ls' or 'asce7', got {method!r}")
    lo, hi = (float(x) for x in period_range)
    if not (0.0 < lo < hi and math.isfinite(hi)):
        raise ValueError(
            f"scale_to_spectrum: period_range must satisfy 0 < T_lo < T_hi, got {period_range!r}"
        )
    recs = list(records)
    if not recs:
        raise ValueError("scale_to_spectrum: no records given")
    periods = np.geomspace(lo, hi, int(n_periods))
    tgt = target_psa(target, periods)
    psa = np.array([response_spectrum(r, periods, damping).psa for r in recs])
    if np.any(psa <= 0.0):
        raise ValueError("scale_to_spectrum: a record has zero spectral acceleration in the period range")
    factors = np.exp(np.mean(np.log(tgt)[None, :] - np.log(psa), axis=1))
    if method == "asce7":
        mean = np.mean(factors[:, None] * psa, axis=0)
        worst = float(np.min(mean / tgt))
        if worst < 0.9:
            factors = factors * (0.9 / worst)
    return [(r.scaled(float(f)), float(f)) for r, f in zip(recs, factors)]
