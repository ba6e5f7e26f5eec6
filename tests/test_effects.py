"""Effect kernels: neutral = base law exactly, dissipation, consistent tangents, signatures."""

import math

import numpy as np
import pytest
from _tangent import assert_tangent_is_the_derivative
from hypothesis import given, settings
from hypothesis import strategies as st

from rrfrei import simulate_force
from rrfrei.energy import cycle_metrics, dissipated_energy
from rrfrei.laws import get
from rrfrei.laws.effects import EFFECTS, SLIP_NEVER
from rrfrei.protocols import protocol

PL = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}
BW = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0, "eta": 1.0, "beta": 0.5,
      "gamma": 0.5}
T1, U1 = protocol(1)


def _neutral(name):
    spec = EFFECTS[name]
    return {p.name: v for p, v in zip(spec.params, spec.neutral)}


@pytest.mark.parametrize("base", [PL, BW], ids=["plasticity", "bouc_wen"])
@pytest.mark.parametrize("name", list(EFFECTS))
def test_effect_at_its_neutral_parameters_is_the_base_law_exactly(base, name):
    law = "plasticity" if base is PL else "bouc_wen"
    fb = simulate_force(law, base, U1, time=T1)
    fa = simulate_force(f"{law}+{name}", {**base, **_neutral(name)}, U1, time=T1)
    np.testing.assert_array_equal(fa, fb)


def test_all_effects_together_at_neutral_parameters_are_the_base_law_exactly():
    names = ["degradation", "mullins", "rate", "slip"]
    params = dict(PL)
    for n in names:
        params.update(_neutral(n))
    np.testing.assert_array_equal(simulate_force("plasticity+" + "+".join(names), params, U1, time=T1),
                                  simulate_force("plasticity", PL, U1, time=T1))


@settings(max_examples=15, deadline=None)
@given(name=st.sampled_from(["degradation", "mullins", "rate", "asymmetry", "slip"]),
       size=st.floats(0.05, 0.6))
def test_dissipative_effects_dissipate_nonnegative_energy_in_every_cycle(name, size):
    values = {"degradation": {"deg_rate": 30 * size}, "mullins": {"mullins": size, "mullins_shape": 1.0},
              "rate": {"rate_c": 20 * size}, "asymmetry": {"asym": size},
              "slip": {"slip_force": 0.7 + size}}[name]
    f = simulate_force(f"plasticity+{name}", {**PL, **values}, U1, time=T1)
    m = cycle_metrics(U1, f)
    assert len(m) == 12
    assert (m.energy >= -1e-12).all()


@pytest.mark.parametrize("name,values", [
    ("degradation", {"deg_rate": 5.0}), ("mullins", {"mullins": 0.3, "mullins_shape": 1.0}),
    ("mullins", {"mullins": 0.3, "mullins_shape": 2.5}), ("mullins", {"mullins": 0.3, "mullins_shape": 0.5}),
    ("rollover", {"roll_k": -20.0, "roll_onset": 0.01}), ("rate", {"rate_c": 5.0, "rate_exp": 0.7}),
    ("asymmetry", {"asym": 0.2}),
])
def test_tangent_is_the_derivative_of_the_force_within_a_step(name, values):
    """dF/du from the kernel equals a central difference of F about the trial point."""
    spec = get(f"plasticity+{name}")
    # commit a history first (loading to 25 mm, back to 5 mm) so history variables are active
    path = np.concatenate([np.linspace(0, 0.025, 60), np.linspace(0.025, 0.005, 40)])
    assert_tangent_is_the_derivative(spec, spec.pack({**PL, **values}), path, (0.006, 0.0265),
                                     h=1e-7, rel=1e-4)


def test_rollover_adds_the_closed_form_hinge_force():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+rollover", {**PL, "roll_k": -20.0, "roll_onset": 0.012}, U1)
    expected = -20.0 * np.sign(U1) * np.maximum(np.abs(U1) - 0.012, 0.0)
    np.testing.assert_allclose(f - fb, expected, atol=1e-12)


def test_asymmetry_scales_positive_and_negative_forces_by_one_plus_and_minus_a():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+asymmetry", {**PL, "asym": 0.2}, U1)
    np.testing.assert_allclose(f, fb * (1 + 0.2 * np.sign(fb)), atol=1e-12)


def test_degradation_fades_the_force_by_the_closed_form_of_cumulative_work():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+degradation", {**PL, "deg_rate": 5.0}, U1)
    w = dissipated_energy(U1, fb)  # independent trapezoid of the base force
    wmax = np.concatenate([[0.0], np.maximum.accumulate(np.maximum(w, 0.0))[:-1]])
    np.testing.assert_allclose(f, fb / (1 + 5.0 * wmax), rtol=1e-9, atol=1e-12)
    assert f[-300:].max() < 0.9 * fb[-300:].max()  # strength visibly faded by the end


