"""Shear buildings on isolators: models, modal analysis, linear exactness, energy, robustness.

* a linear building is Newmark applied mode by mode (to the Newton tolerance), and converges to
  the exact modal solution (Nigam-Jennings per mode) at second order in dt;
* the energy put in by the ground equals kinetic + viscous + isolator work + story strain energy
  for every law on every bundled record (< 0.5 %), and a numerically dissipative Newmark shows up
  as an imbalance;
* a Newton failure is healed by subdivision (and says so) or raises naming record and time;
* the batch kernel returns the single-run peaks;
* bad input is refused with an error naming the field.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from opensees_dynamic import SPECIMEN_PARAMS

import ground_motions
import structures
from structures import Isolator, ShearBuilding


def first_seconds(name: str, seconds: float) -> ground_motions.Record:
    r = ground_motions.load(name)
    n = int(round(seconds / r.dt)) + 1
    return ground_motions.Record(r.name, r.dt, r.accel[:n], r.meta)


def on_law(building_name: str, law: str, params=None, **changes) -> ShearBuilding:
    b = structures.load_building(building_name)
    iso = Isolator(law, SPECIMEN_PARAMS[law] if params is None else params, b.isolator.count,
                   b.isolator.length_scale)
    return replace(b, isolator=iso, **changes)


# ------------------------------------------------------------------------------------ models
def test_bundled_buildings_load_and_are_prototype_scale_rr_frei():
    assert set(structures.available_buildings()) >= {"three_story", "five_story"}
    for name in ("three_story", "five_story"):
        b = structures.load_building(name)
        assert b.name == name and b.isolator.length_scale == 3.0 and b.isolator.params is not None
        # each bearing carries about its design vertical load, 3^2 x 19.25 kN
        per_bearing = b.total_mass * 9.80665 / b.isolator.count
        assert 0.9 * 173.25 < per_bearing < 1.1 * 173.25
        assert 0.8 < b.isolated_period() < 1.2 < b.isolated_period(0.1) < 2.0
    with pytest.raises(ValueError, match="unknown building 'nope'"):
        structures.load_building("nope")


def test_fixed_base_periods_of_a_uniform_chain_are_the_closed_form():
    """n equal stories: w_j = 2 sqrt(k/m) sin((2j-1) pi / (2(2n+1)))."""
    n, m, k = 5, 30.0, 1.0e5
    b = ShearBuilding([m] * n, [k] * n, [3.0] * n, 0.05, 40.0, Isolator("linear", {"k": 1e3}))
    periods, phi = b.fixed_base_modes()
    j = np.arange(1, n + 1)
    w = 2.0 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    np.testing.assert_allclose(periods, 2 * np.pi / w, rtol=1e-12)
    np.testing.assert_allclose(phi.T @ np.diag([m] * n) @ phi, np.eye(n), atol=1e-12)


def test_isolated_period_uses_the_similitude_stiffness_and_the_cyclic_secant():
    """Linear layer: k = count s k_law; rigid superstructure: T = 2 pi sqrt(M / k).  Plasticity at
    amplitude d: k_eff = count s^2 qd / d + count s alpha1 k_init (closed form)."""
    count, s = 7, 3.0
    rigid = ShearBuilding([20.0, 20.0], [1e12, 1e12], [3.0, 3.0], 0.05, 30.0,
                          Isolator("linear", {"k": 100.0}, count, s))
    # eigh's relative accuracy is about eps x (k_story / k_iso) = 2e-16 x 5e8 = 1e-7
    assert rigid.isolated_period() == pytest.approx(2 * np.pi * np.sqrt(70.0 / (count * s * 100.0)), rel=1e-6)
    p = SPECIMEN_PARAMS["plasticity"]
    iso = Isolator("plasticity", p, count, s)
    d = 0.12
    expected = count * s * s * p["qd"] / d + count * s * p["alpha1"] * p["k_init"]
    assert iso.effective_stiffness(d) == pytest.approx(expected, rel=1e-12)
    assert iso.initial_stiffness() == pytest.approx(count * s * p["k_init"], rel=1e-12)


def test_toml_round_trip_and_missing_isolator_params(tmp_path: Path):
    text = """
