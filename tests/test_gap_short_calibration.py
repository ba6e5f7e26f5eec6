"""A calibration test too short for the block rule's rank test to weigh an effect.

With ``m`` calibration blocks the rank test passes only when at least
:func:`rrfrei.gap.decision.needed_gains` of them gain: every block for ``m <= 10``, all but one
up to 14 (:func:`rrfrei.gap.decision.underpowered`).  Two short shake-table runs give 8 blocks of
10 s, so an effect that closes much of the held-out gap was lost when two calibration blocks
lost.  With held-out data the calibration part then asks for the total gain and a majority of
gaining blocks, and the held-out part (rank test and shrink bound) decides; the diagnosis says so
in a note.  Without held-out data, or with enough calibration blocks (an isolator test's 20), the
rule is unchanged.
"""

from __future__ import annotations

from scipy.stats import binom

from rrfrei.gap import decision as dec
from rrfrei.gap.diagnose import diagnose
from tests.test_gap_few_blocks import _test
from tests.test_gap_robust import EFFECTS, LinearModel


def _evidence(positive: int, blocks: int, total: float = 50.0) -> dec.RankEvidence:
    p = float(binom.sf(positive - 1, blocks, 0.5))
    return dec.RankEvidence(blocks=blocks, positive=positive, total=total, p_sign=p, p_wilcoxon=p)


STRONG_HOLDOUT = _evidence(44, 46, 4e4)
SHRINK = dec.ShrinkEvidence(0.84, 0.51, 0.39, 0.26, 0.46)


def test_needed_gains_is_the_fewest_gaining_blocks_that_pass_the_sign_test():
    for m in range(1, 40):
        k = dec.needed_gains(m)
        if k <= m:
            assert binom.sf(k - 1, m, 0.5) < dec.ALPHA / 2 <= binom.sf(k - 2, m, 0.5)
        else:
            assert binom.sf(m - 1, m, 0.5) >= dec.ALPHA / 2
    assert [m for m in range(8, 30) if dec.underpowered(m)] == list(range(8, 15))


def test_a_majority_of_few_calibration_blocks_with_decisive_held_out_blocks_names_the_effect():
    ok, why = dec.significant(_evidence(6, 8), STRONG_HOLDOUT, SHRINK)
    assert ok
    assert "6/8 gain" in why and "named on the held-out evidence" in why


def test_without_held_out_data_few_calibration_blocks_still_need_the_rank_test():
    ok, why = dec.significant(_evidence(6, 8), None, SHRINK)
    assert not ok and "calibration blocks: p = " in why


def test_the_held_out_part_still_decides_and_a_minority_of_calibration_blocks_is_refused():
    weak_ho = _evidence(30, 46, 1e3)  # p ~ 0.03: not significant
    assert not dec.significant(_evidence(6, 8), weak_ho, SHRINK)[0]
    small = dec.ShrinkEvidence(0.84, 0.80, 0.05, -0.02, 0.12)
    assert not dec.significant(_evidence(6, 8), STRONG_HOLDOUT, small)[0]
    assert not dec.significant(_evidence(4, 8), STRONG_HOLDOUT, SHRINK)[0]  # half: no majority
    assert not dec.significant(_evidence(6, 8, total=2.0), STRONG_HOLDOUT, SHRINK)[0]  # gain <= 4 nats


def test_enough_calibration_blocks_keep_the_rank_test():
    """20 blocks (an isolator test's windows): 15 gaining is p = 0.021, not named."""
    assert not dec.underpowered(20)
    assert not dec.significant(_evidence(15, 20), STRONG_HOLDOUT, SHRINK)[0]


def test_a_short_calibration_test_with_held_out_data_says_the_held_out_blocks_decide():
    cal = _test("cal", 5, 0)  # five cycles: ten half-cycle blocks
    ho = _test("ho", 10, 1)
    rep = diagnose(LinearModel(), cal, [ho], effects=EFFECTS)
    assert any("too few for the block rule's rank test to weigh an effect" in n for n in rep.notes)
    assert rep.verdict == "asymmetry"  # every block gains here: named as before
    long = diagnose(LinearModel(), _test("cal", 10, 0), [ho], effects=EFFECTS)
    assert not any("to weigh an effect" in n for n in long.notes)
