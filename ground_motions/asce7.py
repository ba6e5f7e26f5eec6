"""ASCE 7-22 Chapter 17 (seismically isolated structures): scaling a suite of ground-motion pairs.

What the standard requires, as implemented here
-----------------------------------------------
- **17.3.2 Ground-motion selection.**  Response-history analysis of an isolated structure uses a
  suite of *pairs* of horizontal ground-motion components, not fewer than seven pairs
  (:data:`MIN_PAIRS`), selected from events consistent with the MCE_R hazard.
- **17.3.3 Ground-motion modification (amplitude scaling).**  For each pair a
  *maximum-direction* spectrum is built from the two scaled components (RotD100, Boore 2010:
  :func:`ground_motions.rotd_spectrum`); both components of a pair are scaled by **one** factor,
  and the factors may differ from pair to pair.  The pairs are scaled so that, over the period
  range from ``0.75 T_M`` (``T_M`` computed with the *upper-bound* isolation properties, the
  stiffer system: ``t_upper``) to ``1.25 T_M`` (with the *lower-bound* properties: ``t_lower``),
  the **average** of the suite's maximum-direction spectra does not fall below the target
  (5 %-damped MCE_R) spectrum.
- **17.6.3.4 Response-history procedure.**  The pairs are applied simultaneously; the value of
  each response quantity used for design is the average over the suite when seven or more pairs
  are analysed, and the maximum otherwise (:func:`design_value`).

The MCE_R response spectrum is 1.5 times the design response spectrum (ASCE 7-22 Section 11.4.6,
11.4.7 in ASCE 7-16; the section number for 7-22 is not verified): :func:`mcer_target` multiplies
the two-period :func:`ground_motions.design_spectrum` by 1.5.

Verification (what we could and could not check)
-------------------------------------------------
The text of ASCE 7-22 (a paid standard) was not available to this project.  Checked against
public secondary sources: ASCE 7-22 Section 16.2.3.2 (Chapter 16, non-isolated buildings)
builds "a maximum-direction spectrum ... from the two horizontal ground motion components" of
each pair (quoted in a public Q&A); older editions used the SRSS of the two components' spectra
instead (ASCE 7-10 Section 16.1.3.2: average SRSS not below the design spectrum over 0.2 T to
1.5 T; the UFC 3-310-03A / 1997-era isolation text: average SRSS not below 1.3 times the 5 %
spectrum, with identical factors for both components of a pair); ASCE 7-10 kept "maximum from
three or more records, average from seven or more" (R. Hamburger, ASCE 7-16 Chapter 16
briefing, 2014).  **Not verified** from the standard's own text: the exact Chapter 17
percentages (this module uses "not below 100 % of the target", ``fraction=1.0``; pass another
``fraction`` if your edition's text says e.g. 90 %), the period-range wording of 17.3.3 (the
``0.75 T_M`` upper-bound / ``1.25 T_M`` lower-bound range is that of ASCE 7-16 Section 17.3.3 as
we know it, kept in 7-22), and the section number of the average/maximum rule in 7-22 (17.6.3.4
in ASCE 7-10; since 7-16 seven pairs are the minimum, so "fewer than seven" is outside the
standard and the maximum is then the conservative choice).

How the factors are chosen
--------------------------
17.3.3 fixes a condition on the suite, not the factors.  ``method="log-ls"`` (default): each
pair's factor first matches its own RotD100 to the target over the range in the least-squares
sense in log space (``f_i = exp(mean(ln target - ln RotD100_i))``, so each pair keeps its
spectral shape and none dominates the average), then one common factor brings the smallest
ratio of the suite average to the target over the range to exactly ``fraction``.
``method="common"``: one factor for every pair (the records keep their relative amplitudes),
again the smallest that meets the condition.  Either way the suite *just* complies: its
governing period (where the average touches ``fraction x target``) is reported.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .pairs import RecordPair
from .record import ReadOnlyArrays
from .rotd import rotd_spectrum
from .scaling import Target, target_psa
from .spectra import design_spectrum

#: Minimum number of pairs in a suite (ASCE 7-22 Section 17.3.2).
MIN_PAIRS = 7
#: The period range of 17.3.3: from ``0.75 T_M`` (upper-bound) to ``1.25 T_M`` (lower-bound).
RANGE_FACTORS = (0.75, 1.25)
#: MCE_R = 1.5 x design spectrum (ASCE 7-22 Section 11.4.6; module docstring).
MCER_OVER_DESIGN = 1.5



class SuiteSizeWarning(UserWarning):
    """A suite has fewer pairs than ASCE 7-22 Section 17.3.2 requires (seven)."""


def mcer_target(sds: float, sd1: float, tl: float) -> Callable[[np.ndarray], np.ndarray]:
    """The 5 %-damped MCE_R spectrum ``T -> PSA [m/s^2]``: 1.5 x the two-period design spectrum.

    ``sds``, ``sd1`` [g] and ``tl`` [s] as in :func:`ground_motions.design_spectrum`.
    """
    design_spectrum(sds, sd1, tl, [1.0])  # validates the parameters now, not at the first call

    def target(periods):
        return MCER_OVER_DESIGN * design_spectrum(sds, sd1, tl, periods, units="m/s^2")

    target.__doc__ = f"MCE_R PSA [m/s^2]: 1.5 x design spectrum (SDS = {sds} g, SD1 = {sd1} g, TL = {tl} s)"
    return target




@dataclass(frozen=True, eq=False)
class ScaledSuite(ReadOnlyArrays):
    """A suite of pairs scaled per ASCE 7-22 Section 17.3.3 (arrays read-only).

    Attributes
    ----------
    pairs
        The scaled pairs (``RecordPair.scaled``; ``scale_factor`` in each component's meta).
    factors
        One factor per pair [-].
    periods
        The periods [s] of the check, log-spaced over ``[0.75 t_upper, 1.25 t_lower]``.
    target
        Target PSA [m/s^2] at ``periods`` (5 %-damped MCE_R).
    rotd100
        ``(n_pairs, n_periods)``: each scaled pair's maximum-direction PSA [m/s^2].
    average
        The suite average of ``rotd100`` [m/s^2].
    ratio
        ``average / target`` (``>= fraction`` everywhere, equal at the governing period).
    governing_period
        The period [s] where the ratio is smallest.
    t_upper, t_lower
        ``T_M`` [s] with upper- and lower-bound isolation properties.
    fraction
        The required minimum of ``ratio`` (1.0: "not below the target").
    damping
        Damping ratio of the spectra.
    method
        ``"log-ls"`` or ``"common"`` (module docstring).
    """

    pairs: tuple[RecordPair, ...]
    factors: np.ndarray
    periods: np.ndarray
    target: np.ndarray
    rotd100: np.ndarray
    average: np.ndarray
    ratio: np.ndarray
    governing_period: float
    t_upper: float
    t_lower: float
    fraction: float = 1.0
    damping: float = 0.05
    method: str = "log-ls"

    ARRAYS = ("factors", "periods", "target", "rotd100", "average", "ratio")

    def __post_init__(self) -> None:
        self._freeze()
        object.__setattr__(self, "pairs", tuple(self.pairs))

    @property
    def n_pairs(self) -> int:
        """Number of pairs in the suite."""
        return len(self.pairs)

    @property
    def meets_count(self) -> bool:
        """True when the suite has at least :data:`MIN_PAIRS` pairs (Section 17.3.2)."""
        return self.n_pairs >= MIN_PAIRS

    @property
    def min_ratio(self) -> float:
        """The smallest ``average / target`` over the range."""
        return float(np.min(self.ratio))

    @property
    def period_range(self) -> tuple[float, float]:
        """``(0.75 t_upper, 1.25 t_lower)`` [s]."""
        return (float(self.periods[0]), float(self.periods[-1]))

    def summary(self) -> str:
        """A few lines for a report: the range, the factors, the governing period."""
        lo, hi = self.period_range
        lines = [
            f"ASCE 7-22 17.3.3 amplitude scaling of {self.n_pairs} pairs ({self.method}): average "
            f"RotD100 >= {self.fraction:g} x target over {lo:.3g}-{hi:.3g} s "
            f"(0.75 x {self.t_upper:g} s to 1.25 x {self.t_lower:g} s)",
            f"  governing period {self.governing_period:.3g} s: average / target = {self.min_ratio:.4f}",
        ]
        lines += [f"  {p.name}: factor {f:.4g}" for p, f in zip(self.pairs, self.factors)]
        if not self.meets_count:
            lines.append(f"  NOTE: fewer than {MIN_PAIRS} pairs (17.3.2): design values are the maximum")
        return "\n".join(lines)


def scale_pairs_asce7(
    pairs: Sequence[RecordPair],
    target: Target,
    t_upper: float,
    t_lower: float,
    damping: float = 0.05,
    *,
    fraction: float = 1.0,
    method: str = "log-ls",
    n_periods: int = 50,
    n_angles: int = 180,
) -> ScaledSuite:
    """Scale a suite of pairs so its average RotD100 meets the target (ASCE 7-22 17.3.3).

    Parameters
    ----------
    pairs
        The ground-motion pairs (7 or more for Section 17.3.2; fewer gives a
        :class:`SuiteSizeWarning`).
    target
        Target 5 %-damped MCE_R PSA in m/s^2: a :class:`Spectrum`, a callable ``T -> PSA``
        (e.g. :func:`mcer_target`) or a ``(periods, psa)`` pair covering the range.
    t_upper, t_lower
        Effective period ``T_M`` [s] of the isolated structure with the upper-bound (stiffer,
        shorter period) and lower-bound isolation properties; ``0 < t_upper <= t_lower``.
    damping
        Damping ratio of the spectra (the target's: 0.05).
    fraction
        Minimum of ``average / target`` over the range (1.0; see the module docstring).
    method
        ``"log-ls"`` (per-pair shape match, then one common factor) or ``"common"`` (one
        factor for all pairs).
    n_periods
        Number of log-spaced periods checked over ``[0.75 t_upper, 1.25 t_lower]`` (ends included).
    n_angles
        Angles of the RotD100 computation (:func:`ground_motions.rotd_spectrum`).

    Returns
    -------
    ScaledSuite
        Scaled pairs, factors, the suite average, its ratio to the target, the governing period.
    """
    suite = list(pairs)
    if not suite:
        raise ValueError("scale_pairs_asce7: no pairs given")
    for i, p in enumerate(suite):
        if not isinstance(p, RecordPair):
            raise ValueError(
                f"scale_pairs_asce7: pairs[{i}] must be a ground_motions.RecordPair (both horizontal "
                f"components), got {type(p).__name__}"
            )
    tu, tl = float(t_upper), float(t_lower)
    if not (math.isfinite(tu) and math.isfinite(tl) and 0.0 < tu <= tl):
        raise ValueError(
            f"scale_pairs_asce7: need 0 < t_upper <= t_lower (T_M with upper-bound properties is the "
            f"shorter period), got t_upper = {t_upper!r} s, t_lower = {t_lower!r} s"
        )
    frac = float(fraction)
    if not (math.isfinite(frac) and frac > 0.0):
        raise ValueError(f"scale_pairs_asce7: fraction must be finite and > 0, got {fraction!r}")
    if method not in ("log-ls", "common"):
        raise ValueError(f"scale_pairs_asce7: method must be 'log-ls' or 'common', got {method!r}")
    if int(n_periods) != n_periods or int(n_periods) < 2:
        raise ValueError(f"scale_pairs_asce7: n_periods must be a whole number >= 2, got {n_periods!r}")
    if len(suite) < MIN_PAIRS:
        warnings.warn(
            f"scale_pairs_asce7: {len(suite)} pairs; ASCE 7-22 Section 17.3.2 requires at least "
            f"{MIN_PAIRS} (design values are then the maximum over the suite, not the average)",
            SuiteSizeWarning,
            stacklevel=2,
        )
    lo, hi = RANGE_FACTORS[0] * tu, RANGE_FACTORS[1] * tl
    periods = np.geomspace(lo, hi, int(n_periods))
    tgt = target_psa(target, periods, where="scale_pairs_asce7")
    rot = np.array([rotd_spectrum(p, periods, damping, percentile=100, n_angles=n_angles).psa[0]
                    for p in suite])
    for i, row in enumerate(rot):
        if np.any(row <= 0.0):
            j = int(np.flatnonzero(row <= 0.0)[0])
            raise ValueError(
                f"scale_pairs_asce7: pair {suite[i].name!r} has zero RotD100 at T = {periods[j]:g} s "
                "and cannot be scaled"
            )
    if method == "log-ls":
        base = np.exp(np.mean(np.log(tgt)[None, :] - np.log(rot), axis=1))
    else:
        base = np.ones(len(suite))
    average = np.mean(base[:, None] * rot, axis=0)
    factors = base * (frac / float(np.min(average / tgt)))
    scaled_rot = factors[:, None] * rot
    average = np.mean(scaled_rot, axis=0)
    ratio = average / tgt
    return ScaledSuite(
        pairs=tuple(p.scaled(f) for p, f in zip(suite, factors)),
        factors=factors,
        periods=periods,
        target=tgt,
        rotd100=scaled_rot,
        average=average,
        ratio=ratio,
        governing_period=float(periods[int(np.argmin(ratio))]),
        t_upper=tu,
        t_lower=tl,
        fraction=frac,
        damping=float(damping),
        method=method,
    )


def design_value(values, n_pairs: int | None = None) -> float | np.ndarray:
    """The design value of a response quantity over a suite (ASCE 7-22 17.6.3.4; module docstring).

    Parameters
    ----------
    values
        One value per pair along axis 0 (e.g. the maximum plan isolator displacement [m] of each
        pair; further axes, e.g. stories or posterior draws, are kept).
    n_pairs
        Number of pairs analysed; default ``len(values)`` (must agree when given).

    Returns
    -------
    float or numpy.ndarray
        The average over the pairs when ``n_pairs >= 7`` (:data:`MIN_PAIRS`), else the maximum.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 0 or v.shape[0] == 0:
        raise ValueError(
            f"design_value: values must hold one value per pair along axis 0, got shape {v.shape}"
        )
    n = v.shape[0] if n_pairs is None else n_pairs
    if int(n) != n or int(n) != v.shape[0]:
        raise ValueError(f"design_value: n_pairs = {n_pairs!r} but {v.shape[0]} values were given")
    bad = np.flatnonzero(~np.isfinite(v.reshape(v.shape[0], -1)).all(axis=1))
    if bad.size:
        raise ValueError(f"design_value: the value of pair {int(bad[0])} is not finite")
    out = v.mean(axis=0) if v.shape[0] >= MIN_PAIRS else v.max(axis=0)
    return float(out) if out.ndim == 0 else out


__all__ = [
    "MCER_OVER_DESIGN",
    "MIN_PAIRS",
    "RANGE_FACTORS",
    "ScaledSuite",
    "SuiteSizeWarning",
    "design_value",
    "mcer_target",
    "scale_pairs_asce7",
]
