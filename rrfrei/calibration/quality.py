"""How far a calibration may be read: its fit's adequacy and the parameters pressed on a bound.

A band's coverage says nothing of a fit's adequacy: with i.i.d. Gaussian noise the noise sd
absorbs whatever the law misses, so a law that cannot reproduce a test's shape still gets a 95 %
band that covers ~95 % of the samples.  What the law misses shows in the *systematic part* of the
gap, the error left once the white noise is taken out (the definitions of
:mod:`rrfrei.gap.residuals`), for measured force ``y`` and predicted (posterior-mean) force ``f``::

    NRMSE      = RMS(y - f) / RMS(y)
    systematic = sqrt(max(MSE - s_w^2, 0)) / RMS(y)

with ``s_w`` the white-noise sd of the residual series ``y - f`` from its successive differences
(robust MAD: ``s_w = 1.4826 MAD(diff(y - f)) / sqrt(2)``), which a smooth misfit barely enters.

:func:`adequacy` turns the three numbers into one reading: ``adequate`` (systematic part at most
:data:`ADEQUATE` of the force RMS), ``marginal`` (up to :data:`INADEQUATE`) or ``inadequate``.

:func:`at_bounds` names the sampled parameters whose MAP lies within :data:`NEAR_BOUND` of the
width of their admissible range (prior support cut to the physical bounds, on the prior's log
scale for a log prior) from one of its ends: the data pushed them there, so the law reaches its
best fit only at an edge of what it allows (or the range is too narrow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ADEQUATE", "INADEQUATE", "NEAR_BOUND", "Adequacy", "adequacy", "at_bounds",
           "bounds_text", "white_noise_sd"]

ADEQUATE = 0.05
"""Largest systematic part of the gap (fraction of the force RMS) of an adequate fit."""
INADEQUATE = 0.15
"""Systematic part of the gap above which a fit is inadequate (between: marginal)."""
NEAR_BOUND = 0.01
"""A MAP within this fraction of its parameter's admissible range from an end is at that bound."""


def white_noise_sd(resid: np.ndarray) -> float:
    """White-noise sd of a residual series from its successive differences (robust MAD) [kN]."""
    d = np.diff(np.asarray(resid, dtype=float))
    if d.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


@dataclass(frozen=True)
class Adequacy:
    """NRMSE, its systematic part and the band's coverage of one prediction, and their reading."""

    nrmse: float
    systematic: float
    coverage: float
    level: str
    """``"adequate"``, ``"marginal"`` or ``"inadequate"``."""

    @property
    def sentence(self) -> str:
        """One sentence on adequacy, e.g. ``inadequate: NRMSE 45 % (systematic 44 %), ...``."""
        nums = (f"NRMSE {_pct(self.nrmse)} (systematic {_pct(self.systematic)}), "
                f"coverage {_pct(self.coverage)}")
        if self.level == "adequate":
            return f"adequate: {nums}: what the law misses is mostly noise"
        if self.level == "marginal":
            return (f"marginal: {nums}: the law misses part of this test's shape; the band's "
                    "coverage comes partly from a noise sd that absorbs the misfit")
        return (f"inadequate: {nums}: the law cannot reproduce this test's shape; the band's "
                "coverage comes from a noise sd inflated by the misfit, not from a good fit")

    def as_dict(self) -> dict:
        return {"nrmse": self.nrmse, "systematic": self.systematic, "coverage": self.coverage,
                "adequacy": self.level, "reading": self.sentence}


def _pct(x: float) -> str:
    return "nan" if not math.isfinite(x) else f"{100 * x:.1f} %"


def adequacy(measured: np.ndarray, predicted: np.ndarray, coverage: float) -> Adequacy:
    """The :class:`Adequacy` of ``predicted`` (posterior-mean force) against ``measured`` [kN],
    with the band's ``coverage`` (definitions in the module docstring)."""
    y = np.asarray(measured, dtype=float)
    f = np.asarray(predicted, dtype=float)
    r = y - f
    rms = float(np.sqrt(np.mean(y * y)))
    mse = float(np.mean(r * r))
    sw = white_noise_sd(r)
    nrmse = math.sqrt(mse) / rms if rms > 0 else float("nan")
    sys_ = math.sqrt(max(mse - sw * sw, 0.0)) / rms if rms > 0 and math.isfinite(sw) else nrmse
    if not math.isfinite(sys_):
        level = "inadequate"
    else:
        level = "adequate" if sys_ <= ADEQUATE else "marginal" if sys_ <= INADEQUATE else "inadequate"
    return Adequacy(nrmse=float(nrmse), systematic=float(sys_), coverage=float(coverage), level=level)


def at_bounds(spec, priors, names, theta, lower, upper) -> list[dict]:
    """Sampled law parameters whose value in ``theta`` lies at (within :data:`NEAR_BOUND` of the
    range from) an end of their admissible range: ``[{name, value, unit, bound, side}]``.

    ``priors`` maps names to :class:`~rrfrei.calibration.priors.Prior`; ``lower``/``upper`` are
    the physical bounds of ``names`` (the problem's).  An infinite side (a normal prior within
    infinite physical bounds) is never reached.
    """
    from rrfrei.calibration.optimum import _support
    from rrfrei.calibration.priors import cube_range

    out = []
    for j, name in enumerate(names):
        p = priors.get(name)
        if p is None:
            continue
        lo, hi = _support(p)
        lo, hi = max(lo, float(lower[j])), min(hi, float(upper[j]))
        kind, blo, bhi = cube_range(p, float(lower[j]), float(upper[j]))  # the search box: the scale
        log = kind == "log" and blo > 0

        def tr(v: float, log: bool = log) -> float:
            return math.log(max(v, 1e-300)) if log else v

        width = tr(bhi) - tr(blo)
        x = float(theta[j])
        for side, b in (("lower", lo), ("upper", hi)):
            if math.isfinite(b) and width > 0 and abs(tr(x) - tr(b)) <= NEAR_BOUND * width:
                out.append({"name": name, "value": x, "unit": spec.param(name).unit, "bound": b,
                            "side": side})
                break
    return out


def bounds_text(hits: list[dict]) -> str:
    """``alpha2 = -1 at its lower bound -1, gamma = 1 at its upper bound 1`` (plain numbers)."""
    def num(v: float) -> str:
        return f"{v:,.4g}" if abs(v) < 1e4 else f"{v:,.0f}"

    return ", ".join(f"{h['name']} = {num(h['value'])}{' ' + h['unit'] if h['unit'] not in ('', '-') else ''}"
                     f" at its {h['side']} bound {num(h['bound'])}" for h in hits)
