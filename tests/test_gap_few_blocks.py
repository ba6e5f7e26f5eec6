"""The block rule cannot name an effect on too few blocks, and the diagnosis says so.

Its rank tests need ``rank_p < ALPHA / 2``; with every one of ``m`` blocks gaining, both the
one-sided sign test and the exact signed-rank test give ``p = 2^-m``, so fewer than
:func:`rrfrei.gap.decision.min_blocks` blocks can never pass.  Short held-out data (the 20 s
synthetic shake-table runs of the building validation give 2 held-out blocks of 10 s) therefore
end "unexplained" however much an effect closes: the report must say that the verdict is the
rule's limit, not the effects' failure.
"""

from __future__ import annotations

import numpy as np

from rrfrei.gap import decision as dec
from rrfrei.gap.diagnose import diagnose
from rrfrei.io import ShearTest
from tests.test_gap_robust import EFFECTS, LinearModel


def _test(name: str, cycles: int, seed: int) -> ShearTest:
    """force = 2 u + 0.3 |u| + noise (sd 0.05), ``cycles`` cycles at 1 Hz: the asymmetry is plain."""
    t = np.linspace(0.0, float(cycles), 50 * cycles, endpoint=False)
    u = 1.5 * np.sin(2 * np.pi * t)
    f = 2 * u + 0.3 * np.abs(u) + np.random.default_rng(seed).normal(0, 0.05, u.size)
    return ShearTest(name, t, u, f)


def test_min_blocks_is_the_fewest_all_gaining_blocks_that_pass_the_rank_tests():
    m = dec.min_blocks()
    assert dec.rank_evidence(np.ones(m)).passes()
    assert not dec.rank_evidence(np.ones(m - 1)).passes()
    assert dec.min_blocks(0.05) < m


def test_too_few_held_out_blocks_is_a_critical_note_not_a_silent_unexplained():
    cal = _test("cal", 10, 0)
    short = _test("short", 3, 1)  # three cycles: four blocks (half-cycles, the first and last joined)
    rep = diagnose(LinearModel(), cal, [short], effects=EFFECTS)
    few = [n for n in rep.notes if "no effect can be named" in n]
    assert few and "held-out data give 4 blocks" in few[0]
    assert getattr(few[0], "severity", "critical") == "critical"
    asym = next(s for s in rep.ranking if s.effect == "asymmetry")
    assert asym.blocks_holdout.positive == asym.blocks_holdout.blocks == 4
    assert rep.diagnosis != "asymmetry"  # every held-out block gains, yet the rule cannot pass


def test_enough_blocks_names_the_effect_without_the_note():
    cal, ho = _test("cal", 10, 0), _test("long", 10, 1)
    rep = diagnose(LinearModel(), cal, [ho], effects=EFFECTS)
    assert rep.diagnosis == "asymmetry"
    assert not any("no effect can be named" in n for n in rep.notes)
