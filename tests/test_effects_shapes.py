"""Shape parameters of the effects (issue 12 point 4: kernels physically broader than one shape)
and the series slack element of ``pinching``.

Each shape parameter's default is the former kernel bit for bit; each new shape has its closed
form, a tangent consistent with its force, and its physical fact; the slack element agrees with an
independent series solve (bisection) and a fit recovers its own parameters.
"""

import math

import numpy as np
import pytest
from _tangent import assert_tangent_is_the_derivative

from rrfrei import simulate_force
from rrfrei.energy import cycle_metrics, dissipated_energy
from rrfrei.laws import get
from rrfrei.protocols import protocol

PL = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}
BW = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0, "eta": 1.0, "beta": 0.5,
      "gamma": 0.5}
T1, U1 = protocol(1)  # growing cycles to 30 mm
NO_BAND = {"pinch": 0.0, "pinch_width": 0.5, "pinch_angle": 0.0}


def one_step(name, values, u, v, dt=0.05):
    """(force [kN], tangent [kN/m]) of one step of ``name`` from its virgin state at displacement
    u [m] and velocity v [m/s] (the step's status asserted 0)."""
    spec = get(name)
    p = spec.pack(values)
    sc = np.array(spec.initial_state, dtype=float)
    f, k, status = spec.step(p, sc, u, v, dt, sc.copy())
    assert status == 0
    return f, k


def _step_force(name, values, u, v, dt=0.05):
    """Force of one step of ``name`` from its virgin state at displacement u and velocity v."""
    return one_step(name, values, u, v, dt)[0]


# --- defaults are the former kernels ---------------------------------------------------------------
# bouc_wen in the slow tier: each case compiles a kernel of its own (2-6 s of CPU cold); plasticity
# shows the same wrapper property in the default tier
@pytest.mark.parametrize("base", ["plasticity", pytest.param("bouc_wen", marks=pytest.mark.slow)])
@pytest.mark.parametrize("name,former,default", [
    ("degradation", {"deg_rate": 5.0}, {"deg_travel": 0.0}),
    ("rate", {"rate_c": 3.0, "rate_exp": 0.6}, {"rate_sat": 0.0}),
    ("stiffening", {"stiff_k": 40.0, "stiff_onset": 0.01}, {"stiff_exp": 2.0}),
    ("pinching", {"pinch": 0.5, "pinch_width": 0.4, "pinch_angle": 0.3},
     {"slack_gap": 0.0, "slack_force": 0.05}),
    # the breadth parameters of 2026-11-27 (tests/test_effects_breadth.py has their physics)
    ("slip", {"slip_force": 1.1}, {"slip_stick": 0.0}),
    ("slip", {"slip_force": 1.1, "slip_stick": 0.002}, {"slip_static": 1.0, "slip_dc": 0.004}),
    ("rate", {"rate_c": 3.0, "rate_exp": 0.6, "rate_sat": 20.0}, {"rate_rise": 0.0}),
    ("rate", {"rate_c": 3.0}, {"rate_rise": 0.0, "rate_vsat": 0.003}),
    ("degradation", {"deg_rate": 5.0, "deg_travel": 0.3}, {"deg_exp": 1.0}),
    # the smooth rollover of the diagnosis's variants (2026-11-27)
    ("rollover", {"roll_k": -20.0, "roll_onset": 0.01}, {"roll_exp": 1.0}),
    ("pinching", {"pinch": 0.5, "pinch_width": 0.6, "pinch_angle": 0.4}, {"pinch_line": 0.0}),
    ("pinching", {"pinch": 0.5, "pinch_width": 0.6, "pinch_angle": 0.4, "pinch_line": 0.7},
     {"pinch_slope": 30.0, "pinch_force": 0.0}),
    ("scragging", {"scrag": 0.3, "scrag_disp": 0.01}, {"scrag_shape": 1.0}),
])
def test_a_shape_parameter_at_its_default_is_the_former_kernel_bit_for_bit(base, name, former, default):
    values = PL if base == "plasticity" else BW
    implicit = simulate_force(f"{base}+{name}", {**values, **former}, U1, time=T1)
    explicit = simulate_force(f"{base}+{name}", {**values, **former, **default}, U1, time=T1)
    assert np.array_equal(implicit, explicit)
    assert not np.array_equal(implicit, simulate_force(base, values, U1, time=T1))


