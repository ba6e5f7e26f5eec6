"""How one fit is scored against another on blocks (the gap engine's measure, :mod:`rrfrei.gap.diagnose`).

:class:`_Scorer` holds the per-dataset quantities (decision-rule blocks, model groups, noise
levels); :func:`_score` reads a refit against its reference by the block rule of
:mod:`rrfrei.gap.decision` and returns an :class:`EffectScore`; :func:`_beats` and
:func:`_beats_held_out` compare two fits by the block rank test; :func:`_parsimonious` picks the
effect to name among significant ones (one-standard-error rule, :func:`_ahead_by_one_se`).  The
leave-one-group-out elpd is :func:`loco` (PSIS, Vehtari, Gelman & Gabry 2017, ``arviz.psislw``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
from scipy.special import logsumexp

from rrfrei.gap import decision as dec
from rrfrei.gap.model import FitResult, GapModel, white_noise
from rrfrei.gap.residuals import energy_error, gap, systematic_gap
from rrfrei.gap.results import EffectScore, Metrics

__all__ = ["EffectScore", "Metrics", "loco"]


# ---------------------------------------------------------------------------------------------
def loco(ll: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """PSIS leave-one-group-out elpd of every group from pointwise log-lik (S, n)."""
    from arviz import psislw

    G = int(groups.max()) + 1
    sums = np.stack([ll[:, groups == g].sum(axis=1) for g in range(G)], axis=0)  # (G, S)
    if sums.shape[1] < 20:  # too few valid draws for importance sampling: plug-in estimate
        return sums.mean(axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lw, _ = psislw(-sums.copy())
    return logsumexp(lw + sums, axis=1)


_loco = loco  # the name the engine used before it was public


def _lppd_groups(ll: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Held-out log predictive density summed per group: sum_i log mean_s p(y_i | theta_s)."""
    lp = logsumexp(ll, axis=0) - math.log(ll.shape[0])
    G = int(groups.max()) + 1
    return np.array([lp[groups == g].sum() for g in range(G)])


