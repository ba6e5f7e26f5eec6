"""Which form of a history effect a combination step tries (rrfrei.gap.diagnose, step 5).

A model whose effects interact (``GapModel.interacting_effects``: a building fitted by output
error) may fit an effect in a variant that changes what is simulated (the building's runs each
from the virgin state, ``shape_variant`` false).  Which form stands for the effect alone is read
against the baseline, where the missing effects distort the evidence as they distort the effect's
gain; so the combination step refits such an effect in each of its forms against the combination
it would join, and the form the data ask for there is the one combined.

The model is the engine tests' linear one (tests/test_gap_robust.py) with one effect, ``slip``,
whose primary regressor is confounded with ``asymmetry`` and whose ``recovering`` variant is the
true one: force = 2 u + 0.3 |u| + 0.15 V(u) + noise.  Against the baseline the confounded
primary form explains more than the variant (it stands in for part of ``asymmetry``), so the
variant does not stand for ``slip`` alone; beside ``asymmetry`` only the variant is right.
"""

from __future__ import annotations

import numpy as np

from rrfrei.gap.diagnose import _forms, diagnose
from rrfrei.io import ShearTest
from tests.test_gap_robust import LinearModel

N = 600


def _ramp(u):
    return np.linspace(0.0, 1.0, u.size)


def _v(u):
    """The variant's (true) regressor."""
    return u * _ramp(u)


def _w(u):
    """A regressor the truth does not hold."""
    return u * np.cos(np.linspace(0.0, 7 * np.pi, u.size))


REG = {
    "asymmetry": lambda u: np.abs(u),
    "slip": lambda u: 0.5 * np.abs(u) + _v(u) + 0.5 * _w(u),  # the confounded primary form
    "slip:recovering": _v,
}


class FormsLinear(LinearModel):
    """Force = b0 u + regressors; ``slip`` has a ``recovering`` variant that changes what is simulated."""

    regressors = REG

    def __init__(self, effects=(), *, interacting=True, calls=None, **kw):
        super().__init__(effects, calls=calls, **kw)
        self.interacting_effects = interacting

    def augment(self, effects, variants=None):
        names = [f"{e}:{variants[e]}" if variants and e in variants else e for e in effects]
        return FormsLinear(self.effects + tuple(names), interacting=self.interacting_effects,
                           calls=self.calls)

    def variants(self, effect):
        return ("recovering",) if effect == "slip" else ()

    def shape_variant(self, effect, variant):
        return False


def _data():
    out = []
    for k, amp in enumerate((1.0, 1.5)):
        t = np.linspace(0.0, 12.0, N, endpoint=False)
        u = amp * np.sin(2 * np.pi * t)
        f = 2 * u + 0.3 * np.abs(u) + 0.15 * _v(u) + np.random.default_rng(k).normal(0, 0.05, u.size)
        out.append(ShearTest(f"test{k}", t, u, f))
    return out


def test_a_history_effect_is_combined_in_the_form_the_combination_asks_for():
    cal, ho = _data()
    rep = diagnose(FormsLinear(), cal, [ho], effects=["asymmetry", "slip"])
    slip = next(s for s in rep.ranking if s.effect == "slip")
    assert slip.variant == ""  # alone, against the baseline, the confounded primary form stands
    assert rep.diagnosis == "asymmetry"
    assert rep.combination == ("asymmetry", "slip")
    assert rep.steps[1].variant == "recovering"
    assert "linear+asymmetry+slip" in rep.fits and "linear+asymmetry+slip:recovering" in rep.fits


def test_a_model_whose_effects_do_not_interact_keeps_the_form_read_alone():
    cal, ho = _data()
    calls: list[str] = []
    rep = diagnose(FormsLinear(interacting=False, calls=calls), cal, [ho], effects=["asymmetry", "slip"])
    assert "linear+asymmetry+slip:recovering" not in calls
    assert all(s.variant == "" for s in rep.steps)


def test_the_forms_of_a_step_are_the_chosen_one_first_then_the_others_that_change_the_simulation():
    m = FormsLinear()
    assert _forms(m, ["asymmetry", "slip"], {}) == [("asymmetry", ""), ("slip", ""), ("slip", "recovering")]
    assert _forms(m, ["slip"], {"slip": "recovering"}) == [("slip", "recovering"), ("slip", "")]
    assert _forms(FormsLinear(interacting=False), ["slip"], {}) == [("slip", "")]