@pytest.mark.parametrize("base", ["plasticity", "bouc_wen"])
def test_slack_without_travel_is_the_base_law_whatever_its_force_width(base):
    values = PL if base == "plasticity" else BW
    fb = simulate_force(base, values, U1, time=T1)
    for sg in (1e-6, 0.05, 100.0):
        f = simulate_force(f"{base}+pinching", {**values, **NO_BAND, "slack_gap": 0.0, "slack_force": sg},
                           U1, time=T1)
        assert np.array_equal(f, fb)


# --- rollover: the smooth shape ------------------------------------------------------------------
def test_smooth_rollover_adds_the_closed_form_force_with_no_tangent_at_its_onset():
    k, ur, n = -40.0, 0.01, 3.0
    vals = {**PL, "roll_k": k, "roll_onset": ur, "roll_exp": n}
    for u in (-0.03, -0.015, -0.004, 0.0, 0.006, 0.012, 0.02, 0.045):
        fa = _step_force("plasticity+rollover", vals, u, 0.0) - _step_force("plasticity", PL, u, 0.0)
        e = max(abs(u) - ur, 0.0)
        assert fa == pytest.approx(k * ur * np.sign(u) * (e / ur) ** n / n, rel=1e-12, abs=1e-15)
    # the added tangent is zero at the onset and k_r at twice the onset (the plasticity base's
    # tangent cancels in the difference of two steps from the virgin state)
    _, k_on = one_step("plasticity+rollover", vals, ur, 0.0, 0.05)[:2]
    _, k_base = one_step("plasticity", PL, ur, 0.0, 0.05)[:2]
    _, k_2 = one_step("plasticity+rollover", vals, 2 * ur, 0.0, 0.05)[:2]
    _, k_b2 = one_step("plasticity", PL, 2 * ur, 0.0, 0.05)[:2]
    assert k_on == pytest.approx(k_base, abs=1e-12) and k_2 - k_b2 == pytest.approx(k, rel=1e-12)


def test_smooth_rollover_softens_beyond_its_onset_only_and_stores_no_energy_in_a_cycle():
    vals = {**PL, "roll_k": -30.0, "roll_onset": 0.008, "roll_exp": 2.5}
    f = simulate_force("plasticity+rollover", vals, U1, time=T1)
    fb = simulate_force("plasticity", PL, U1, time=T1)
    d = f - fb
    assert np.all(d * U1 <= 1e-12) and np.all(d[np.abs(U1) <= 0.008] == 0) and np.any(d * U1 < 0)
    # elastic: the added force is a function of u alone, so its work over a closed path is zero
    w = np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(U1))
    assert abs(w) < 1e-9 * np.sum(np.abs(d[1:]) * np.abs(np.diff(U1)))


# --- scragging: the Weibull onset -----------------------------------------------------------------
@pytest.mark.parametrize("k", [0.6, 3.0])
def test_scragging_with_an_onset_scales_by_the_closed_form_of_the_running_peak(k):
    s, uc = 0.3, 0.012
    vals = {**PL, "scrag": s, "scrag_disp": uc, "scrag_shape": k}
    f, kt = simulate_force("plasticity+scragging", vals, U1, time=T1, return_tangent=True)
    fb, kb = simulate_force("plasticity", PL, U1, time=T1, return_tangent=True)
    um = np.maximum.accumulate(np.abs(U1))
    g = 1 - s * (1 - np.exp(-((um / uc) ** k)))
    np.testing.assert_allclose(f, g * fb, rtol=1e-12, atol=1e-14)
    # on a new peak the tangent carries dg/du_max (away from the virgin start)
    new = np.r_[False, np.abs(U1[1:]) > um[:-1]] & (um > 1e-4)
    x = um[new] / uc
    dg = -s * k * x ** (k - 1) * np.exp(-(x**k)) / uc * np.sign(U1[new])
    np.testing.assert_allclose(kt[new], g[new] * kb[new] + fb[new] * dg, rtol=1e-10)
    # k > 1: little softening while the peak is well below u_c, more than the exponential beyond it
    exp_g = 1 - s * (1 - np.exp(-um / uc))
    if k > 1:
        early, late = (um > 0) & (um < 0.3 * uc), um > 1.5 * uc
        assert (g[early] > exp_g[early]).all() and (g[late] < exp_g[late]).all()