def _paired(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    d = np.asarray(a) - np.asarray(b)
    return float(d.sum()), float(math.sqrt(d.size * d.var(ddof=1))) if d.size > 1 else float("nan")


def _blocks(model: GapModel, data) -> np.ndarray:
    """Blocks of the decision rule: :func:`rrfrei.gap.decision.blocks` of a displacement history
    (half-cycles or time windows), else the model's own groups."""
    if hasattr(data, "disp"):
        return dec.blocks(np.asarray(data.disp))
    return np.asarray(model.groups(data), dtype=np.int64)


class _Scorer:
    """Caches the per-dataset quantities and scores fits."""

    def __init__(self, model: GapModel, cal, holdout: Sequence, seed: int = 0) -> None:
        self.model = model
        self.cal = cal
        self.holdout = tuple(holdout)
        self.seed = seed
        self.g_cal = _blocks(model, cal)  # blocks of the decision rule
        self.g_ho = [_blocks(model, d) for d in self.holdout]
        self.c_cal = model.groups(cal)  # the model's groups (cycles): delta elpd and its paired se
        self.c_ho = [model.groups(d) for d in self.holdout]
        self.noise: dict[int, float] = {}

    def set_noise(self, fit: FitResult) -> None:
        for d in (self.cal, *self.holdout):
            r = self.model.observed(d) - fit.predict(d).mean
            self.noise[id(d)] = white_noise(r)

    def metrics(self, fit: FitResult, data: Sequence) -> Metrics | None:
        if not data:
            return None
        ys, fs, ss, ee, cov = [], [], [], [], []
        for d in data:
            pr = fit.predict(d)
            y = self.model.observed(d)
            ys.append(y)
            fs.append(pr.mean)
            ss.append(np.full(y.size, self.noise[id(d)]))
            cov.append((y >= pr.lower) & (y <= pr.upper))
            if hasattr(d, "disp"):
                ee.append(energy_error(d.disp, y, pr.mean))
        y, f, s = np.concatenate(ys), np.concatenate(fs), np.concatenate(ss)
        sig = float(np.sqrt(np.mean(s**2)))
        ee_ok = [e for e in ee if math.isfinite(e)]
        return Metrics(gap(y, f), systematic_gap(y, f, sig), float(np.mean(ee_ok)) if ee_ok else float("nan"),
                       float(np.mean(np.concatenate(cov))))

    def residual(self, fit: FitResult, data: Sequence) -> dec.Residual | None:
        """What is left of ``fit``'s gap on ``data`` (systematic part, excess over noise, rho1)."""
        if not data:
            return None
        return dec.residual_state([self.model.observed(d) for d in data], [fit.predict(d).mean for d in data],
                                  [self.noise[id(d)] for d in data])

    def loco(self, fit: FitResult, blocks: bool = True) -> np.ndarray:
        """Leave-one-out elpd per block (``blocks``) or per model group (cycle)."""
        return _loco(fit.loglik(self.cal), self.g_cal if blocks else self.c_cal)

    def lppd(self, fit: FitResult) -> np.ndarray:
        """Held-out log predictive density per model group (cycle)."""
        if not self.holdout:
            return np.zeros(0)
        return np.concatenate([_lppd_groups(fit.loglik(d), g) for d, g in zip(self.holdout, self.c_ho)])

    def parts(self, fit: FitResult, ref: FitResult, data: Sequence | None = None,
              blocks: Sequence | None = None) -> dec.BlockParts:
        """Per-block squared errors of ``ref`` and ``fit`` on ``data`` (default: the held-out tests)."""
        data = self.holdout if data is None else data
        blocks = self.g_ho if blocks is None else blocks
        return dec.BlockParts.concat([
            dec.block_parts(self.model.observed(d), ref.predict(d).mean, fit.predict(d).mean, g,
                            self.noise[id(d)]) for d, g in zip(data, blocks)])


def _shrink(before: float, after: float) -> float:
    return 1.0 - after / before if before > 0 else float("nan")


def _score(sc: _Scorer, effect: str, fit: FitResult, ref: FitResult, screen: float,
           ref_metrics: tuple[Metrics, Metrics | None]) -> EffectScore:
    """Score ``fit`` against ``ref`` and apply the decision rule (:func:`rrfrei.gap.decision.significant`)."""
    de, se = _paired(sc.loco(fit, blocks=False), sc.loco(ref, blocks=False))
    cal_ev = dec.rank_evidence(sc.loco(fit) - sc.loco(ref))
    mc = sc.metrics(fit, [sc.cal])
    mh = sc.metrics(fit, sc.holdout)
    ho_ev = sh_ev = None
    if sc.holdout:
        dh, seh = _paired(sc.lppd(fit), sc.lppd(ref))
        sh = _shrink(ref_metrics[1].systematic, mh.systematic)
        parts = sc.parts(fit, ref)
        ho_ev = dec.rank_evidence(parts.gains)
        sh_ev = dec.shrink_ci(parts, seed=sc.seed)
    else:
        dh, seh, sh = float("nan"), float("nan"), float("nan")
        sh_ev = dec.shrink_ci(sc.parts(fit, ref, [sc.cal], [sc.g_cal]), seed=sc.seed)
    sig, why = dec.significant(cal_ev, ho_ev, sh_ev)
    return EffectScore(effect=effect, law=fit.name, screen=screen, delta_elpd=de, se=se,
                       delta_holdout=dh, se_holdout=seh, calibration=mc, holdout=mh,
                       shrink_calibration=_shrink(ref_metrics[0].systematic, mc.systematic),
                       shrink_holdout=sh, significant=sig, params=dict(fit.params),
                       blocks_calibration=cal_ev, blocks_holdout=ho_ev, shrink_ci=sh_ev, why=why)


def _gain(sc: _Scorer, s: EffectScore) -> float:
    """What effects are ranked by: the held-out lpd gain with held-out data, else the calibration
    test's leave-one-block-out elpd gain."""
    return s.delta_holdout if sc.holdout else s.delta_elpd


def _beats_held_out(sc: _Scorer, a: FitResult, b: FitResult) -> bool:
    """``a`` beats ``b`` by the block rank test of :mod:`rrfrei.gap.decision` over the held-out
    blocks' squared-error reductions."""
    return dec.rank_evidence(sc.parts(a, b).gains).passes()


def _beats(sc: _Scorer, a: FitResult, b: FitResult) -> bool:
    """``a`` beats ``b`` by the block rank test: on the held-out blocks with held-out data
    (:func:`_beats_held_out`), else over the calibration test's leave-one-block-out elpd gains."""
    if sc.holdout:
        return _beats_held_out(sc, a, b)
    return dec.rank_evidence(sc.loco(a) - sc.loco(b)).passes()



def _n_free(fit: FitResult) -> int:
    return len(getattr(fit, "free", fit.params))


def _ahead_by_one_se(gains: np.ndarray) -> bool:
    """True when the per-block gains of one model over another total more than one standard error.

    ``gains``: per-block held-out squared-error reductions ``g_b`` of the higher-ranked model
    against the other (:class:`rrfrei.gap.decision.BlockParts`); standard error of their total
    ``sqrt(m) sd(g)`` over the ``m`` blocks (blocks as independent replicates, the estimate of the
    one-standard-error rule, Hastie, Tibshirani & Friedman 2009, sec. 7.10).
    """
    g = np.asarray(gains, dtype=float)
    g = g[np.isfinite(g)]
    if g.size < 2:
        return False
    return bool(g.sum() > math.sqrt(g.size) * g.std(ddof=1))


def _parsimonious(sc: _Scorer, fits: dict, sig: list[EffectScore]) -> tuple[str, str]:
    """The significant effect to name with held-out data, and a note ("" when it is the leader).

    ``sig`` in ranking order (largest held-out lpd gain first).  An effect is *admissible* when
    no significant effect ranked above it predicts the held-out blocks better by more than one
    standard error (:func:`_ahead_by_one_se` on the per-block squared-error reductions of the
    higher-ranked model against it); the admissible effect with the fewest fitted parameters is
    named (the leader on a tie).  This is the "one-standard-error rule" of model selection
    (Hastie, Tibshirani & Friedman 2009, *The Elements of Statistical Learning*, 2nd ed.,
    sec. 7.10): among models whose predictive error the data cannot tell apart, the simplest.  A
    flexible candidate (pinching: band and slack, five parameters) can then no longer take the
    place of a simpler effect it only imitates, while an effect that predicts better than a
    simpler one by more than the blocks' scatter keeps its place.

    Why not the effect's own block rank test (p < ``ALPHA`` / 2) here: that test asks whether an
    effect is real at all, and its signs ignore sizes.  Between two significant effects on an
    earthquake record, the strong-motion windows carry the difference and the free-vibration
    windows flip coins, so the rank test keeps the simpler model even where the other closes
    most of the error the simpler one leaves; the tie of the one-standard-error rule is read from
    the sizes of the gains.
    """
    leader = sig[0]

    def beaten(i: int, o: EffectScore) -> bool:
        return any(_ahead_by_one_se(sc.parts(fits[a.law], fits[o.law]).gains) for a in sig[:i])

    admissible = [o for i, o in enumerate(sig) if i == 0 or not beaten(i, o)]
    best = min(admissible, key=lambda o: (_n_free(fits[o.law]), sig.index(o)))
    if best is leader:
        return leader.effect, ""
    return best.effect, (
        f"{best.effect} named before {leader.effect} (larger held-out gain): it has fewer fitted "
        f"parameters ({_n_free(fits[best.law])} against {_n_free(fits[leader.law])}) and no "
        f"significant effect ranked above it predicts the held-out blocks better by more than one "
        f"standard error (parsimony)")
