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


def _target_psa(target: Target, periods: np.ndarray) -> np.ndarray:
    if isinstance(target, Spectrum):
        values = target.at(periods)
    elif callable(target):
        values = np.asarray(target(periods), dtype=np.float64)
    else:
        try:
            tp, tv = (np.asarray(x, dtype=np.float64) for x in target)
        except (TypeError, ValueError):
            raise ValueError(
                "scale_to_spectrum: target must be a Spectrum, a callable T -> PSA [m/s^2], or a "
                f"(periods, psa) pair, got {type(target).__name__}"
            ) from None
        values = np.interp(periods, tp, tv)
    values = np.broadcast_to(values, periods.shape)
    if not np.all(np.isfinite(values) & (values > 0.0)):
        bad = int(np.flatnonzero(~(np.isfinite(values) & (values > 0.0)))[0])
        raise ValueError(
            f"scale_to_spectrum: target PSA at T = {periods[bad]:g} s is {values[bad]!r}; must be > 0"
        )
    return values


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
    tgt = _target_psa(target, periods)
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
