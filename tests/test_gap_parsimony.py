"""With held-out data the diagnosis names, among the significant effects that no higher-ranked
one beats on the held-out blocks, the one with the fewest fitted parameters (parsimony)."""

from types import SimpleNamespace

import numpy as np

from rrfrei.gap.scoring import _parsimonious

WINS = np.linspace(0.5, 2.0, 40)  # every held-out block gains: a significant win
TIES = np.resize([1.0, -1.1, 0.9, -0.8], 40)  # as many losses as gains: no significant win


class _Scorer:
    def __init__(self, wins):
        self.wins = wins  # (better, worse) law pairs whose gains are a significant win

    def parts(self, fit, ref):
        return SimpleNamespace(gains=WINS if (fit.name, ref.name) in self.wins else TIES)


def _case(free, wins):
    sig = [SimpleNamespace(effect=e, law=f"base+{e}") for e in free]
    fits = {f"base+{e}": SimpleNamespace(name=f"base+{e}", free=tuple(range(k)), params={})
            for e, k in free.items()}
    return _Scorer({(f"base+{a}", f"base+{b}") for a, b in wins}), fits, sig


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