story_masses = [10.0, 12.0]
story_stiffness = [5e4, 4e4]
story_heights = [3.0, 2.8]
damping_ratio = 0.02
base_mass = 15.0
[isolator]
law = "bouc_wen"
count = 4
length_scale = 2.0
"""
    path = tmp_path / "two.toml"
    path.write_text(text)
    b = ShearBuilding.from_toml(path)
    assert b.name == "two" and b.isolator.params is None and b.isolator.count == 4
    rec = first_seconds("elcentro", 1.0)
    with pytest.raises(ValueError, match="has no parameters"):
        structures.time_history(b, rec)
    full = b.with_isolator_params(SPECIMEN_PARAMS["bouc_wen"])
    again = ShearBuilding.from_toml(path, isolator_params=SPECIMEN_PARAMS["bouc_wen"])
    assert full == again
    assert structures.time_history(full, rec).time.size == rec.npts
    path.write_text("colour = 'red'\n" + text)
    with pytest.raises(ValueError, match="unknown key.*colour"):
        ShearBuilding.from_toml(path)


BASE = dict(story_masses=[10.0, 10.0], story_stiffness=[1e4, 1e4], story_heights=[3.0, 3.0],
            damping_ratio=0.05, base_mass=10.0)


@pytest.mark.parametrize(
    "change, field",
    [
        ({"story_masses": [10.0, -1.0]}, r"story_masses\[1\] = -1"),
        ({"story_stiffness": [1e4, 0.0]}, r"story_stiffness\[1\] = 0"),
        ({"story_heights": [3.0, float("nan")]}, r"story_heights\[1\]"),
        ({"story_masses": [10.0, 10.0, 10.0]}, "same length"),
        ({"base_mass": -5.0}, "base_mass = -5"),
        ({"damping_ratio": 1.5}, "damping_ratio = 1.5"),
        ({"damping": "modal"}, "damping = 'modal'"),
    ],
)
def test_bad_building_input_is_refused_naming_the_field(change, field):
    kw = {**BASE, **change}
    with pytest.raises(ValueError, match=field):
        ShearBuilding(isolator=Isolator("linear", {"k": 1e3}), **kw)


def test_bad_isolator_input_is_refused_naming_the_field():
    with pytest.raises(ValueError, match="unknown law 'lead_rubber'"):
        Isolator("lead_rubber", {})
    with pytest.raises(ValueError, match="qd = -1"):
        Isolator("plasticity", {**SPECIMEN_PARAMS["plasticity"], "qd": -1.0})
    with pytest.raises(ValueError, match="count = 0"):
        Isolator("linear", {"k": 1.0}, count=0)
    with pytest.raises(ValueError, match="length_scale"):
        Isolator("linear", {"k": 1.0}, length_scale=-3.0)


def test_bad_records_and_options_are_refused():
    b = structures.load_building("three_story")
    with pytest.raises(ValueError, match=r"accel\[2\] = nan"):
        ground_motions.Record("bad", 0.01, [0.0, 0.1, np.nan, 0.0])

    class Duck:  # a record-like object that skipped Record's validation
        name, dt, accel = "duck", 0.01, np.array([0.0, 0.1, np.inf, 0.0])

    with pytest.raises(ValueError, match=r"record 'duck': accel\[2\] = inf \(t = 0.02 s\) is not finite"):
        structures.time_history(b, Duck())
    rec = first_seconds("elcentro", 1.0)
    with pytest.raises(ValueError, match="dt = 0.02 is invalid"):
        structures.time_history(b, rec, dt=0.02)
    with pytest.raises(ValueError, match="beta = 0"):
        structures.time_history(b, rec, beta=0.0)
    with pytest.raises(ValueError, match="params row 1: .*qd"):
        p = np.tile(b.isolator.packed(), (2, 1))
        p[1, 1] = -1.0
        structures.time_history_batch(b, rec, p)


# ---------------------------------------------------------------------------- linear exactness
def linear_building(zeta: float = 0.05) -> tuple[ShearBuilding, float]:
    """Three stories on a linear layer whose dashpot makes C = a1 K (classical damping)."""
    b = structures.load_building("three_story")
    w1 = 2 * np.pi / b.fixed_base_modes()[0][0]
    a1 = 2 * zeta / w1  # the story dashpots are a1 k_i; the layer gets a1 k too
    k = 300.0
    b = replace(b, damping_ratio=zeta, isolator=Isolator("linear", {"k": k, "c": a1 * k},
                                                         b.isolator.count, b.isolator.length_scale))
    return b, a1


def modes(b: ShearBuilding, a1: float):
    iso = b.isolator
    m = np.array([b.base_mass, *b.story_masses])
    ks = np.array(b.story_stiffness)
    n = m.size
    K = np.zeros((n, n))
    K[0, 0] = iso.count * iso.length_scale * iso.params["k"]
    for i in range(1, n):
        K[np.ix_([i - 1, i], [i - 1, i])] += ks[i - 1] * np.array([[1, -1], [-1, 1]])
    w2, phi = scipy.linalg.eigh(K, np.diag(m))
    w = np.sqrt(w2)
    return w, phi, phi.T @ m, a1 * w / 2  # frequencies, shapes, participation, modal damping


def newmark_sdof(w, z, ag, dt, gamma=0.5, beta=0.25):
    """Linear Newmark for q'' + 2 z w q' + w^2 q = -ag, from rest with a_0 = -ag_0."""
    u = np.zeros(ag.size)
    v = 0.0
    a = -ag[0]
    keff = w * w + gamma / (beta * dt) * 2 * z * w + 1 / (beta * dt * dt)
    for k in range(1, ag.size):
        p = (-ag[k] + (u[k - 1] / (beta * dt * dt) + v / (beta * dt) + (1 / (2 * beta) - 1) * a)
             + 2 * z * w * (gamma / (beta * dt) * u[k - 1] + (gamma / beta - 1) * v
                            + dt * (gamma / (2 * beta) - 1) * a))
        u[k] = p / keff
        a_new = (u[k] - u[k - 1]) / (beta * dt * dt) - v / (beta * dt) - (1 / (2 * beta) - 1) * a
        v = v + dt * ((1 - gamma) * a + gamma * a_new)
        a = a_new
    return u


