"""Which effects a combination step tries (rrfrei.gap.diagnose, step 5).

The significant effects always; for a model whose effects act on each other's evidence
(``GapModel.interacting_effects``: a building fitted by output error) also every effect with
calibration support, because such an effect may close the held-out gap only beside another.  An
effect tried so is still named only when it passes the whole rule against the current combination.

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


def test_an_interacting_model_tries_the_effects_with_calibration_support_in_its_combination(monkeypatch):
    """force = 2 u + 0.3 |u|: asymmetry is named; rollover, given calibration support here, is tried
    beside it by the interacting model only, and not combined (it closes nothing held out)."""
    dg = sys.modules["rrfrei.gap.diagnose"]  # the module (the package exports its function by this name)
    monkeypatch.setattr(dg, "_calibration_support", lambda s: s.effect == "rollover")
    cal, ho = _robust_tests()
    plain, inter = LinearModel(), InteractingLinear()
    for m in (plain, inter):
        rep = diagnose(m, cal, [ho], effects=EFFECTS)
        assert rep.diagnosis == "asymmetry"
        assert rep.combination == ("asymmetry",)
    assert "linear+asymmetry+rollover" in inter.calls
    assert not any(c.startswith("linear+asymmetry+") for c in plain.calls)
    assert "linear+asymmetry+degradation" not in inter.calls  # no support, not tried


def _evidence(total: float, positive: int, blocks: int = 20) -> RankEvidence:
    p = float(binomtest(positive, blocks, 0.5, alternative="greater").pvalue)
    return RankEvidence(blocks=blocks, positive=positive, total=total, p_sign=p, p_wilcoxon=p)


def test_calibration_support_is_the_calibration_part_of_the_rule():
    """Gain above MIN_GAIN nats and the calibration blocks' rank test: both needed."""
    from rrfrei.gap.diagnose import MIN_GAIN, _calibration_support

    def score(ev):
        return SimpleNamespace(blocks_calibration=ev)

    assert _calibration_support(score(_evidence(MIN_GAIN + 20, 19)))
    assert not _calibration_support(score(_evidence(MIN_GAIN - 1, 19)))  # too small a gain
    assert not _calibration_support(score(_evidence(MIN_GAIN + 20, 11)))  # carried by a few blocks
    assert not _calibration_support(score(None))
