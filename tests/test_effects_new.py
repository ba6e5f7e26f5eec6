"""The effects real bearings show (issue 12 point 3): stiffening, pinching, scragging.

Each is the base law bit for bit at its neutral parameters, has its physical signature, composes
with the other effects and with ``slip``, and keeps its defining property on random histories.
"""

import numpy as np
import pytest
from _law_strategies import histories
from hypothesis import given, settings
from hypothesis import strategies as st

from rrfrei import simulate_force
from rrfrei.energy import cycle_metrics, dissipated_energy
from rrfrei.laws import get
from rrfrei.laws.effects import EFFECTS
from rrfrei.protocols import protocol

PL = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}
BW = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0, "eta": 1.0, "beta": 0.5,
      "gamma": 0.5}
T1, U1 = protocol(1)  # growing cycles to 30 mm

STIFF = {"stiff_k": 50.0, "stiff_onset": 0.01}
PINCH = {"pinch": 0.5, "pinch_width": 0.003}
SCRAG = {"scrag": 0.3, "scrag_disp": 0.01}
NEW = {"stiffening": STIFF, "pinching": PINCH, "scragging": SCRAG}


def _sine(amp: float, cycles: int = 3, n: int = 400) -> np.ndarray:
    return amp * np.sin(2 * np.pi * np.linspace(0.0, cycles, cycles * n + 1))


def _before(u: np.ndarray) -> np.ndarray:
    """Largest |u| committed before each sample (0 at the first)."""
    return np.concatenate([[0.0], np.maximum.accumulate(np.abs(u))[:-1]])


def test_the_three_effects_are_catalogue_candidates_after_the_six_earlier_ones():
    for name, order in (("stiffening", 7), ("pinching", 8), ("scragging", 9)):
        assert EFFECTS[name].hints.order == order
    assert get("plasticity+stiffening").param_names[-2:] == ("stiff_k", "stiff_onset")
    assert get("plasticity+pinching").param_names[-2:] == ("pinch", "pinch_width")
    assert get("plasticity+scragging").param_names[-2:] == ("scrag", "scrag_disp")
    assert get("plasticity+stiffening").param("stiff_k").lower == 0.0  # stiffening only


@pytest.mark.parametrize("base", ["plasticity", "bouc_wen"])
@pytest.mark.parametrize("name,zero", [
    ("stiffening", {"stiff_k": 0.0, "stiff_onset": 1e-4}),
    ("pinching", {"pinch": 0.0, "pinch_width": 1e-6}),
    ("scragging", {"scrag": 0.0, "scrag_disp": 1e-6}),
])
def test_a_zero_amplitude_is_the_base_law_bit_for_bit_whatever_its_length_scale(base, name, zero):
    values = PL if base == "plasticity" else BW
    fb = simulate_force(base, values, U1, time=T1)
    f = simulate_force(f"{base}+{name}", {**values, **zero}, U1, time=T1)
    assert np.array_equal(f, fb)


@pytest.mark.parametrize("name", list(NEW))
def test_tangent_is_the_derivative_of_the_force_within_a_step(name):
    spec = get(f"plasticity+{name}")
    p = spec.pack({**PL, **NEW[name]})
    sc = np.array(spec.initial_state, dtype=float)
    stt = sc.copy()
    path = np.concatenate([np.linspace(0, 0.025, 60), np.linspace(0.025, 0.002, 40)])
    for u in path:
        spec.step(p, sc, u, 0.0, 1.0, stt)
        sc[:] = stt
    # below the peak near zero (pinching band), beyond the onset, and on a new peak
    for u in (0.0015, 0.018, 0.0262):
        f, k, _ = spec.step(p, sc, u, 0.0, 1.0, stt.copy())
        h = 1e-8
        fp, _, _ = spec.step(p, sc, u + h, 0.0, 1.0, stt.copy())
        fm, _, _ = spec.step(p, sc, u - h, 0.0, 1.0, stt.copy())
        assert k == pytest.approx((fp - fm) / (2 * h), rel=1e-5, abs=1e-6)


# --- stiffening --------------------------------------------------------------------------------
def test_stiffening_adds_the_closed_form_quadratic_excess_force():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+stiffening", {**PL, **STIFF}, U1)
    ex = np.maximum(np.abs(U1) - 0.01, 0.0)
    np.testing.assert_allclose(f - fb, 50.0 * np.sign(U1) * ex**2 / (2 * 0.01), atol=1e-12)
    assert np.array_equal(f[np.abs(U1) <= 0.01], fb[np.abs(U1) <= 0.01])