def test_linear_building_is_newmark_applied_mode_by_mode():
    b, a1 = linear_building()
    rec = first_seconds("elcentro", 8.0)
    w, phi, gam, zeta = modes(b, a1)
    u = sum(np.outer(newmark_sdof(w[j], zeta[j], gam[j] * rec.accel, rec.dt), phi[:, j])
            for j in range(w.size))
    r = structures.time_history(b, rec)
    np.testing.assert_allclose(r.isolator_disp, u[:, 0], rtol=0, atol=1e-9 * np.abs(u[:, 0]).max())
    np.testing.assert_allclose(r.floor_disp, u[:, 1:], rtol=0, atol=1e-9 * np.abs(u[:, 1:]).max())


def test_linear_building_converges_to_the_exact_modal_solution_at_second_order():
    """Exact: modal superposition of the piecewise-linear SDOF solutions (Nigam-Jennings,
    ``ground_motions.sdof_response``).  Newmark's period error is O(dt^2), so halving dt
    divides the error by about 4."""
    b, a1 = linear_building()
    rec = first_seconds("elcentro", 8.0)
    w, phi, gam, zeta = modes(b, a1)
    exact = sum(gam[j] * phi[0, j] * ground_motions.sdof_response(rec, 2 * np.pi / w[j], zeta[j])[0]
                for j in range(w.size))
    errors = []
    for f in (2, 4, 8):
        r = structures.time_history(b, rec, dt=rec.dt / f)
        errors.append(np.max(np.abs(r.isolator_disp[::f] - exact)) / np.max(np.abs(exact)))
    assert errors[-1] < 1e-3
    for coarse, fine in zip(errors, errors[1:]):
        assert 3.5 < coarse / fine < 4.5


