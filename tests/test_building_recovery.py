"""Isolators that recover between runs (``BuildingModel(recover=True)``, the ``recovering`` variant
of a history effect): every run is driven from the virgin state, as when the rests between
shake-table runs let the rubber's softening recover; by default the state is carried.

The truth here is a building on Mullins-softening isolators whose two runs were each simulated from
the virgin state (the recovering truth) or one after the other (the carried truth).
"""

from __future__ import annotations

import numpy as np
import pytest

from structures.shake_table.building_model import RECOVERING, BuildingModel
from structures.shake_table.simulation import BuildingData, Superstructure
from tests._shake_table_truth import PL, ZETA, model_of

MULLINS = {"mullins": 0.4, "mullins_shape": 1.0}


def _x(model: BuildingModel, extra=None) -> np.ndarray:
    vals = {**PL, **(extra or {}), "k_scale": 1.0, "zeta": ZETA}
    return np.array([vals[n] for n in model.layout.names])


def _rms(a):
    return float(np.sqrt(np.mean(np.asarray(a) ** 2)))


def test_a_recovering_building_drives_each_run_from_the_virgin_state(truth):
    """Run 2 of the recovering model is run 2 driven alone, bit for bit, and not run 2 after run 1
    (the isolators yield in run 1 and would carry a residual state); run 1 is the same either way."""
    b, runs = truth
    carried = model_of(runs, Superstructure.of(b), PL)
    recovering = BuildingModel("plasticity", carried.sup, carried.start_test, carried.scales, draws=8,
                               loop_fit=carried.loop_fit, recover=True)
    x = _x(carried)
    both = BuildingData(tuple(runs))
    _, rec = recovering.simulate(x, both)
    _, car = carried.simulate(x, both)
    _, alone = carried.simulate(x, BuildingData((runs[1],)))
    for c in rec["run2"]:
        np.testing.assert_array_equal(rec["run2"][c], alone["run2"][c], err_msg=c)
        np.testing.assert_array_equal(rec["run1"][c], car["run1"][c], err_msg=c)
    gap = _rms(rec["run2"]["isolator_force"] - car["run2"]["isolator_force"])
    assert gap > 1e-4 * _rms(car["run2"]["isolator_force"])


def test_history_effects_have_the_recovering_variant_and_others_not(truth):
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    for effect in ("mullins", "scragging", "degradation"):
        assert m.variants(effect) == (RECOVERING,)
        assert not m.shape_variant(effect, RECOVERING)
    for effect in ("rate", "pinching", "isolation_damping", "softening"):
        assert m.variants(effect) == ()
    rec = m.augment(["mullins"], variants={"mullins": RECOVERING})
    plain = m.augment(["mullins"])
    assert rec.recover and not plain.recover
    assert rec.name == "plasticity+mullins (recovering)" and plain.name == "plasticity+mullins"
    # a recovering model adds effects and stays recovering; its fits are checkpointed apart
    assert rec.augment(["rate"]).recover
    data = BuildingData(tuple(runs), observed=("run1",))
    assert rec.checkpoint_key(data) != plain.checkpoint_key(data)
    with pytest.raises(ValueError, match="unknown variant 'wider' of 'mullins'.*expected 'recovering'"):
        m.augment(["mullins"], variants={"mullins": "wider"})
    with pytest.raises(ValueError, match="unknown variant 'recovering' of 'rate'"):
        m.augment(["rate"], variants={"rate": RECOVERING})


def test_mullins_isolators_that_recover_are_reproduced_only_by_the_recovering_model(truth):
    """The recovering truth (each run of a Mullins building from the virgin state) is reproduced by
    the recovering model at the true parameters and missed by the carried one, and conversely: the
    two memories are different buildings, told apart by the data."""
    b, runs = truth
    base = model_of(runs, Superstructure.of(b), PL)
    carried = base.augment(["mullins"])
    recovering = base.augment(["mullins"], variants={"mullins": RECOVERING})
    x = _x(carried, MULLINS)
    both = BuildingData(tuple(runs))
    _, truth_rec = recovering.simulate(x, both)
    _, truth_car = carried.simulate(x, both)
    scale = _rms(truth_rec["run2"]["isolator_disp"])
    miss = _rms(truth_rec["run2"]["isolator_disp"] - truth_car["run2"]["isolator_disp"])
    assert miss > 0.01 * scale  # run 1's softening, carried into run 2, moves it by more than 1 %
    # the recovering model at the truth reproduces its own truth run by run and in any grouping
    _, again = recovering.simulate(x, BuildingData(tuple(runs), observed=("run2",)))
    np.testing.assert_array_equal(again["run2"]["isolator_disp"], truth_rec["run2"]["isolator_disp"])