def test_stiffening_raises_the_secant_stiffness_more_the_larger_the_amplitude_and_adds_no_energy():
    gain = []
    for amp in (0.008, 0.02, 0.04):
        u = _sine(amp)
        fb = simulate_force("plasticity", PL, u)
        f = simulate_force("plasticity+stiffening", {**PL, **STIFF}, u)
        mb, m = cycle_metrics(u, fb), cycle_metrics(u, f)
        gain.append(float(m.k_eff.iloc[-1] / mb.k_eff.iloc[-1]))
        # an elastic addition: the loop area of every cycle is unchanged
        np.testing.assert_allclose(m.energy, mb.energy, rtol=1e-9, atol=1e-12)
    assert gain[0] == pytest.approx(1.0, abs=1e-12)  # below the onset: nothing
    assert 1.0 < gain[1] < gain[2]


def test_stiffening_tangent_is_continuous_at_the_onset_unlike_rollover():
    _, k_s = simulate_force("plasticity+stiffening", {**PL, "stiff_k": 50.0, "stiff_onset": 0.01},
                            np.linspace(0, 0.03, 3001), return_tangent=True)
    _, k_r = simulate_force("plasticity+rollover", {**PL, "roll_k": -50.0, "roll_onset": 0.01},
                            np.linspace(0, 0.03, 3001), return_tangent=True)
    i = 1000  # u = 0.01 exactly: the onset
    assert abs(k_s[i + 2] - k_s[i - 2]) < 1.0  # the added tangent is 50 * 2e-5 / 0.01 = 0.1 kN/m
    assert k_r[i + 2] - k_r[i - 2] == pytest.approx(-50.0)  # rollover's kink (softening only)


def test_rollover_only_softens_stiffening_is_its_own_effect():
    with pytest.raises(ValueError, match="roll_k"):
        simulate_force("plasticity+rollover", {**PL, "roll_k": 50.0, "roll_onset": 0.01}, U1)


# --- pinching ----------------------------------------------------------------------------------
def test_pinching_scales_the_force_near_zero_by_the_closed_form_below_the_previous_peak():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+pinching", {**PL, **PINCH}, U1)
    um = _before(U1)
    below = np.abs(U1) < um
    g = 1 - 0.5 * (np.exp(-(U1 / 0.003) ** 2) - np.exp(-(um / 0.003) ** 2))
    np.testing.assert_allclose(f[below], fb[below] * g[below], rtol=1e-12, atol=1e-15)
    assert np.array_equal(f[~below], fb[~below])  # virgin loading is not pinched


def test_pinching_shrinks_the_loop_lowers_the_force_near_zero_and_the_loop_still_closes():
    u = _sine(0.02, cycles=4)
    fb = simulate_force("plasticity", PL, u)
    f = simulate_force("plasticity+pinching", {**PL, **PINCH}, u)
    mb, m = cycle_metrics(u, fb), cycle_metrics(u, f)
    assert (m.energy.iloc[1:] < 0.95 * mb.energy.iloc[1:]).all()  # about 10 % smaller here
    near = (np.abs(u) < 0.001) & (np.arange(u.size) > 400)  # crossings of zero after the first cycle
    assert near.any()
    assert (np.abs(f[near]) < 0.7 * np.abs(fb[near])).all()
    assert (np.sign(f[near]) == np.sign(fb[near])).all()
    # steady cycles at one amplitude repeat: the loop closes
    n = 400
    np.testing.assert_allclose(f[2 * n:3 * n + 1], f[3 * n:4 * n + 1], atol=1e-12)
    assert np.max(np.abs(np.diff(f))) < 2 * np.max(np.abs(np.diff(fb)))  # no jump in the force


# --- scragging ---------------------------------------------------------------------------------
def test_scragging_softens_by_the_closed_form_of_the_peak_including_virgin_loading():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+scragging", {**PL, **SCRAG}, U1)
    um = np.maximum.accumulate(np.abs(U1))
    np.testing.assert_allclose(f, fb * (1 - 0.3 * (1 - np.exp(-um / 0.01))), rtol=1e-12, atol=1e-15)
    virgin = np.abs(U1) >= _before(U1)
    late = virgin & (np.abs(U1) > 0.02)
    assert (np.abs(f[late]) < 0.85 * np.abs(fb[late])).all()  # unlike mullins, virgin is softer
    fm = simulate_force("plasticity+mullins", {**PL, "mullins": 0.3}, U1)
    assert np.array_equal(fm[virgin], fb[virgin])


def test_scragging_does_not_soften_before_any_displacement():
    """A virgin bearing starts on the base law: same force and tangent at rest, and a softening
    that grows from nothing with the first displacement (g = 1 - s u / u_c to first order)."""
    u = np.linspace(0.0, 1e-5, 11)
    fb, kb = simulate_force("plasticity", PL, u, return_tangent=True)
    f, k = simulate_force("plasticity+scragging", {**PL, **SCRAG}, u, return_tangent=True)
    assert f[0] == fb[0] == 0.0 and k[0] == kb[0]
    np.testing.assert_allclose(f[1:] / fb[1:], 1 - 0.3 * u[1:] / 0.01, rtol=1e-6)