@pytest.mark.parametrize("shape", [1.0, 2.0, 0.5, 5.0])
def test_mullins_softens_reloading_below_the_previous_maximum_only(shape):
    """g = 1 - m (1 - r^c), r = |u| / u_max below the previous maximum, 1 on virgin loading."""
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+mullins", {**PL, "mullins": 0.3, "mullins_shape": shape}, U1)
    umax_before = np.concatenate([[0.0], np.maximum.accumulate(np.abs(U1))[:-1]])
    virgin = np.abs(U1) >= umax_before
    np.testing.assert_array_equal(f[virgin], fb[virgin])
    g = 1 - 0.3 * (1 - (np.abs(U1[~virgin]) / umax_before[~virgin]) ** shape)
    np.testing.assert_allclose(f[~virgin], fb[~virgin] * g, rtol=1e-12)


def test_mullins_shape_decides_where_below_the_peak_the_bearing_is_softer():
    """Every shape softens by m at u = 0 and recovers at u_max; a larger exponent c keeps the
    reloading soft closer to the previous peak (energy-like deficit), a smaller one only near 0."""
    u = np.concatenate([np.linspace(0, 0.03, 301), np.linspace(0.03, 0.0, 301)[1:]])
    fb = simulate_force("plasticity", PL, u)
    back = np.arange(u.size) > 300
    ratio = {c: simulate_force("plasticity+mullins", {**PL, "mullins": 0.4, "mullins_shape": c}, u)[back]
             / fb[back] for c in (0.5, 1.0, 3.0)}
    mid = np.abs(u[back] - 0.015) < 1e-9
    assert ratio[0.5][mid] > ratio[1.0][mid] > ratio[3.0][mid]
    for c in ratio:
        assert ratio[c][-1] == pytest.approx(0.6)  # at u = 0: 1 - m
        assert ratio[c][0] == pytest.approx(1.0, abs=1e-2)


def test_rate_force_grows_with_loading_speed():
    """Faster cycles of the same amplitude dissipate more energy (viscous signature)."""
    energies = []
    for period in (40.0, 4.0):
        t = np.linspace(0, 2 * period, 801)
        u = 0.02 * np.sin(2 * np.pi * t / period)
        f = simulate_force("plasticity+rate", {**PL, "rate_c": 10.0}, u, time=t)
        energies.append(cycle_metrics(u, f).energy.iloc[-1])
    v_ratio = 10.0
    base = cycle_metrics(u, simulate_force("plasticity", PL, u, time=t)).energy.iloc[-1]
    # viscous part of the loop area pi c omega A^2 scales with the frequency
    assert (energies[1] - base) == pytest.approx(v_ratio * (energies[0] - base), rel=0.05)
    assert (energies[1] - base) == pytest.approx(math.pi * 10.0 * 2 * math.pi / 4.0 * 0.02**2, rel=0.05)


def test_slip_caps_the_force_and_agrees_with_an_independent_series_slider():
    from rrfrei.gap.validate import _slip

    fs = 1.1
    f = simulate_force("plasticity+slip", {**PL, "slip_force": fs}, U1)
    assert np.abs(f).max() <= fs + 1e-9
    assert np.abs(f).max() == pytest.approx(fs)
    p = np.array([PL[k] for k in ("k_init", "qd", "alpha1", "alpha2", "mu")])
    peer = _slip(U1, T1, p, fs, 1e6 * PL["k_init"])  # elastic-plastic slider, bisection
    np.testing.assert_allclose(f, peer, atol=2e-5)


def test_compose_rejects_unknown_and_repeated_effects():
    with pytest.raises(ValueError, match="unknown effect 'creep'"):
        get("plasticity+creep")
    with pytest.raises(ValueError, match="repeat"):
        get("plasticity+rate+rate")


def test_augmented_law_names_its_parameters_base_first_then_each_effect():
    spec = get("bouc_wen+rollover+rate")
    assert spec.param_names[:8] == get("bouc_wen").param_names
    assert spec.param_names[8:] == ("roll_k", "roll_onset", "roll_exp", "rate_c", "rate_exp", "rate_sat",
                                    "rate_rise", "rate_vsat")
    assert spec.free_names[-3:] == ("roll_k", "roll_onset", "rate_c")
    with pytest.raises(ValueError, match="alpha1"):
        spec.pack({**BW, "alpha1": 1.0, "roll_k": 0, "roll_onset": 0, "rate_c": 0})
    assert SLIP_NEVER == get("plasticity+slip").param("slip_force").upper