# --- rate: the Cross form saturates -------------------------------------------------------------
def test_rate_adds_the_closed_form_cross_force_and_levels_off_at_c_over_lam_to_the_a():
    c, a, lam = 4.0, 0.8, 50.0
    vals = {**PL, "rate_c": c, "rate_exp": a, "rate_sat": lam}
    u = 0.004
    fb = _step_force("plasticity", PL, u, 0.0)
    added = []
    for v in (-0.3, -0.01, 1e-4, 0.002, 0.02, 0.2, 2.0, 20.0):
        fa = _step_force("plasticity+rate", vals, u, v) - fb
        assert fa == pytest.approx(c * np.sign(v) * abs(v) ** a / (1 + (lam * abs(v)) ** a), rel=1e-12)
        added.append(fa)
    assert np.all(np.diff(added[2:]) > 0)  # grows with the speed ...
    assert added[-1] < c / lam**a and added[-1] > 0.95 * c / lam**a  # ... up to its plateau
    # the power law (lam = 0) does not level off
    p20 = _step_force("plasticity+rate", {**vals, "rate_sat": 0.0}, u, 20.0) - fb
    assert p20 == pytest.approx(c * 20.0**a, rel=1e-12) and p20 > 10 * c / lam**a


def test_saturating_rate_dissipates_in_every_cycle():
    t = np.linspace(0, 30, 3001)
    u = 0.02 * np.sin(2 * np.pi * t / 2.0)
    vals = {**PL, "rate_c": 5.0, "rate_exp": 0.5, "rate_sat": 30.0}
    f = simulate_force("plasticity+rate", vals, u, time=t)
    fb = simulate_force("plasticity", PL, u, time=t)
    mf, mb = cycle_metrics(u, f), cycle_metrics(u, fb)
    assert len(mf) == len(mb) == 15
    assert (mf.energy.to_numpy() > mb.energy.to_numpy()).all()


# --- stiffening: a power of the excess ----------------------------------------------------------
@pytest.mark.parametrize("n", [1.5, 3.0, 4.5])
def test_stiffening_adds_the_closed_form_power_of_the_excess(n):
    k, us = 50.0, 0.01
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+stiffening", {**PL, "stiff_k": k, "stiff_onset": us, "stiff_exp": n}, U1)
    e = np.maximum(np.abs(U1) - us, 0.0)
    np.testing.assert_allclose(f - fb, k * us * np.sign(U1) * (e / us) ** n / n, rtol=1e-12, atol=1e-14)


def test_a_larger_stiffening_exponent_starts_later_and_rises_steeper_through_k_s_at_twice_the_onset():
    k, us = 50.0, 0.01
    u = np.array([0.0125, 0.02, 0.029])
    spec, base = get("plasticity+stiffening"), get("plasticity")
    pb = base.pack(PL)
    scb = np.array(base.initial_state, dtype=float)
    tangents = {}
    for n in (2.0, 4.0):
        p = spec.pack({**PL, "stiff_k": k, "stiff_onset": us, "stiff_exp": n})
        sc = np.array(spec.initial_state, dtype=float)
        tangents[n] = [spec.step(p, sc, x, 0.0, 1.0, sc.copy())[1]
                       - base.step(pb, scb, x, 0.0, 1.0, scb.copy())[1] for x in u]
    assert tangents[4.0][0] < tangents[2.0][0]  # later: softer just beyond the onset
    assert tangents[4.0][1] == pytest.approx(k) and tangents[2.0][1] == pytest.approx(k)  # e = u_s
    assert tangents[4.0][2] > tangents[2.0][2]  # steeper at large excess


