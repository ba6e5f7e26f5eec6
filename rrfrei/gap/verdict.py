"""The gap engine's verdict and its evidence (step 6 of :mod:`rrfrei.gap.diagnose`): the named
effect, ``"none"`` (what is left is noise), ``"unexplained"`` or ``"incomplete"``, with the
numbers behind it."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from rrfrei.gap import decision as dec
from rrfrei.gap.model import FitResult
from rrfrei.gap.results import EffectScore
from rrfrei.gap.scoring import _Scorer
from rrfrei.jsonable import number as _num

__all__ = ["VERDICTS"]

VERDICTS = ("none", "unexplained", "incomplete")
"""The verdicts that name no effect (otherwise the verdict is the named effect)."""


def _residuals(sc: _Scorer, fit: FitResult) -> dict:
    out = {"calibration": sc.residual(fit, [sc.cal])}
    if sc.holdout:
        out["holdout"] = sc.residual(fit, sc.holdout)
    return out


def _verdict(sc: _Scorer, diagnosis: str, combination: list[str], base: FitResult, final: FitResult,
             ranking: tuple[EffectScore, ...], steps: list[EffectScore], where: pd.DataFrame,
             tied: list[str], missing: dict[str, str],
             alternatives: Sequence[tuple[EffectScore, dec.GapDifference]] = ()
             ) -> tuple[str, dict]:
    """The verdict and its evidence (see :func:`rrfrei.gap.diagnose.diagnose`); ``alternatives``:
    the effects the held-out data cannot tell from the named one, each with how much more of the
    baseline's held-out systematic gap it leaves than the named effect
    (:func:`rrfrei.gap.diagnose._alternatives`)."""
    rule = ("an effect is named when its leave-one-block-out gains on the calibration test total > "
            f"{dec.MIN_GAIN:g} nats and pass a sign or Wilcoxon signed-rank test over blocks at "
            f"p < {dec.ALPHA / 2:g}" + (" (with held-out tests and too few calibration blocks for that "
                                         "test to weigh an effect, fewer than 15: a majority of them)"
                                         if sc.holdout else "")
            + (f", and on the held-out tests its per-block squared-error "
                                         f"reductions pass the same test and the block-bootstrap "
                                         f"{dec.LEVEL:.0%} interval of the held-out systematic-gap "
                                         f"shrink lies above {dec.MIN_SHRINK:.0%}" if sc.holdout else
                                         f", and the block-bootstrap {dec.LEVEL:.0%} interval of the "
                                         f"calibration test's systematic-gap shrink lies above "
                                         f"{dec.MIN_SHRINK:.0%}")
            + f"; what is left is noise when its MSE / sigma^2 - 1 <= {dec.EXCESS:g}, its "
            f"systematic NRMSE <= {dec.SYS_FLOOR:.0%}, or its residuals are white (|lag-1 "
            "autocorrelation| < 2 / sqrt(n))")
    before = {k: v.as_dict() for k, v in _residuals(sc, base).items()}
    ev: dict = {"rule": rule, "baseline": before, "tied": list(tied)}
    scored = [s for s in ranking if math.isfinite(s.shrink_holdout if sc.holdout else s.shrink_calibration)]
    key = (lambda s: s.shrink_holdout) if sc.holdout else (lambda s: s.shrink_calibration)
    closest = max(scored, key=key) if scored else None
    if closest is not None:
        ce = closest.evidence()
        ev["closest"] = {"effect": closest.effect, **ce, "shrink": _num(key(closest)),
                         "shrink_ci": ce["shrink"]}
    if diagnosis not in VERDICTS:
        left = _residuals(sc, final)
        ev["named"] = {"effect": diagnosis, "combination": list(combination),
                       "steps": [{"effect": s.effect, **s.evidence()} for s in steps]}
        ev["alternatives"] = [{"effect": s.effect, "label": s.label, "passes_rule": s.significant,
                               "shrink": _num(key(s)), "shrink_ci": s.evidence()["shrink"],
                               "against_named": vs.as_dict(), "why": s.why} for s, vs in alternatives]
        ev["left"] = {k: v.as_dict() for k, v in left.items()}
        ev["left_is_noise"] = all(v.noise_only for v in left.values())
        return diagnosis, ev
    if diagnosis == "incomplete":
        ev["not_evaluated"] = dict(missing)
        return "incomplete", ev
    res = _residuals(sc, base)
    noisy = [k for k, v in res.items() if not v.noise_only]
    ev["systematic_on"] = noisy
    if not noisy:
        ev["reasons"] = [
            f"{k}: systematic gap {_pct(v.systematic)} of the RMS force, "
            f"MSE / sigma^2 - 1 = {v.excess:.2f} "
            f"(noise: <= {dec.EXCESS:g}, <= {dec.SYS_FLOOR:.0%} or white); "
            "lag-1 autocorrelation of the residuals "
            f"{v.rho1:.2f} ({'white' if v.white else 'not white'} at 2 / sqrt(n))" for k, v in res.items()]
        if closest is not None:
            ev["reasons"].append(f"no effect passes the block rule; closest {closest.effect}: {closest.why}")
        return "none", ev
    ev["where"] = [{"axis": r.axis, "segment": r.segment, "error_share": _num(r.error_share),
                    "rms_over_noise": _num(r.rms_over_noise)} for r in where.head(3).itertuples()]
    ev["size"] = {k: _num(v.systematic) for k, v in res.items()}
    return "unexplained", ev


def _pct(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{100 * x:.1f} %"
