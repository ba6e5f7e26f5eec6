"""A law is added in one place (issue 13.1).

``tests/_toy_law.py`` defines one law (a bilinear elastic spring with one state variable) with one
registry entry, and nothing else in the repository names it.  It then runs through every verb
that takes a law: ``simulate_force``, ``calibrate``, ``structures.time_history`` and
``structures.propagate``, with the closed-form force where there is one.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import _toy_law as toy
import numpy as np
import pandas as pd
import pytest

import ground_motions
import rrfrei
import structures
from rrfrei.calibration import ConvergenceWarning
from rrfrei.io import ShearTest
from rrfrei.protocols import protocol1
from structures import Isolator

ROOT = Path(__file__).resolve().parents[1]
P = {"k": 260.0, "r": 0.3, "d_b": 0.005}


def closed_form(u: np.ndarray, k: float, r: float, d_b: float) -> np.ndarray:
    a = np.abs(u)
    return np.where(a <= d_b, k * u, np.sign(u) * (k * d_b + r * k * (a - d_b)))


def test_the_toy_law_is_named_nowhere_but_its_module_and_this_test():
    mentions = [p for pkg in ("rrfrei", "structures", "rubber", "ground_motions", "benchmarks")
                for p in (ROOT / pkg).rglob("*.py") if toy.NAME in p.read_text()]
    assert mentions == []
    assert rrfrei.laws.get(toy.NAME) is toy.SPEC
    assert toy.NAME in rrfrei.laws.names()
    assert toy.NAME not in rrfrei.laws.OPENSEES_LAWS  # no OpenSees element: not compared


def test_simulate_force_runs_the_toy_law_and_gives_its_closed_form():
    t, u = protocol1()
    f, k = rrfrei.simulate_force(toy.NAME, P, u, return_tangent=True)
    np.testing.assert_allclose(f, closed_form(u, **P), rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(k, np.where(np.abs(u) <= P["d_b"], P["k"], P["r"] * P["k"]))
    # its robust local solve is a no-op (closed form), so the result is the same
    np.testing.assert_array_equal(rrfrei.simulate_force(toy.NAME, P, u, local_solver="robust"), f)


def test_an_effect_wraps_the_toy_law_like_any_other():
    t, u = protocol1()
    base = rrfrei.simulate_force(toy.NAME, P, u, time=t)
    neutral = rrfrei.simulate_force(f"{toy.NAME}+rate", {**P, "rate_c": 0.0}, u, time=t)
    np.testing.assert_array_equal(neutral, base)
    f = rrfrei.simulate_force(f"{toy.NAME}+asymmetry", {**P, "asym": 0.2}, u, time=t)
    np.testing.assert_allclose(f, base * (1 + 0.2 * np.sign(base)), atol=1e-12)


def test_calibrate_recovers_the_toy_stiffness_within_its_posterior():
    t, u = protocol1()
    t, u = t[:400], u[:400]
    rng = np.random.default_rng(0)
    test = ShearTest("toy", t, u, closed_form(u, **P) + 0.05 * rng.standard_normal(u.size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # a short chain
        cal = rrfrei.calibrate(test, toy.NAME, walkers=16, steps=60, seed=0, progress=False)
    assert cal.free == ("k",)
    k = cal.draws()["k"].to_numpy()
    lo, hi = np.quantile(k, [0.005, 0.995])
    assert lo < P["k"] < hi
    assert hi - lo < 0.05 * P["k"]  # and the posterior is informative


def _toy_building(law: str = toy.NAME, params=None) -> structures.ShearBuilding:
    b = structures.load_building("three_story")
    iso = Isolator(law, P if params is None else params, b.isolator.count, b.isolator.length_scale)
    return replace(b, isolator=iso)


def _record(seconds: float = 3.0) -> ground_motions.Record:
    r = ground_motions.load("elcentro")
    n = int(round(seconds / r.dt)) + 1
    return ground_motions.Record(r.name, r.dt, r.accel[:n], r.meta)


def test_time_history_runs_the_toy_law_and_its_isolator_force_is_the_closed_form():
    b = _toy_building()
    res = structures.time_history(b, _record())
    iso = b.isolator
    s, count = iso.length_scale, iso.count
    u_law = res.isolator_disp / s
    # similitude: the layer force is count s^2 times the law's force at u / s
    expected = count * s * s * closed_form(u_law, **P)
    np.testing.assert_allclose(res.isolator_force, expected, rtol=1e-12,
                               atol=1e-12 * np.abs(expected).max())
    assert np.abs(u_law).max() > P["d_b"]  # both branches were used
    assert abs(res.energy_error) < 5e-3


def test_propagate_runs_posterior_draws_of_the_toy_law_through_a_building():
    post = pd.DataFrame([[200.0, 0.3, 0.005], [260.0, 0.3, 0.005], [320.0, 0.3, 0.005]],
                        columns=list(toy.SPEC.param_names))
    post.attrs["law"] = toy.NAME
    rs = structures.propagate(post, _toy_building(), [_record()], n_samples=3, progress=False)
    assert rs.law == toy.NAME and len(rs.table) == 3 and rs.table["converged"].all()
    # every run is the time history of its draw (the same kernels, run in a batch)
    for _, row in rs.table.iterrows():
        params = rs.draws.loc[int(row["sample"])].to_dict()
        one = structures.time_history(_toy_building(params=params), _record())
        assert row["iso_disp_peak_m"] == pytest.approx(np.abs(one.isolator_disp).max(), rel=1e-12)


@pytest.mark.parametrize("robust", ["opensees", "robust"])
def test_time_history_batch_equals_single_runs_for_the_toy_law(robust):
    b = _toy_building()
    rows = np.array([[200.0, 0.3, 0.005], [320.0, 0.5, 0.004]])
    out = structures.time_history_batch(b, _record(), rows, local_solver=robust)
    for r, row in enumerate(rows):
        one = structures.time_history(_toy_building(params=dict(zip(toy.SPEC.param_names, row))), _record())
        assert out["iso_disp_peak"][r] == pytest.approx(np.abs(one.isolator_disp).max(), rel=1e-12)
