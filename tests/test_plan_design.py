"""The code's answers (ASCE 7-22 Chapter 17 response history) of a plan building under pairs.

* the maximum plan isolator displacement is the largest vector sum over time: never below either
  component's maximum, equal to it along one axis, sqrt(2) x it on a diagonal, r on a circle;
* over the suite, 6 pairs give the maximum and 7 pairs the average;
* under a quasi-static push the lower-bound (softer) isolator moves 1/lambda_min times as far as
  the nominal one and the upper-bound one 1/lambda_max times: the bounds bracket the nominal,
  and the governing value is the larger bound;
* without torsion the total maximum displacement is the plan displacement; the corner-bearing
  amplification is 1 + (y / P_T^2) 12 e / (b^2 + d^2);
* a record with one component, a file given alone and a law without a plan form are refused with
  errors that say what to give instead.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import ground_motions
import structures
from structures.propagation.plan_design import (
    ANSWERS,
    PlanDesignAnswers,
    TorsionAmplification,
    check_plan_law,
    pair_answers,
    plan_design_answers,
    plot_orbit,
    resolve_pairs,
    suite_value,
)
from tests._plan_fake import FakePair, decoupled, pair_from

finite = st.floats(-0.5, 0.5, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(arrays(float, st.tuples(st.integers(1, 40), st.just(2)), elements=finite))
def test_the_plan_displacement_is_never_below_either_component(u):
    a = pair_answers(u, np.zeros_like(u))
    assert a["plan_disp_max_m"] >= a["disp_x_max_m"] - 1e-15
    assert a["plan_disp_max_m"] >= a["disp_y_max_m"] - 1e-15
    assert a["plan_disp_max_m"] <= math.hypot(a["disp_x_max_m"], a["disp_y_max_m"]) + 1e-15
    assert a["total_max_disp_m"] == a["plan_disp_max_m"]  # no torsion: the centre's displacement


def test_the_plan_displacement_on_an_axis_a_diagonal_and_a_circle():
    t = np.linspace(0.0, 4.0 * np.pi, 801)
    r = 0.2
    along_x = np.column_stack([r * np.sin(t), 0.0 * t])
    assert pair_answers(along_x, along_x)["plan_disp_max_m"] == pytest.approx(r, rel=1e-12)
    diagonal = np.column_stack([r * np.sin(t), r * np.sin(t)])
    assert pair_answers(diagonal, diagonal)["plan_disp_max_m"] == pytest.approx(math.sqrt(2) * r, rel=1e-6)
    circle = np.column_stack([r * np.cos(t), r * np.sin(t)])
    a = pair_answers(circle, 3.0 * circle)
    assert a["plan_disp_max_m"] == pytest.approx(r, rel=1e-12)
    assert a["disp_x_max_m"] == pytest.approx(r, rel=1e-12)
    assert a["base_shear_y_max_kN"] == pytest.approx(3.0 * r, rel=1e-5)


def test_six_pairs_take_the_maximum_and_seven_the_average():
    six = [0.10, 0.12, 0.30, 0.11, 0.09, 0.13]
    assert suite_value(six) == pytest.approx(0.30)
    seven = [*six, 0.15]
    assert suite_value(seven) == pytest.approx(np.mean(seven))
    assert suite_value([0.1, float("nan")]) != suite_value([0.1, float("nan")])  # a failed pair: NaN


def _answers(values: dict[str, list[float]]) -> PlanDesignAnswers:
    rows = []
    for bound, vals in values.items():
        for i, v in enumerate(vals):
            rows.append({"bound": bound, "lambda": {"nominal": 1.0, "lower": 0.85, "upper": 1.15}[bound],
                         "pair": f"p{i}", **{a: v for a in ANSWERS}})
    n = len(next(iter(values.values())))
    lambdas = {"nominal": 1.0, "lower": 0.85, "upper": 1.15}
    return PlanDesignAnswers(law="linear", building="b", pairs=tuple(f"p{i}" for i in range(n)),
                             per_pair=pd.DataFrame(rows), lambdas=lambdas,
                             rule="average" if n >= 7 else "maximum")


@pytest.mark.parametrize("n", [6, 7])
def test_the_design_value_per_bound_and_the_governing_one(n):
    rng = np.random.default_rng(n)
    vals = {b: list(rng.uniform(0.1, 0.3, n)) for b in ("nominal", "lower", "upper")}
    des = _answers(vals).design()
    rule = np.mean if n >= 7 else np.max
    for b in vals:
        assert des.loc[b, "plan_disp_max_m"] == pytest.approx(rule(vals[b]))
    governing = max(rule(v) for v in vals.values())  # the nominal one may exceed both bounds
    assert des.loc["governing", "plan_disp_max_m"] == pytest.approx(governing)
    table = _answers(vals).table()
    assert len(table) == 3 * n + 4
    assert table["pair"].iloc[-1] == f"design ({'average' if n >= 7 else 'maximum'} of {n})"


def test_the_corner_bearing_amplification_and_its_errors():
    tor = TorsionAmplification(y=3.5, b=6.0, d=7.0, e=0.35)
    assert tor.factor == pytest.approx(1 + 3.5 * 12 * 0.35 / (36 + 49))
    assert TorsionAmplification(y=0.0, b=6.0, d=7.0, e=0.35).factor == 1.0
    assert TorsionAmplification(y=3.5, b=6.0, d=7.0, e=0.35, p_t=2.0).factor == pytest.approx(
        1 + 3.5 / 4 * 12 * 0.35 / 85)
    u = np.array([[0.1, 0.0], [0.0, 0.2]])
    a = pair_answers(u, u, torsion=tor)
    assert a["total_max_disp_m"] == pytest.approx(0.2 * tor.factor)
    with pytest.raises(ValueError, match=r"torsion\.b = -1"):
        TorsionAmplification(y=1.0, b=-1.0, d=7.0, e=0.3)


# ----------------------------------------------------------------------------- the bounds
def _sdof(k: float = 2000.0) -> structures.ShearBuilding:
    """A nearly rigid one-story building (100 t) on a linear isolator of stiffness k [kN/m]."""
    return structures.ShearBuilding(
        story_masses=[50.0], story_stiffness=[1.0e7], story_heights=[3.0], damping_ratio=0.0,
        base_mass=50.0, isolator=structures.Isolator("linear", {"k": k, "c": 400.0}, 1, 1.0),
    )


def _push(a0: float = 1.0, dt: float = 0.02, seconds: float = 30.0) -> FakePair:
    """A quasi-static push: the ground acceleration ramps (smoothly) to a0 in 20 s and holds."""
    t = np.arange(0.0, seconds + dt / 2, dt)
    ramp = np.where(t < 20.0, 0.5 * (1 - np.cos(np.pi * t / 20.0)), 1.0)
    return FakePair("push", dt, np.column_stack([a0 * ramp, 0.5 * a0 * ramp]))


def test_the_bounds_bracket_the_nominal_under_a_quasi_static_push():
    bld = _sdof()
    ans = plan_design_answers(bld, [_push()], bounds=(0.85, 1.15), simulate=decoupled)
    per = ans.per_pair.set_index("bound")
    # static: u = M a / k, with M = 100 t and a = (1, 0.5) m/s^2 -> |u| = 100 * sqrt(1.25) / k
    static = 100.0 * math.sqrt(1.25) / 2000.0
    assert per.loc["nominal", "plan_disp_max_m"] == pytest.approx(static, rel=2e-3)
    assert per.loc["lower", "plan_disp_max_m"] == pytest.approx(static / 0.85, rel=2e-3)
    assert per.loc["upper", "plan_disp_max_m"] == pytest.approx(static / 1.15, rel=2e-3)
    assert per.loc["upper", "plan_disp_max_m"] < per.loc["nominal", "plan_disp_max_m"] < \
        per.loc["lower", "plan_disp_max_m"]
    # the base shear is the inertia force M a in both directions, whatever the stiffness
    for b in ("nominal", "lower", "upper"):
        assert per.loc[b, "base_shear_x_max_kN"] == pytest.approx(50.0, rel=2e-3)
        assert per.loc[b, "base_shear_y_max_kN"] == pytest.approx(25.0, rel=2e-3)
    assert ans.design_displacement == pytest.approx(per.loc["lower", "plan_disp_max_m"])
    assert ans.rule == "maximum" and any("fewer than the 7" in n for n in ans.notes)
    assert any("no torsion" in n for n in ans.notes)
    d = ans.to_dict()
    assert d["design"]["governing"]["plan_disp_max_m"] == pytest.approx(ans.design_displacement)
    assert set(ans.orbits) == {(b, "push") for b in ("nominal", "lower", "upper")}
    fig = plot_orbit(ans.orbits[("nominal", "push")], ans.design_displacement, title="push",
                     others={"lower bound": ans.orbits[("lower", "push")]})
    ax = fig.axes[0]
    assert ax.get_xlabel() == "isolator displacement x [m]"
    assert ax.get_ylabel() == "isolator displacement y [m]"


def test_a_property_modification_object_gives_its_envelope_lambdas():
    class PM:
        def law_lambdas(self):
            return 0.8, 1.3

    ans = plan_design_answers(_sdof(), [_push(seconds=22.0)], bounds=PM(), simulate=decoupled)
    assert dict(ans.lambdas) == {"nominal": 1.0, "lower": 0.8, "upper": 1.3}
    with pytest.raises(ValueError, match="lambda_min <= 1 <= lambda_max"):
        plan_design_answers(_sdof(), [_push(seconds=22.0)], bounds=(1.2, 1.3), simulate=decoupled)


# ----------------------------------------------------------------------------- errors
def test_a_record_with_one_component_is_refused_saying_how_to_give_two():
    rec = ground_motions.load("elcentro")
    with pytest.raises(ValueError, match="one component"):
        resolve_pairs([rec])
    with pytest.raises(ValueError, match=r"joined by '\+'"):
        resolve_pairs(["some/where/RSN1_A.AT2"])
    with pytest.raises(ValueError, match="unique"):
        p = FakePair("a", 0.01, np.zeros((5, 2)))
        resolve_pairs([p, p])


def test_a_law_without_a_plan_form_is_refused_listing_those_with_one():
    with pytest.raises(ValueError, match=r"no coupled bidirectional form.*linear"):
        check_plan_law("plasticity+rate")
    assert check_plan_law("linear") == "linear"


def test_the_decoupled_stand_in_is_the_plan_building_for_a_linear_isolator():
    """The quasi-static tests above use two 1-D histories; for a linear isolator that is exact up to
    the Newton stop test (on the norm over both directions in plan, per direction in 1-D: the
    iterates differ at the 1e-12 m tolerance, ~1e-9 relative on a small y base shear)."""
    bld = structures.ShearBuilding(
        story_masses=[40.0, 35.0], story_stiffness=[2.0e5, 1.5e5], story_heights=[3.0, 3.0],
        damping_ratio=0.05, base_mass=45.0,
        isolator=structures.Isolator("linear", {"k": 800.0, "c": 30.0}, 4, 2.0))
    pair = pair_from(ground_motions.load("kocaeli"), 5.0)
    real = plan_design_answers(bld, [pair], bounds=None)
    fake = plan_design_answers(bld, [pair], bounds=None, simulate=decoupled)
    for a in ANSWERS:
        assert real.per_pair[a].iloc[0] == pytest.approx(fake.per_pair[a].iloc[0], rel=1e-7), a
    assert real.notes[-1].startswith("nominal properties only")
