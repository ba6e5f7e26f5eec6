"""The named effect's model fitted from scratch stands for its building (rrfrei.gap.diagnose).

For a model whose effects interact (a building fitted by output error), an effect's refit starts
from the baseline's optimum, which the missing effect shaped, and every combination step would
inherit that basin.  So the named effect's model is also fitted from scratch (the baseline's
search, ``start=None``); when the calibration data prefer that fit (total leave-one-block-out
elpd), it stands for the effect's building: the combination starts from it and is judged against
it, and it is the final model when nothing is added.  The effect stays named on its refit's
evidence.  A model whose effects do not interact is not refitted.

The model is the engine tests' linear one (tests/test_gap_robust.py: force = 2 u + 0.3 |u| +
noise) whose refits from a start end in a poorer optimum (the effects' coefficients at 80 % of
their least-squares values), as a refit held in the baseline's basin does; rollover is made
consistent so that a combination step runs.
"""

from __future__ import annotations

import sys

from rrfrei.gap.diagnose import diagnose
from tests.test_gap_robust import EFFECTS, LinearFit, LinearModel
from tests.test_gap_robust import _tests as _robust_tests


class Stuck(LinearModel):
    """Exact least squares from scratch; from a start, the effects' coefficients at ``stuck`` of it.
    ``calls``: (model name, the starts' names, or None from scratch)."""

    def __init__(self, effects=(), *, interacting=True, stuck=0.8, calls=None, **kw):
        super().__init__(effects, calls=calls, **kw)
        self.interacting_effects = interacting
        self.stuck = stuck

    def augment(self, effects):
        return Stuck(self.effects + tuple(effects), interacting=self.interacting_effects, stuck=self.stuck,
                     calls=self.calls)

    def fit(self, data, *, seed=0, start=None, budget=None):
        fit = super().fit(data, seed=seed, start=start, budget=budget)
        starts = None if start is None else [start] if isinstance(start, LinearFit) else list(start)
        self.calls[-1] = (self.name, None if starts is None else tuple(s.params["b1"] if len(s.beta) > 1
                                                                        else None for s in starts))
        if start is None or not self.effects:
            return fit
        beta = fit.beta.copy()
        beta[1:] *= self.stuck
        return LinearFit(fit.effects, beta, fit.B - fit.beta + beta, fit.sigma)


def _run(monkeypatch, **kw):
    dg = sys.modules["rrfrei.gap.diagnose"]
    monkeypatch.setattr(dg, "_consistent", lambda s: s.effect == "rollover")
    cal, ho = _robust_tests()
    calls: list = []
    rep = diagnose(Stuck(calls=calls, **kw), cal, [ho], effects=EFFECTS)
    return rep, calls


def test_the_named_effect_fitted_from_scratch_stands_for_its_building_and_starts_the_combination(monkeypatch):
    rep, calls = _run(monkeypatch)
    assert rep.diagnosis == "asymmetry"
    assert rep.combination == ("asymmetry",)
    assert ("linear+asymmetry", None) in calls  # fitted from scratch
    step = [c for c in calls if c[0] == "linear+asymmetry+rollover"]
    assert len(step) == 1 and len(step[0][1]) == 1
    (start_b1,) = step[0][1]
    assert abs(start_b1 - 0.3) < 0.05  # the combination starts from the fit from scratch
    final = rep.fits["linear+asymmetry"]  # the building that stands for the named effect
    assert final.params["b1"] == start_b1
    alone = next(s for s in rep.ranking if s.effect == "asymmetry")
    assert alone.params["b1"] < 0.8 * start_b1 + 1e-9  # the refit, stuck at 80 %
    assert rep.steps[0] is alone  # the effect is named on its refit's evidence
    # the final metrics are the fit from scratch's: it leaves less of the held-out gap than the refit
    assert rep.final[1].systematic < alone.holdout.systematic
    assert any("fitted from scratch" in str(n) for n in rep.notes)


def test_a_refit_as_good_as_from_scratch_stands(monkeypatch):
    rep, calls = _run(monkeypatch, stuck=1.0)  # refits reach the optimum
    alone = next(s for s in rep.ranking if s.effect == "asymmetry")
    assert rep.fits["linear+asymmetry"].params["b1"] == alone.params["b1"]
    assert not any("fitted from scratch" in str(n) for n in rep.notes)


def test_a_model_whose_effects_do_not_interact_is_not_fitted_from_scratch(monkeypatch):
    rep, calls = _run(monkeypatch, interacting=False)
    assert rep.diagnosis == "asymmetry"
    assert ("linear+asymmetry", None) not in calls
    alone = next(s for s in rep.ranking if s.effect == "asymmetry")
    assert rep.fits["linear+asymmetry"].params["b1"] == alone.params["b1"]