def test_a_finer_step_interpolates_the_record_linearly():
    b = structures.load_building("three_story")
    rec = first_seconds("elcentro", 4.0)
    a = structures.time_history(b, rec, dt=rec.dt / 3)
    c = structures.time_history(b, rec.resampled(rec.dt / 3))
    np.testing.assert_array_equal(a.isolator_disp, c.isolator_disp)
    assert a.time[-1] == pytest.approx(rec.duration)


# ------------------------------------------------------------------------------------- energy
LAWS = ("linear", "plasticity", "bouc_wen", "elastomeric_x", "hdr")
SPECIMEN_LINEAR = {"k": 200.0, "c": 0.5}


@pytest.mark.parametrize("law", LAWS)
def test_energy_balances_within_half_a_percent_on_every_bundled_record(law):
    params = SPECIMEN_LINEAR if law == "linear" else None
    b = on_law("five_story", law, params=params)
    for name in ground_motions.available():
        rec = ground_motions.load(name)  # the first value is not zero: a_0 = -a_g(0) is solved
        r = structures.time_history(b, rec, dt=min(rec.dt, 0.01))
        assert r.energy_error < 5e-3, (name, r.energy_error)
        assert r.energy_error == pytest.approx(structures.dynamics.energy.balance_error(r.energy),
                                               rel=1e-9, abs=1e-15)
        e = r.energy
        assert np.all(np.diff(e["viscous"]) >= -1e-12 * e["input"].max())  # dashpots only dissipate
        assert e["isolator"][-1] > 0.0 and e["input"].max() > 0.0


def test_a_numerically_dissipative_newmark_shows_as_an_energy_imbalance():
    """gamma > 1/2 damps the response numerically; the balance must notice (else it checks nothing)."""
    b = on_law("three_story", "bouc_wen")
    rec = ground_motions.load("sanfernando")
    exact = structures.time_history(b, rec)
    damped = structures.time_history(b, rec, gamma=0.7, beta=0.36)
    assert exact.energy_error < 1e-9
    assert damped.energy_error > 5e-3


@settings(max_examples=15, deadline=None)
@given(qd=st.floats(0.3, 3.0), alpha1=st.floats(0.05, 0.8), scale=st.floats(0.3, 3.0))
def test_energy_balance_holds_for_any_plasticity_layer_and_intensity(qd, alpha1, scale):
    params = {**SPECIMEN_PARAMS["plasticity"], "qd": qd, "alpha1": alpha1}
    b = on_law("three_story", "plasticity", params=params)
    r = structures.time_history(b, first_seconds("elcentro", 6.0).scaled(scale))
    assert r.energy_error < 1e-6
    assert r.energy["isolator"][-1] >= 0.0


# ---------------------------------------------------------------------- robustness and batch
def test_a_failed_newton_step_is_subdivided_and_reported():
    b = on_law("three_story", "bouc_wen")
    rec = first_seconds("sanfernando", 10.0)
    ref = structures.time_history(b, rec)
    tight = structures.time_history(b, rec, max_iter=3)
    assert tight.subdivided_steps.size > 0
    assert tight.energy_error < 5e-3
    assert np.max(np.abs(tight.isolator_disp - ref.isolator_disp)) < 0.01 * np.max(np.abs(ref.isolator_disp))


def test_a_step_that_fails_at_every_subdivision_raises_naming_record_and_time():
    b = on_law("three_story", "bouc_wen")
    rec = first_seconds("sanfernando", 10.0)
    with pytest.raises(structures.ConvergenceError, match=r"record 'sanfernando': the step to t = .* s"):
        structures.time_history(b, rec, max_iter=1, max_subdivisions=1)