def test_a_second_test_on_a_scragged_bearing_is_softer_than_on_a_virgin_one():
    u = _sine(0.02, cycles=2)
    virgin = simulate_force("plasticity+scragging", {**PL, **SCRAG}, u)
    both = simulate_force("plasticity+scragging", {**PL, **SCRAG}, np.concatenate([_sine(0.04, 1), u]))
    second = both[-u.size:]
    k_virgin = cycle_metrics(u, virgin).k_eff.to_numpy()
    k_second = cycle_metrics(u, second).k_eff.to_numpy()
    assert (k_second < 0.97 * k_virgin).all()
    # the base law alone carries nothing of the kind over (it is back on the same loop)
    b1 = simulate_force("plasticity", PL, u)
    b2 = simulate_force("plasticity", PL, np.concatenate([_sine(0.04, 1), u]))[-u.size:]
    np.testing.assert_allclose(cycle_metrics(u, b2).k_eff.iloc[-1], cycle_metrics(u, b1).k_eff.iloc[-1],
                               rtol=1e-9)


# --- composition -------------------------------------------------------------------------------
def test_scaling_effects_compose_as_a_product_in_either_order_with_degradation():
    fb = simulate_force("plasticity", PL, U1)
    a = simulate_force("plasticity+scragging+pinching+degradation", {**PL, **SCRAG, **PINCH,
                                                                      "deg_rate": 5.0}, U1)
    b = simulate_force("plasticity+degradation+pinching+scragging", {**PL, **SCRAG, **PINCH,
                                                                      "deg_rate": 5.0}, U1)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    um, ub = np.maximum.accumulate(np.abs(U1)), _before(U1)
    g_s = 1 - 0.3 * (1 - np.exp(-um / 0.01))
    g_p = np.where(np.abs(U1) < ub, 1 - 0.5 * (np.exp(-(U1 / 0.003) ** 2) - np.exp(-(ub / 0.003) ** 2)), 1)
    w = dissipated_energy(U1, fb)
    g_d = 1 / (1 + 5.0 * np.concatenate([[0.0], np.maximum.accumulate(np.maximum(w, 0.0))[:-1]]))
    np.testing.assert_allclose(a, fb * g_s * g_p * g_d, rtol=1e-9, atol=1e-12)


def test_stiffening_composes_with_scaling_effects_and_with_slip():
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+scragging+stiffening", {**PL, **SCRAG, **STIFF}, U1)
    um = np.maximum.accumulate(np.abs(U1))
    ex = np.maximum(np.abs(U1) - 0.01, 0.0)
    expected = fb * (1 - 0.3 * (1 - np.exp(-um / 0.01))) + 50.0 * np.sign(U1) * ex**2 / 0.02
    np.testing.assert_allclose(f, expected, rtol=1e-12, atol=1e-12)
    # in series with a slider: capped at the capacity, and the slider never reached is nothing
    names = "plasticity+stiffening+pinching+scragging+slip"
    vals = {**PL, **STIFF, **PINCH, **SCRAG}
    capped = simulate_force(names, {**vals, "slip_force": 1.0}, U1)
    assert np.abs(capped).max() == pytest.approx(1.0)
    free = simulate_force(names, {**vals, "slip_force": 1e6}, U1)
    assert np.array_equal(free, simulate_force("plasticity+stiffening+pinching+scragging", vals, U1))


# --- properties on random histories ------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(u=histories(min_size=5, max_size=60), s=st.floats(0.0, 0.9), uc=st.floats(1e-3, 0.05),
       p=st.floats(0.0, 0.9), w=st.floats(1e-3, 0.05), k=st.floats(0.0, 500.0),
       onset=st.floats(1e-3, 0.05))
def test_properties_on_random_histories(u, s, uc, p, w, k, onset):
    """Scragging and pinching only ever shrink the force, never flip it; scragging's factor never
    recovers; stiffening adds a path-independent force of the sign of u."""
    fb = simulate_force("plasticity", PL, u)
    fs = simulate_force("plasticity+scragging", {**PL, "scrag": s, "scrag_disp": uc}, u)
    fp = simulate_force("plasticity+pinching", {**PL, "pinch": p, "pinch_width": w}, u)
    fk = simulate_force("plasticity+stiffening", {**PL, "stiff_k": k, "stiff_onset": onset}, u)
    for f, floor in ((fs, 1 - s), (fp, 1 - p)):
        assert (np.abs(f) <= np.abs(fb) + 1e-12).all()
        assert (np.abs(f) >= floor * np.abs(fb) - 1e-12).all()
        assert (f * fb >= 0).all()
    nz = np.abs(fb) > 1e-9
    g = fs[nz] / fb[nz]
    assert (np.diff(g) <= 1e-12).all()
    add = fk - fb
    assert (add * np.sign(u) >= -1e-12).all()
    np.testing.assert_allclose(add, k * np.sign(u) * np.maximum(np.abs(u) - onset, 0.0) ** 2
                               / (2 * onset), rtol=1e-9, atol=1e-9)
