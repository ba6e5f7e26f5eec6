"""Which effects a combination step tries (rrfrei.gap.diagnose, step 5).

The significant effects always; for a model whose effects act on each other's evidence
(``GapModel.interacting_effects``: a building fitted by output error) also every effect whose gains
pass the rule's rank tests (calibration and held-out blocks) but whose shrink alone is too small,
because such an effect may close the held-out gap only beside another.  An effect tried so is
still named only when it passes the whole rule against the current combination.

The model is the engine tests' linear one (tests/test_gap_robust.py): force = b0 u + effect
regressors, exact least squares.
"""

from __future__ import annotations

import sys
from types import SimpleNamespace

from scipy.stats import binomtest

from rrfrei.gap.decision import RankEvidence
from rrfrei.gap.diagnose import diagnose
from tests.test_gap_robust import EFFECTS, LinearModel
from tests.test_gap_robust import _tests as _robust_tests


class InteractingLinear(LinearModel):
    interacting_effects = True

    def augment(self, effects):
        return InteractingLinear(self.effects + tuple(effects), clock=self.clock, cost=self.cost,
                                 fail=self.fail, calls=self.calls)


def test_an_interacting_model_tries_the_effects_with_consistent_gains_in_its_combination(monkeypatch):
    """force = 2 u + 0.3 |u|: asymmetry is named; rollover, given consistent gains here, is tried
    beside it by the interacting model only, and not combined (it closes nothing held out)."""
    dg = sys.modules["rrfrei.gap.diagnose"]  # the module (the package exports its function by this name)
    monkeypatch.setattr(dg, "_consistent", lambda s: s.effect == "rollover")
    cal, ho = _robust_tests()
    plain, inter = LinearModel(), InteractingLinear()
    for m in (plain, inter):
        rep = diagnose(m, cal, [ho], effects=EFFECTS)
        assert rep.diagnosis == "asymmetry"
        assert rep.combination == ("asymmetry",)
    assert "linear+asymmetry+rollover" in inter.calls
    assert not any(c.startswith("linear+asymmetry+") for c in plain.calls)
    assert "linear+asymmetry+degradation" not in inter.calls  # not consistent, not tried


def _evidence(total: float, positive: int, blocks: int = 20) -> RankEvidence:
    p = float(binomtest(positive, blocks, 0.5, alternative="greater").pvalue)
    return RankEvidence(blocks=blocks, positive=positive, total=total, p_sign=p, p_wilcoxon=p)


def test_consistent_gains_are_the_rank_tests_of_the_rule_without_the_shrink_bound():
    """Calibration gain above MIN_GAIN nats with its blocks' test, and the held-out blocks' test:
    each needed; without held-out data the calibration part decides."""
    from rrfrei.gap.diagnose import MIN_GAIN, _consistent

    def score(cal, ho):
        return SimpleNamespace(blocks_calibration=cal, blocks_holdout=ho)

    good, few = _evidence(MIN_GAIN + 20, 19), _evidence(MIN_GAIN + 20, 11)
    assert _consistent(score(good, good))
    assert _consistent(score(good, None))  # no held-out data
    assert not _consistent(score(_evidence(MIN_GAIN - 1, 19), good))  # too small a gain
    assert not _consistent(score(few, good))  # calibration gains carried by a few blocks
    assert not _consistent(score(good, few))  # held-out blocks as often worse as better
    assert not _consistent(score(None, good))
