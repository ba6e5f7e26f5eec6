"""A posterior from a very different specimen is flagged before it drives a building.

* the building's own design bearing (and draws around it) passes both checks silently;
* a reinforced-concrete-column-like posterior (stiff, strong, calibrated on +-20 mm) gives an
  isolated period barely above the fixed-base one, and a stiffness tens of times the design
  bearing's: both are named, with numbers, as a ``SpecimenWarning`` and a note of the result;
* a bearing of the right kind but five times too soft (a smaller specimen run without its
  similitude scale) still isolates, so it trips the stiffness check only.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

import ground_motions
import structures
from rrfrei.laws import get as get_law
from structures.building.specimen import SpecimenWarning, specimen_checks
from structures.propagation.propagate import propagate


@pytest.fixture(scope="module")
def five():
    return structures.load_building("five_story")


def _design(five) -> dict[str, float]:
    return dict(five.isolator.params)


def _column(five) -> dict[str, float]:
    """Bouc-Wen fitted to a concrete column: k0 ~ 60 MN/m, yield ~ 150 kN at ~ 2.5 mm."""
    p = _design(five)
    p.update(k_init=60000.0, qd=150.0, alpha1=0.05)
    return p


def test_the_design_bearing_passes_both_checks(five):
    s = five.isolator.length_scale
    assert specimen_checks(five, _design(five), 0.1 * s) == []
    assert specimen_checks(five, _design(five), None) == []  # the assumed 0.1 m prototype


def test_a_concrete_column_posterior_fails_the_period_shift_and_the_stiffness_check(five):
    msgs = specimen_checks(five, _column(five), 0.02 * five.isolator.length_scale)
    assert len(msgs) == 2
    period, stiffness = msgs
    t1 = five.fixed_base_modes()[0][0]
    assert f"{t1:.2f} s" in period and "isolated period" in period and "an isolator needs >= 2" in period
    assert "different specimen" in stiffness and "x either way" in stiffness


def test_a_bearing_five_times_too_soft_trips_only_the_stiffness_check(five):
    p = _design(five)
    p.update(k_init=p["k_init"] / 5, qd=p["qd"] / 5)
    msgs = specimen_checks(five, p, 0.1 * five.isolator.length_scale)
    assert len(msgs) == 1 and "different specimen" in msgs[0]


def _draws(spec, params: dict[str, float], n: int, dmax: float) -> pd.DataFrame:
    df = pd.DataFrame({q.name: np.full(n, float(params.get(q.name, q.default or 0.0))) for q in spec.params})
    df.attrs.update(law=spec.name, disp_min_m=-dmax, disp_max_m=dmax)
    return df


def test_propagate_warns_and_notes_a_foreign_posterior_but_not_the_design_one(five):
    spec = get_law(five.isolator.law)
    r = ground_motions.load("elcentro")
    rec = ground_motions.Record(r.name, r.dt, r.accel[: int(2.0 / r.dt)], r.meta)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SpecimenWarning)
        ok = propagate(_draws(spec, _design(five), 2, 0.1), five, [rec], n_samples=2, progress=False)
    assert not any("isolator needs" in n for n in ok.notes)
    with pytest.warns(SpecimenWarning) as caught:
        bad = propagate(_draws(spec, _column(five), 2, 0.02), five, [rec], n_samples=2, progress=False)
    said = [str(w.message) for w in caught if w.category is SpecimenWarning]
    assert len(said) == 2 and "isolated period" in said[0] and "different specimen" in said[1]
    assert said == [n for n in bad.notes if n in said]
