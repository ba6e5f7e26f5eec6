"""The PRF model in the one gap engine: ``rrfrei.gap.diagnose`` diagnoses rubber as it does isolators
and buildings (issue 27.2), from the model interface alone (fit, predict, per-draw log-likelihood,
blocks).

Synthetic data as in ``test_rubber_gap`` (the PRF model of case A plus a withheld effect written
independently of the catalogue's form, plus white noise), on longer protocols: the block rule needs
at least ``rrfrei.gap.decision.min_blocks()`` loading cycles on each side.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_rubber_gap import GENERATORS, NOISE, TRUTH, local_model

import rubber
from rrfrei.gap import diagnose
from rrfrei.gap.decision import min_blocks
from rubber import protocol1
from rubber.gap import EFFECTS
from rubber.gap.model import DRAWS

CAL = protocol1(1.2, 0.1, 10, dt=0.1)  # 11 loading cycles (blocks)
HOLDOUT = protocol1(1.25, 0.15, 8, rate=0.2, dt=0.1)  # 9, larger and twice as fast


def synthetic(effect: str, seed: int = 1) -> tuple[rubber.Test, rubber.Test]:
    rng = np.random.default_rng(seed)
    return tuple(
        rubber.Test(name, t, lam, GENERATORS[effect](TRUTH, t, lam) + NOISE * rng.normal(size=t.size))
        for name, (t, lam) in (("sawtooth_1.2", CAL), ("sawtooth_1.25_fast", HOLDOUT)))


def test_the_protocols_give_the_block_rule_enough_blocks():
    cal, ho = synthetic("none")
    m = local_model()
    assert np.unique(m.groups(cal)).size >= min_blocks()
    assert np.unique(m.groups(ho)).size >= min_blocks()


def test_a_fit_carries_importance_corrected_laplace_draws_and_scores_each_one(monkeypatch):
    cal, ho = synthetic("mullins")
    fit = local_model().fit(cal)
    assert len(fit.draws) == DRAWS and 1.0 <= fit.ess <= DRAWS
    ll = fit.loglik(ho)
    assert ll.shape == (DRAWS, ho.time.size) and np.all(np.isfinite(ll))
    pred = fit.predict(ho)
    assert pred.draws.shape == (DRAWS, ho.time.size)
    assert np.all(pred.lower < pred.mean) and np.all(pred.mean < pred.upper)
    # the band is never narrower than the residual scale alone
    assert np.all(pred.upper - pred.mean >= 1.959 * fit.sigma)
    # the engine's multi-start: a list of fits is a start (least squares from it: no worse, up to
    # the round trip of the start through the search's unit coordinates)
    again = local_model().fit(cal, start=[fit])
    assert again.name == fit.name and again.rss <= 1.01 * fit.rss
    # a draw the integrator cannot follow is said in the fit's notes (the engine reports them)
    assert fit.note == ""
    bad, real = fit.draws[0][0], rubber.gap.model.augmented_stress

    def failing(prf, *args, **kw):
        if prf is bad:
            raise FloatingPointError("step size underflow")
        return real(prf, *args, **kw)

    monkeypatch.setattr(rubber.gap.model, "augmented_stress", failing)
    failed = fit.failed_draws([cal, ho])
    assert failed >= 1 and f"{failed} of {DRAWS} Laplace draws failed" in fit.note
    assert [n.severity for n in fit.notes] == ["warning"]


@pytest.mark.slow  # a validation study (the other two withheld effects are beside it)
def test_the_one_engine_names_withheld_mullins_damage_on_rubber():
    cal, ho = synthetic("mullins")
    rep = diagnose(local_model(), cal, [ho], seed=0)
    assert {s.effect for s in rep.ranking} == set(EFFECTS)  # the PRF catalogue, not the isolators'
    assert rep.verdict == "mullins"
    named = next(s for s in rep.ranking if s.effect == "mullins")
    assert named.significant and named.shrink_ci.lower > 0.5  # most of the held-out gap closes


@pytest.mark.slow
@pytest.mark.parametrize("effect,verdict", [("permanent_set", "permanent_set"), ("none", "none")])
def test_the_one_engine_names_permanent_set_and_raises_no_false_alarm(effect, verdict):
    cal, ho = synthetic(effect)
    rep = diagnose(local_model(), cal, [ho], seed=0)
    assert rep.verdict == verdict
    assert [s.effect for s in rep.ranking if s.significant] == ([] if effect == "none" else [effect])