# --- degradation: a damage index of work and travel --------------------------------------------
def test_degradation_fades_by_the_closed_form_of_cumulative_work_and_travel():
    c, ct = 5.0, 0.4
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+degradation", {**PL, "deg_rate": c, "deg_travel": ct}, U1)
    w = dissipated_energy(U1, fb)
    wmax = np.concatenate([[0.0], np.maximum.accumulate(np.maximum(w, 0.0))[:-1]])
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(U1)))])  # to each sample
    travel = np.concatenate([[0.0], travel[:-1]])  # lagged one step, like the work
    np.testing.assert_allclose(f, fb / (1 + c * wmax + ct * travel), rtol=1e-9, atol=1e-12)


def test_travel_fades_small_cycles_as_much_per_millimetre_as_large_ones_work_does_not():
    """Per unit travel, 2 mm cycles fade the bearing by the travel term as much as 20 mm cycles;
    the work term fades them far less (their loops are small)."""
    def fade(amp, values):
        u = _sine_cycles(amp, 60.0 * 0.02 / (4 * amp))  # the same travel, 1.2 m
        f = simulate_force("plasticity+degradation", {**PL, **values}, u)
        fb = simulate_force("plasticity", PL, u)
        return 1 - f[-1] / fb[-1] if fb[-1] != 0 else np.nan, u

    t_small, _ = fade(0.002, {"deg_rate": 0.0, "deg_travel": 0.5})
    t_large, _ = fade(0.02, {"deg_rate": 0.0, "deg_travel": 0.5})
    e_small, _ = fade(0.002, {"deg_rate": 5.0, "deg_travel": 0.0})
    e_large, _ = fade(0.02, {"deg_rate": 5.0, "deg_travel": 0.0})
    assert t_small == pytest.approx(t_large, rel=0.02)
    assert e_small < 0.2 * e_large


def _sine_cycles(amp, cycles, n=200):
    x = np.linspace(0.0, cycles, int(round(cycles * n)) + 1)
    return amp * np.sin(2 * np.pi * x + np.pi / 4)


# --- tangents --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,values", [
    ("rate", {"rate_c": 5.0, "rate_exp": 0.7, "rate_sat": 20.0}),
    ("rate", {"rate_c": 2.0, "rate_rise": 0.5, "rate_vsat": 0.004}),  # velocity-dependent strength
    ("degradation", {"deg_rate": 5.0, "deg_travel": 0.3}),
    ("stiffening", {"stiff_k": 50.0, "stiff_onset": 0.01, "stiff_exp": 3.5}),
    ("pinching", {**NO_BAND, "slack_gap": 0.003, "slack_force": 0.1}),
    ("pinching", {"pinch": 0.4, "pinch_width": 0.4, "pinch_angle": 0.2, "slack_gap": 0.002,
                  "slack_force": 0.2}),
])
def test_tangent_is_the_derivative_of_the_force_within_a_step(name, values):
    spec = get(f"plasticity+{name}")
    path = np.concatenate([np.linspace(0, 0.025, 60), np.linspace(0.025, 0.002, 40)])
    assert_tangent_is_the_derivative(spec, spec.pack({**PL, **values}), path,
                                     (0.0015, 0.005, 0.007, 0.018, 0.0262, -0.004), h=1e-8, rel=1e-5)


# --- the slack element -----------------------------------------------------------------------------
def _series_bisection(base, values, u, a, sg):
    """The base law in series with x_s = a erf(F / sigma), solved independently of the kernel:
    per sample, plain bisection on x in [-a, a] for x = a erf(F_b(u - x) / sigma), the base law
    stepped from its committed state at every trial."""
    spec = get(base)
    p = spec.pack(values)
    sc = np.array(spec.initial_state, dtype=float)
    out = np.empty(u.size)
    for i, ui in enumerate(u):
        def phi(x, ui=ui):
            st = sc.copy()
            f = spec.step(p, sc, ui - x, 0.0, 1.0, st)[0]
            return x - a * math.erf(f / sg), f, st

        lo, hi = -a, a
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if phi(mid)[0] > 0:
                hi = mid
            else:
                lo = mid
            if hi - lo < 1e-16:
                break
        _, out[i], st = phi(0.5 * (lo + hi))
        sc[:] = st
    return out


