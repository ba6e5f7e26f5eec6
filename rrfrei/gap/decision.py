"""The decision rule of the gap diagnosis: is an effect's gain real, and is what is left noise?

Pure functions over arrays (issue 12, points 1 and 2).  Why blocks: the old rule compared the sum
of held-out log predictive density gains with twice its paired standard error over cycles.  The
log density of a Gaussian grows with the squared error, so a large effect gains enormously in the
few cycles where the baseline misses most; those cycles inflate the standard error faster than the
sum, and the larger the effect the less significant it looked.  Here the evidence is read from
*signs and ranks* of per-block gains (which a few huge blocks cannot dilute) and from a block
bootstrap of the pooled systematic gap (which a few huge blocks only strengthen).

Blocks (:func:`blocks`)
    the exchangeable units of a test: its *half-cycles* when it has at least two full cycles
    (:func:`rrfrei.energy.cycle_bounds`; each cycle starts at an upward zero crossing and is split
    at its downward one; samples before the first or after the last cycle join the nearest block),
    else ``WINDOWS`` equal time windows (monotonic pushes, earthquake-like records).

Gain of a block
    held out: the reduction of the squared error, ``g_b = sum_b (y - f_ref)^2 - (y - f_eff)^2``
    [force^2] (posterior-mean forces; the noise is common to both models, so this is the
    reduction of the block's systematic squared error); on the calibration test: the difference
    of the leave-one-block-out elpd (PSIS, :func:`rrfrei.gap.diagnose`) [nats].

Tests over the blocks (one-sided, H1: the effect model is better)
    * sign test: ``p = P(X >= k)``, ``X ~ Binomial(m, 1/2)``, ``k`` positive gains among the ``m``
      non-zero ones (Conover 1999, *Practical Nonparametric Statistics*, 3rd ed., sec. 3.4);
    * Wilcoxon signed-rank test (Wilcoxon 1945; exact null distribution up to 50 blocks, normal
      approximation beyond, :func:`scipy.stats.wilcoxon`).
    Neither depends on the size of the largest gains, so their power does not collapse when the
    gains are heavy-tailed.  ``rank_p = min(p_sign, p_wilcoxon)``; the pair is read as one test
    at level ``ALPHA`` after a Bonferroni factor 2 (``rank_p < ALPHA / 2``).

Block bootstrap of the shrink
    pooled systematic gap ``S = sqrt(max(SSE - sum n_b sigma_t^2, 0) / N) / RMS(y)`` over the
    held-out blocks (``sigma_t``: white-noise level of test t), shrink ``1 - S_eff / S_ref``;
    ``B = BOOT`` resamples of whole blocks with replacement within each test (a non-overlapping
    block bootstrap with cycle-aligned blocks, Carlstein 1986, Kunsch 1989), seeded; the CI is
    the percentile interval at ``LEVEL`` (two-sided), its lower end a one-sided 95 % bound.

Significance of an effect (:func:`significant`)
    calibration: total leave-one-block-out gain > ``MIN_GAIN`` nats and ``rank_p < ALPHA / 2``
    over the calibration blocks; with held-out tests also: ``rank_p < ALPHA / 2`` over the
    held-out blocks AND the bootstrap lower bound of the held-out shrink > ``MIN_SHRINK`` (10 %;
    the guard: an effect that wins on the calibration test but does not close a real part of the
    held-out gap is rejected).  Without held-out tests the bound applies to the calibration
    test's own shrink (over its blocks), so that a consistent but negligible gain on a test with a
    large systematic gap is not named.  With held-out tests and a calibration test of too few
    blocks for its rank test to weigh an effect (:func:`underpowered`: fewer than 15 at ``ALPHA``,
    where it passes only when every block gains, or all but one), the calibration part asks for
    the total gain and a majority of gaining blocks, and the held-out part decides: an effect
    fitted on two short shake-table runs (8 blocks) that closes 39 % [26, 46] of the held-out gap
    with 44 of 46 held-out blocks gaining is not lost because two calibration blocks lose.

What is left (:func:`residual_state`)
    the residual of the chosen model is *noise* when its systematic part is small against the
    noise (``MSE / sigma^2 - 1 <= EXCESS``), negligible (systematic NRMSE <= ``SYS_FLOOR``), or
    when the residuals are white: lag-1 autocorrelation ``|rho1| < 2 / sqrt(n)`` (Box & Jenkins
    1976: the sample autocorrelation of white noise has sd ``1 / sqrt(n)``).  The last clause
    keeps heavy-tailed noise (Student-t, outliers) from reading as a systematic gap: the
    excess over the robust white-noise level grows with the tails, while a model error of a
    smooth law on a smooth history is serially correlated.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rrfrei.jsonable import number as _num

__all__ = ["ALPHA", "BOOT", "EXCESS", "LEVEL", "MIN_GAIN", "MIN_SHRINK", "SYS_FLOOR", "WINDOWS", "BlockParts",
           "RankEvidence", "ShrinkEvidence", "Residual", "blocks", "block_parts", "calibration_support",
           "needed_gains", "sign_test", "underpowered",
           "wilcoxon_test", "min_blocks", "rank_evidence", "shrink_ci", "significant", "residual_state"]

ALPHA = 0.01
"""Level of the block test of one effect (0.05 over ~5 effects, Bonferroni)."""
MIN_GAIN = 4.0
"""Least total leave-one-block-out elpd gain on the calibration test [nats]."""
BOOT = 2000
"""Block-bootstrap resamples of the held-out shrink."""
LEVEL = 0.90
"""Two-sided level of the bootstrap interval (its lower end is a one-sided 95 % bound)."""
WINDOWS = 20
"""Time windows of a test without two full cycles."""
EXCESS = 0.25
"""Largest ``MSE / sigma^2 - 1`` of a residual called noise (systematic RMS below half the noise)."""
SYS_FLOOR = 0.01
"""Systematic NRMSE at or below which a gap is negligible (1 % of the RMS force)."""
MIN_SHRINK = 0.10
"""Least lower bound of the held-out shrink: an effect must close at least a tenth of the gap."""


# --- blocks ----------------------------------------------------------------------------------
def blocks(disp, *, windows: int = WINDOWS) -> np.ndarray:
    """Block label (0..B-1, in time order) of every sample of a displacement history.

    Parameters
    ----------
    disp : (n,) displacement [m].
    windows : number of equal windows when the history has fewer than two full cycles.

    Returns
    -------
    (n,) int64 labels: half-cycles of a cyclic history, else ``min(windows, n // 10)`` (at least
    one) equal time windows (see the module docstring).
    """
    from rrfrei.energy import cycle_bounds

    u = np.asarray(disp, dtype=float)
    n = u.size
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    if not isinstance(windows, (int, np.integer)) or windows < 1:
        raise ValueError(f"windows must be an integer >= 1, got {windows!r}")
    bounds = np.asarray(cycle_bounds(u)).reshape(-1, 2)
    if bounds.shape[0] >= 2:
        cuts: list[int] = []
        for s, e in bounds:
            cuts.append(int(s))
            seg = u[s: e + 1]
            j = int(np.argmax(seg))  # cycles start at an upward crossing: positive half first
            down = np.nonzero(seg[j:] <= 0.0)[0]
            if down.size and 0 < j + down[0] < seg.size - 1:
                cuts.append(int(s) + j + int(down[0]))
        lab = np.zeros(n, dtype=np.int64)
        for k, c in enumerate(cuts[1:], start=1):
            lab[c:] = k
        lab[int(bounds[-1, 1]) + 1:] = len(cuts) - 1  # the tail joins the last block
        return lab
    w = max(1, min(int(windows), n // 10))
    return np.minimum(np.arange(n) * w // n, w - 1).astype(np.int64)


@dataclass(frozen=True)
class BlockParts:
    """Per-block sums of one or more tests (all arrays (B,)).

    ``n`` samples, ``sse_ref``/``sse_eff`` squared errors of the reference and effect models
    [force^2], ``yy`` sum of squared measured force [force^2], ``noise`` ``n sigma_t^2``
    [force^2], ``stratum`` index of the test each block belongs to.
    """

    n: np.ndarray
    sse_ref: np.ndarray
    sse_eff: np.ndarray
    yy: np.ndarray
    noise: np.ndarray
    stratum: np.ndarray

    @property
    def gains(self) -> np.ndarray:
        """Reduction of the squared error per block [force^2]."""
        return self.sse_ref - self.sse_eff

    @staticmethod
    def concat(parts: Sequence[BlockParts]) -> BlockParts:
        """The blocks of several tests, each test its own bootstrap stratum."""
        if not parts:
            z = np.zeros(0)
            return BlockParts(z, z, z, z, z, np.zeros(0, dtype=np.int64))
        out = {k: np.concatenate([getattr(p, k) for p in parts])
               for k in ("n", "sse_ref", "sse_eff", "yy", "noise")}
        strata = np.concatenate([np.full(p.n.size, i, dtype=np.int64) for i, p in enumerate(parts)])
        return BlockParts(stratum=strata, **out)


def block_parts(y, f_ref, f_eff, labels, sigma: float) -> BlockParts:
    """Per-block sums of one test: measured ``y``, reference and effect predictions [force],
    block ``labels`` (:func:`blocks`), white-noise level ``sigma`` [force]."""
    y, a, b = (np.asarray(x, dtype=float) for x in (y, f_ref, f_eff))
    lab = np.asarray(labels, dtype=np.int64)
    if not (y.shape == a.shape == b.shape == lab.shape):
        raise ValueError(f"y, f_ref, f_eff and labels must have the same shape, got "
                         f"{y.shape}, {a.shape}, {b.shape}, {lab.shape}")
    if not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be finite and >= 0, got {sigma!r}")
    B = int(lab.max()) + 1 if lab.size else 0
    n = np.bincount(lab, minlength=B).astype(float)
    return BlockParts(n=n, sse_ref=np.bincount(lab, (y - a) ** 2, B),
                      sse_eff=np.bincount(lab, (y - b) ** 2, B), yy=np.bincount(lab, y**2, B),
                      noise=n * sigma**2, stratum=np.zeros(B, dtype=np.int64))


# --- rank tests ------------------------------------------------------------------------------
def sign_test(gains) -> float:
    """One-sided sign test p-value that the gains are positive more often than not (1.0 without
    non-zero gains)."""
    from scipy.stats import binomtest

    g = np.asarray(gains, dtype=float)
    g = g[np.isfinite(g) & (g != 0)]
    if g.size == 0:
        return 1.0
    return float(binomtest(int((g > 0).sum()), int(g.size), 0.5, alternative="greater").pvalue)


def wilcoxon_test(gains) -> float:
    """One-sided Wilcoxon signed-rank p-value that the gains are shifted above zero (zeros
    dropped; 1.0 without non-zero gains)."""
    from scipy.stats import wilcoxon

    g = np.asarray(gains, dtype=float)
    g = g[np.isfinite(g) & (g != 0)]
    if g.size == 0:
        return 1.0
    return float(wilcoxon(g, alternative="greater", zero_method="wilcox").pvalue)


@dataclass(frozen=True)
class RankEvidence:
    """Sign and signed-rank tests over the gains of ``blocks`` blocks."""

    blocks: int
    positive: int
    total: float
    p_sign: float
    p_wilcoxon: float

    @property
    def p(self) -> float:
        """``min(p_sign, p_wilcoxon)`` (compared with ``ALPHA / 2``)."""
        return min(self.p_sign, self.p_wilcoxon)

    def passes(self, alpha: float = ALPHA) -> bool:
        return bool(self.p < alpha / 2)

    def as_dict(self) -> dict:
        return {"blocks": self.blocks, "positive": self.positive, "total_gain": _num(self.total),
                "p_sign": _num(self.p_sign), "p_wilcoxon": _num(self.p_wilcoxon)}


def min_blocks(alpha: float = ALPHA) -> int:
    """Fewest blocks on which the rank tests can pass at all: with every one of ``m`` blocks
    gaining, the one-sided sign test and the exact signed-rank test both give ``p = 2^-m``, so the
    rule's ``rank_p < alpha / 2`` needs ``m >= log2(2 / alpha)`` (8 at ``ALPHA``).  On fewer blocks
    no effect can be named, however much it closes."""
    m = 1
    while 0.5**m >= alpha / 2:
        m += 1
    return m


def needed_gains(m: int, alpha: float = ALPHA) -> int:
    """Fewest gaining blocks of ``m`` with which the one-sided sign test gives ``p < alpha / 2``
    (``m + 1`` when even ``m`` do not)."""
    from scipy.stats import binom

    for k in range(m + 1):
        if binom.sf(k - 1, m, 0.5) < alpha / 2:
            return k
    return m + 1


def underpowered(m: int, alpha: float = ALPHA) -> bool:
    """True when the rank tests on ``m`` blocks pass only with every block gaining or all but one
    (:func:`needed_gains` ``>= m - 1``; ``m < 15`` at ``ALPHA``): they can confirm an effect that
    wins everywhere but cannot weigh one that wins in most blocks."""
    return needed_gains(m, alpha) >= m - 1


def calibration_support(calibration: RankEvidence, holdout: RankEvidence | None = None,
                        alpha: float = ALPHA) -> tuple[bool, bool]:
    """(supported, on the held-out evidence): the calibration blocks' rank test passes, or, with
    held-out blocks and an :func:`underpowered` calibration test, a majority of the calibration
    blocks gain (the second flag then True; the held-out part of the rule decides)."""
    if calibration.passes(alpha):
        return True, False
    weak = (holdout is not None and underpowered(calibration.blocks, alpha)
            and 2 * calibration.positive > calibration.blocks)
    return weak, weak


def rank_evidence(gains) -> RankEvidence:
    """:class:`RankEvidence` of per-block gains."""
    g = np.asarray(gains, dtype=float)
    g = g[np.isfinite(g)]
    return RankEvidence(int(g.size), int((g > 0).sum()), float(g.sum()), sign_test(g), wilcoxon_test(g))


# --- block bootstrap -------------------------------------------------------------------------
def _systematic(sse, noise, n, yy):
    return np.sqrt(np.maximum(sse - noise, 0.0) / n) / np.sqrt(yy / n)


@dataclass(frozen=True)
class ShrinkEvidence:
    """Pooled systematic gap of reference and effect model, its shrink and bootstrap interval."""

    systematic_ref: float
    systematic_eff: float
    shrink: float
    lower: float
    upper: float

    def passes(self, min_shrink: float = MIN_SHRINK) -> bool:
        return bool(self.lower > min_shrink)

    def as_dict(self) -> dict:
        return {"systematic_ref": _num(self.systematic_ref), "systematic_eff": _num(self.systematic_eff),
                "shrink": _num(self.shrink), "ci": [_num(self.lower), _num(self.upper)], "level": LEVEL}


def shrink_ci(parts: BlockParts, *, seed: int = 0, boot: int = BOOT, level: float = LEVEL) -> ShrinkEvidence:
    """Pooled systematic-gap shrink ``1 - S_eff / S_ref`` and its block-bootstrap interval.

    Blocks are resampled with replacement within each stratum (test); ``seed`` fixes the draws.
    A resample whose reference gap is zero counts as no shrink (0).
    """
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    p = parts
    if p.n.size == 0 or p.n.sum() == 0:
        nan = float("nan")
        return ShrinkEvidence(nan, nan, nan, nan, nan)
    cols = np.stack([p.n, p.sse_ref, p.sse_eff, p.yy, p.noise])  # (5, B)
    tot = cols.sum(axis=1)
    s_ref = float(_systematic(tot[1], tot[4], tot[0], tot[3]))
    s_eff = float(_systematic(tot[2], tot[4], tot[0], tot[3]))
    shrink = 1.0 - s_eff / s_ref if s_ref > 0 else 0.0
    T = _block_weights(p.stratum, boot, seed) @ cols.T  # (boot, 5)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = _systematic(T[:, 1], T[:, 4], T[:, 0], T[:, 3])
        e = _systematic(T[:, 2], T[:, 4], T[:, 0], T[:, 3])
        sh = np.where(r > 0, 1.0 - e / np.where(r > 0, r, 1.0), 0.0)
    a = (1 - level) / 2
    lo, hi = np.quantile(sh, [a, 1 - a])
    return ShrinkEvidence(s_ref, s_eff, shrink, float(lo), float(hi))


def _block_weights(stratum: np.ndarray, boot: int, seed: int) -> np.ndarray:
    """(boot, B) multiplicities of the blocks in ``boot`` resamples with replacement within each
    stratum (test); ``seed`` fixes the draws (the same for every caller given the same seed)."""
    rng = np.random.default_rng([int(seed), 12])
    W = np.zeros((boot, stratum.size))
    for s in np.unique(stratum):
        idx = np.nonzero(stratum == s)[0]
        pick = rng.integers(0, idx.size, size=(boot, idx.size))
        np.add.at(W, (np.arange(boot)[:, None], idx[pick]), 1.0)
    return W


@dataclass(frozen=True)
class GapDifference:
    """How much more of the reference's systematic gap a model ``b`` leaves than a model ``a``:
    ``(S_b - S_a) / S_ref`` (the difference of their shrinks against the reference), with its
    block-bootstrap interval."""

    difference: float
    lower: float
    upper: float

    def as_dict(self) -> dict:
        return {"difference": _num(self.difference), "ci": [_num(self.lower), _num(self.upper)],
                "level": LEVEL}


def gap_difference_ci(pa: BlockParts, pb: BlockParts, *, seed: int = 0, boot: int = BOOT,
                      level: float = LEVEL) -> GapDifference:
    """:class:`GapDifference` of ``b`` against ``a``, from their block parts against one reference
    (``pa.sse_ref`` and ``pb.sse_ref`` the same model's, the same blocks); paired: each resample
    takes the same blocks for both."""
    if pa.n.size != pb.n.size or not np.array_equal(pa.sse_ref, pb.sse_ref):
        raise ValueError("gap_difference_ci needs the block parts of two models against one reference "
                         "on the same blocks")
    if pa.n.size == 0 or pa.n.sum() == 0:
        nan = float("nan")
        return GapDifference(nan, nan, nan)
    cols = np.stack([pa.n, pa.sse_ref, pa.sse_eff, pb.sse_eff, pa.yy, pa.noise])  # (6, B)

    def diff(c):
        r, a_, b_ = (_systematic(c[i], c[5], c[0], c[4]) for i in (1, 2, 3))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(r > 0, (b_ - a_) / np.where(r > 0, r, 1.0), 0.0)

    d0 = float(diff(cols.sum(axis=1)))
    T = (_block_weights(pa.stratum, boot, seed) @ cols.T).T  # (6, boot)
    a = (1 - level) / 2
    lo, hi = np.quantile(diff(T), [a, 1 - a])
    return GapDifference(d0, float(lo), float(hi))


# --- the rule --------------------------------------------------------------------------------
def significant(calibration: RankEvidence, holdout: RankEvidence | None = None,
                shrink: ShrinkEvidence | None = None, *, alpha: float = ALPHA,
                min_gain: float = MIN_GAIN, min_shrink: float = MIN_SHRINK) -> tuple[bool, str]:
    """The rule of the module docstring: (significant, why in one line)."""
    why = []
    ok = True
    if not calibration.total > min_gain:
        ok = False
        why.append(f"calibration gain {calibration.total:.3g} nats <= {min_gain:g}")
    supported, weak = calibration_support(calibration, holdout, alpha)
    if not supported:
        ok = False
        why.append(f"calibration blocks: p = {calibration.p:.2g} >= {alpha / 2:g} "
                   f"({calibration.positive}/{calibration.blocks} gain)")
    on = "held-out" if holdout is not None else "calibration"
    if holdout is not None and not holdout.passes(alpha):
        ok = False
        why.append(f"held-out blocks: p = {holdout.p:.2g} >= {alpha / 2:g} "
                   f"({holdout.positive}/{holdout.blocks} gain)")
    if (holdout is not None or shrink is not None) and (shrink is None or not shrink.passes(min_shrink)):
        ok = False
        lo = float("nan") if shrink is None else shrink.lower
        why.append(f"{on} shrink lower bound {lo:.0%} <= {min_shrink:.0%}")
    if ok:
        txt = f"calibration blocks p = {calibration.p:.2g} ({calibration.positive}/{calibration.blocks} gain)"
        if weak:
            txt = (f"calibration blocks {calibration.positive}/{calibration.blocks} gain (too few blocks "
                   f"for the rank test: it needs {needed_gains(calibration.blocks, alpha)}; named on the "
                   "held-out evidence)")
        if holdout is not None:
            txt += f"; held-out blocks p = {holdout.p:.2g} ({holdout.positive}/{holdout.blocks} gain)"
        if shrink is not None:
            txt += f", {on} shrink {shrink.shrink:.0%} [{shrink.lower:.0%}, {shrink.upper:.0%}]"
        return True, txt
    return False, "; ".join(why)


@dataclass(frozen=True)
class Residual:
    """What is left of a model's gap on some data: systematic NRMSE, excess over noise, whiteness."""

    systematic: float
    excess: float  # MSE / sigma^2 - 1
    rho1: float  # lag-1 autocorrelation of the residuals (pooled over tests)
    n: int

    @property
    def noise_only(self) -> bool:
        """True when what is left is noise (the module docstring's rule)."""
        return bool(not self.excess > EXCESS or not self.systematic > SYS_FLOOR or self.white)

    @property
    def white(self) -> bool:
        return bool(abs(self.rho1) < 2.0 / math.sqrt(max(self.n, 1)))

    def as_dict(self) -> dict:
        return {"systematic": _num(self.systematic), "excess_over_noise": _num(self.excess),
                "lag1_autocorrelation": _num(self.rho1), "white": self.white, "points": self.n,
                "noise_only": self.noise_only}


def residual_state(ys: Sequence, fs: Sequence, sigmas: Sequence[float]) -> Residual:
    """:class:`Residual` of measured ``ys`` against predictions ``fs`` (one array per test) with
    white-noise levels ``sigmas`` [force]."""
    r = [np.asarray(y, dtype=float) - np.asarray(f, dtype=float) for y, f in zip(ys, fs)]
    n = sum(x.size for x in r)
    if n == 0:
        return Residual(float("nan"), float("nan"), float("nan"), 0)
    sse = sum(float(x @ x) for x in r)
    noise = sum(x.size * float(s) ** 2 for x, s in zip(r, sigmas))
    yy = sum(float(np.asarray(y, dtype=float) @ np.asarray(y, dtype=float)) for y in ys)
    sys_ = float(_systematic(sse, noise, n, yy)) if yy > 0 else float("nan")
    excess = sse / noise - 1.0 if noise > 0 else float("inf")
    num = sum(float((x[1:] - x.mean()) @ (x[:-1] - x.mean())) for x in r if x.size > 1)
    den = sum(float((x - x.mean()) @ (x - x.mean())) for x in r)
    rho1 = num / den if den > 0 else 0.0
    return Residual(sys_, excess, rho1, n)