def test_batch_returns_the_peaks_of_single_runs_and_flags_failures():
    b = on_law("five_story", "bouc_wen")
    rec = first_seconds("sanfernando", 8.0)
    rng = np.random.default_rng(3)
    base = b.isolator.packed()
    P = np.tile(base, (5, 1))
    P[:, 1] *= rng.uniform(0.7, 1.3, 5)  # qd
    P[:, 2] = rng.uniform(0.2, 0.5, 5)  # alpha1
    out = structures.time_history_batch(b, rec, P, n_blocks=3)
    assert out["converged"].all()
    for i in range(5):
        r = structures.time_history(b.with_isolator_params(P[i]), rec)
        s = r.summary()
        assert out["iso_disp_peak"][i] == pytest.approx(s["isolator_disp_peak"], rel=1e-13)
        assert out["iso_disp_residual"][i] == pytest.approx(s["isolator_disp_residual"], rel=1e-13)
        assert out["base_shear_peak"][i] == pytest.approx(s["base_shear_peak"], rel=1e-13)
        assert out["iso_energy"][i] == pytest.approx(s["isolator_work"], rel=1e-13)
        assert out["energy_error"][i] == pytest.approx(r.energy_error, rel=1e-6, abs=1e-15)
        np.testing.assert_allclose(out["drift_peak"][i], np.abs(r.drift_ratio).max(axis=0), rtol=1e-13)
        np.testing.assert_allclose(out["floor_acc_peak"][i], np.abs(r.floor_accel_abs).max(axis=0),
                                   rtol=1e-13)
    failed = structures.time_history_batch(b, rec, P[:2], max_iter=1, max_subdivisions=0)
    assert not failed["converged"].any() and np.isnan(failed["iso_disp_peak"]).all()


def test_an_augmented_law_with_neutral_effect_is_its_base_law_and_a_real_effect_matters():
    """Augmented laws run through their own step instance (rrfrei.laws.effects) inside Newmark."""
    rec = first_seconds("sanfernando", 6.0)
    base = structures.time_history(on_law("three_story", "bouc_wen"), rec)
    params = {**SPECIMEN_PARAMS["bouc_wen"], "deg_rate": 0.0}
    neutral = on_law("three_story", "bouc_wen+degradation", params=params)
    same = structures.time_history(neutral, rec)
    np.testing.assert_allclose(same.isolator_disp, base.isolator_disp, rtol=0,
                               atol=1e-12 * np.abs(base.isolator_disp).max())
    degrading = neutral.with_isolator_params({**SPECIMEN_PARAMS["bouc_wen"], "deg_rate": 5.0})
    other = structures.time_history(degrading, rec)
    assert np.abs(other.isolator_disp - base.isolator_disp).max() > 1e-3 * np.abs(base.isolator_disp).max()
    assert other.energy_error < 5e-3


@settings(max_examples=8, deadline=None)
@given(law=st.sampled_from(("plasticity", "bouc_wen", "elastomeric_x", "hdr")), scale=st.floats(0.2, 2.0))
def test_reversing_the_ground_motion_reverses_the_response(law, scale):
    """The laws are odd from a virgin state and the chain is linear: u(-a_g) = -u(a_g)."""
    b = on_law("three_story", law)
    rec = first_seconds("elcentro", 5.0).scaled(scale)
    up = structures.time_history(b, rec)
    down = structures.time_history(b, rec.scaled(-1.0))
    top = np.abs(up.isolator_disp).max()
    np.testing.assert_allclose(down.isolator_disp, -up.isolator_disp, rtol=0, atol=1e-12 * top)
    np.testing.assert_allclose(down.floor_accel_abs, -up.floor_accel_abs, rtol=0,
                               atol=1e-12 * np.abs(up.floor_accel_abs).max())