@pytest.mark.parametrize("base", ["plasticity", "bouc_wen"])
def test_slack_agrees_with_an_independent_series_solve(base):
    values = PL if base == "plasticity" else BW
    a, sg = 0.003, 0.08
    ref = _series_bisection(base, values, U1, a, sg)
    f = simulate_force(f"{base}+pinching", {**values, **NO_BAND, "slack_gap": a, "slack_force": sg}, U1)
    np.testing.assert_allclose(f, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_slack_on_a_linear_spring_is_elastic_and_soft_near_zero_force_only():
    k, a, sg = 100.0, 0.004, 0.1
    u = 0.02 * np.sin(2 * np.pi * np.linspace(0, 3, 1201))
    lin = {"k": k, "c": 0.0}
    f = simulate_force("linear+pinching", {**lin, **NO_BAND, "slack_gap": a, "slack_force": sg}, u)
    # closed form of the series pair: u = F / k + a erf(F / sigma)
    np.testing.assert_allclose(u, f / k + a * np.vectorize(math.erf)(f / sg), atol=1e-11)
    assert abs(dissipated_energy(u, f)[-1]) < 1e-9  # no loop: the element stores, it does not dissipate
    spec = get("linear+pinching")
    p = spec.pack({**lin, **NO_BAND, "slack_gap": a, "slack_force": sg})
    sc = np.array(spec.initial_state, dtype=float)
    k0 = spec.step(p, sc, 0.0, 0.0, 1.0, sc.copy())[1]
    assert k0 == pytest.approx(k / (1 + k * 2 * a / (math.sqrt(math.pi) * sg)))  # soft at zero force
    f_far, k_far, _ = spec.step(p, sc, 0.02, 0.0, 1.0, sc.copy())
    assert f_far == pytest.approx(k * (0.02 - a), rel=1e-6) and k_far == pytest.approx(k, rel=1e-6)


def test_slack_lags_each_zero_crossing_and_lowers_the_peak_of_a_hysteretic_loop():
    a, sg = 0.004, 0.05
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+pinching", {**PL, **NO_BAND, "slack_gap": a, "slack_force": sg}, U1)
    assert np.abs(f).max() < np.abs(fb).max()
    assert dissipated_energy(U1, f)[-1] < dissipated_energy(U1, fb)[-1]
    # on the largest cycles the force crosses zero later than the base law's, by up to the travel
    last = U1.size - U1.size // 6
    zb = np.where(np.diff(np.sign(fb[last:])) != 0)[0]
    zf = np.where(np.diff(np.sign(f[last:])) != 0)[0]
    assert len(zb) == len(zf) >= 2
    shift = np.abs(U1[last:][zf] - U1[last:][zb])
    assert np.all(shift > 0.5 * a) and np.all(shift < 2.5 * a)


@pytest.mark.slow
def test_a_fit_of_the_slack_recovers_its_own_travel_and_force_width():
    from rrfrei.gap.model import IsolatorModel
    from rrfrei.io import ShearTest

    a, sg = 0.003, 0.08
    f = simulate_force("plasticity+pinching", {**PL, **NO_BAND, "slack_gap": a, "slack_force": sg}, U1,
                       time=T1)
    y = f + np.random.default_rng(0).normal(0, 0.002, f.size)
    fit = IsolatorModel("plasticity+pinching", fixed={"alpha2": 0.0, "mu": 2.0}, draws=20).fit(
        ShearTest("slack", T1, U1, y), seed=0)
    assert fit.params["slack_gap"] == pytest.approx(a, rel=0.1)
    assert fit.params["slack_force"] == pytest.approx(sg, rel=0.2)
    assert fit.params["k_init"] == pytest.approx(PL["k_init"], rel=0.1)
