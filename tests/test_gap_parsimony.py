"""With held-out data the diagnosis names, among the significant effects that no higher-ranked
one predicts better on the held-out blocks by more than one standard error, the one with the
fewest fitted parameters (parsimony, the one-standard-error rule)."""

from types import SimpleNamespace

import numpy as np

from rrfrei.gap.decision import rank_evidence
from rrfrei.gap.scoring import _ahead_by_one_se, _parsimonious

WINS = np.linspace(0.5, 2.0, 40)  # every held-out block gains: a significant win
TIES = np.resize([1.0, -1.1, 0.9, -0.8], 40)  # as many losses as gains: no significant win
# an earthquake record: four strong-motion windows carry the difference, the other 21 flip coins
STRONG = np.concatenate([[5900.0, 3800.0, 1800.0, 980.0], np.resize([40.0, -40.0, 9.0, -180.0, 7.0], 21)])


class _Scorer:
    def __init__(self, wins):
        self.wins = wins  # (better, worse) law pairs whose gains are a significant win

    def parts(self, fit, ref):
        if (fit.name, ref.name) in self.wins:
            return SimpleNamespace(gains=self.wins[fit.name, ref.name])
        return SimpleNamespace(gains=TIES)


def _case(free, wins):
    sig = [SimpleNamespace(effect=e, law=f"base+{e}") for e in free]
    fits = {f"base+{e}": SimpleNamespace(name=f"base+{e}", free=tuple(range(k)), params={})
            for e, k in free.items()}
    wins = {(a, b): WINS for a, b in wins} if not isinstance(wins, dict) else wins
    return _Scorer({(f"base+{a}", f"base+{b}"): g for (a, b), g in wins.items()}), fits, sig


def test_a_flexible_leader_that_does_not_beat_a_simpler_effect_gives_way_to_it():
    sc, fits, sig = _case({"pinching": 10, "mullins": 7}, wins=[])
    name, note = _parsimonious(sc, fits, sig)
    assert name == "mullins" and "fewer fitted parameters (7 against 10)" in note


def test_a_leader_that_beats_the_simpler_effect_on_the_held_out_blocks_keeps_its_place():
    sc, fits, sig = _case({"pinching": 10, "mullins": 7}, wins=[("pinching", "mullins")])
    assert _parsimonious(sc, fits, sig) == ("pinching", "")


def test_an_effect_beaten_by_any_higher_ranked_one_is_not_admissible():
    # a beats c, nobody beats b: b (8) is named, not the simplest c (5)
    sc, fits, sig = _case({"a": 10, "b": 8, "c": 5}, wins=[("a", "c")])
    assert _parsimonious(sc, fits, sig)[0] == "b"
    # a leader with the fewest parameters stays whatever the others
    sc, fits, sig = _case({"a": 5, "b": 8}, wins=[])
    assert _parsimonious(sc, fits, sig) == ("a", "")


def test_gains_carried_by_a_few_strong_windows_are_a_win_the_rank_test_cannot_see():
    # 16 of 25 windows gain: the sign/signed-rank test is far from p < 0.005, yet the total gain
    # is more than one standard error of it, so the models are not tied
    assert not rank_evidence(STRONG).passes()
    assert _ahead_by_one_se(STRONG)
    sc, fits, sig = _case({"rate": 12, "isolation_damping": 10}, wins={("rate", "isolation_damping"): STRONG})
    assert _parsimonious(sc, fits, sig) == ("rate", "")


def test_a_total_gain_within_one_standard_error_is_a_tie():
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 1.0, 40)
    small = noise - noise.mean() + 0.5 / np.sqrt(40)  # total: half a standard error
    assert not _ahead_by_one_se(small)
    assert _ahead_by_one_se(small + 2.0 / np.sqrt(40))  # total: 2.5 standard errors
    assert not _ahead_by_one_se(np.array([3.0]))  # one block has no standard error
    sc, fits, sig = _case({"pinching": 10, "mullins": 7}, wins={("pinching", "mullins"): small})
    assert _parsimonious(sc, fits, sig)[0] == "mullins"
