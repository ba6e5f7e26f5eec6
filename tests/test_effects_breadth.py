"""Broader catalogue kernels for the held-out gap (issue 12: shrink >= 50 % whenever an effect is
named): the slider's stick displacement and static capacity, the velocity-dependent strength of
``rate`` and the amplitude exponent of degradation's travel measure.

Each new parameter at its default is the former kernel bit for bit, and each has its physical
fact: the elastic-plastic slider agrees with an independent series solve and sticks with the
series stiffness; the slip-weakening slider agrees with an independent one and breaks away above
its kinetic capacity; the strength rises with velocity to ``1 + r`` by the exponential law of
Constantinou, Mokha & Reinhorn (1990); the travel of ``|u|^m`` weights a cycle of amplitude ``A``
by ``A^m`` (Miner's rule over a Coffin-Manson life).
"""

import numpy as np
import pytest
from _tangent import committed_after
from test_effects_shapes import PL, T1, U1
from test_effects_shapes import one_step as _step

from rrfrei import simulate_force
from rrfrei.energy import cycle_metrics
from rrfrei.laws import get


def test_the_new_parameters_follow_their_former_ones():
    assert get("plasticity+slip").param_names[-4:] == ("slip_force", "slip_stick", "slip_static", "slip_dc")
    assert get("plasticity+rate").param_names[-5:] == ("rate_c", "rate_exp", "rate_sat", "rate_rise",
                                                       "rate_vsat")
    assert get("plasticity+degradation").param_names[-3:] == ("deg_rate", "deg_travel", "deg_exp")


# --- slip: the stick displacement ------------------------------------------------------------------
@pytest.mark.parametrize("ys", [0.0005, 0.003, 0.01])
def test_elastic_plastic_slider_agrees_with_an_independent_series_solve(ys):
    from rrfrei.gap.validate import _slip

    fs = 1.1
    f = simulate_force("plasticity+slip", {**PL, "slip_force": fs, "slip_stick": ys}, U1)
    p = np.array([PL[k] for k in ("k_init", "qd", "alpha1", "alpha2", "mu")])
    peer = _slip(U1, T1, p, fs, fs / ys)  # elastic-plastic slider of stiffness F_s / y_s, bisection
    np.testing.assert_allclose(f, peer, atol=1e-9)
    assert np.abs(f).max() <= fs + 1e-9


def test_a_sticking_slider_is_a_spring_in_series_and_its_tangent_is_the_series_stiffness():
    """Below its capacity (an elastic base, no sliding) the bearing is the base stiffness in series
    with k_s = F_s / y_s; the more the interface deforms, the softer the bearing while it sticks."""
    lin = {**PL, "qd": 1e6}  # the plasticity law stays elastic: k_init
    fs, u = 1.0, 0.004
    for ys in (0.001, 0.004):
        ks = fs / ys
        f, k = _step("plasticity+slip", {**lin, "slip_force": fs, "slip_stick": ys}, u, 0.0)
        kser = 1.0 / (1.0 / lin["k_init"] + 1.0 / ks)
        assert f == pytest.approx(kser * u, rel=1e-10) and abs(f) < fs
        assert k == pytest.approx(kser, rel=1e-10)
    f0, k0 = _step("plasticity+slip", {**lin, "slip_force": fs, "slip_stick": 0.0}, u, 0.0)
    assert f0 == pytest.approx(lin["k_init"] * u) and k0 == pytest.approx(lin["k_init"])


def test_stick_displacement_rounds_the_loop_and_keeps_it_dissipative():
    rigid = simulate_force("plasticity+slip", {**PL, "slip_force": 1.0}, U1)
    soft = simulate_force("plasticity+slip", {**PL, "slip_force": 1.0, "slip_stick": 0.004}, U1)
    m = cycle_metrics(U1, soft)
    assert (m.energy >= -1e-12).all()
    # the stick spring delays sliding: the same capacity is reached later (at larger |u|)
    first = lambda f: np.argmax(np.abs(f) >= 1.0 - 1e-9)  # noqa: E731
    assert first(soft) > first(rigid)


def test_stick_tangent_is_the_derivative_of_the_force_within_a_step():
    spec = get("plasticity+slip")
    p = spec.pack({**PL, "slip_force": 1.1, "slip_stick": 0.003})
    path = np.concatenate([np.linspace(0, 0.025, 60), np.linspace(0.025, 0.015, 30)])
    sc, stt = committed_after(spec, p, path)
    for u in (0.0145, 0.012, 0.008):  # sticking after the reversal
        f, k, _ = spec.step(p, sc, u, 0.0, 1.0, stt.copy())
        assert abs(f) < 1.1
        h = 1e-8
        fp = spec.step(p, sc, u + h, 0.0, 1.0, stt.copy())[0]
        fm = spec.step(p, sc, u - h, 0.0, 1.0, stt.copy())[0]
        assert k == pytest.approx((fp - fm) / (2 * h), rel=1e-5, abs=1e-6)


# --- slip: static and kinetic friction -------------------------------------------------------------
class _WeakeningSlider:
    """Rigid-plastic slider whose capacity weakens linearly from r F_k to F_k over d_c of slip
    travel since it last stuck (an independent peer of the kernel, stepped by bisection)."""

    def __init__(self, fk, r, dc):
        self.fk, self.r, self.dc = fk, r, dc
        self.us, self.s = 0.0, 0.0

    def capacity(self):
        return self.fk * (1 + (self.r - 1) * max(1 - self.s / self.dc, 0.0))


def _series_weakening(u, fk, r, dc):
    spec = get("plasticity")
    p = spec.pack(PL)
    sc = np.array(spec.initial_state, dtype=float)
    sl = _WeakeningSlider(fk, r, dc)
    out = np.empty(u.size)
    for i, ui in enumerate(u):
        cap = sl.capacity()
        st = sc.copy()
        f = spec.step(p, sc, ui - sl.us, 0.0, 1.0, st)[0]
        if abs(f) <= cap:
            sl.s = 0.0
        else:  # slide: bisection on the inner displacement for |F| = cap
            target = np.sign(f) * cap
            lo, hi = ui - sl.us - np.sign(f) * 1.0, ui - sl.us
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                st = sc.copy()
                fm = spec.step(p, sc, mid, 0.0, 1.0, st)[0]
                if np.sign(f) * (fm - target) > 0:
                    hi = mid
                else:
                    lo = mid
            st = sc.copy()
            f = spec.step(p, sc, 0.5 * (lo + hi), 0.0, 1.0, st)[0]
            new = ui - 0.5 * (lo + hi)
            sl.s += abs(new - sl.us)
            sl.us = new
        out[i] = f
        sc[:] = st
    return out


def test_static_capacity_agrees_with_an_independent_slip_weakening_slider():
    fk, r, dc = 1.0, 1.3, 0.002
    f = simulate_force("plasticity+slip", {**PL, "slip_force": fk, "slip_static": r, "slip_dc": dc}, U1)
    np.testing.assert_allclose(f, _series_weakening(U1, fk, r, dc), atol=1e-9)


def test_breakaway_exceeds_the_kinetic_capacity_after_each_stick_and_weakens_while_sliding():
    fk, r, dc = 0.7, 1.3, 0.002
    f = simulate_force("plasticity+slip", {**PL, "slip_force": fk, "slip_static": r, "slip_dc": dc}, U1)
    flat = simulate_force("plasticity+slip", {**PL, "slip_force": fk}, U1)
    assert np.abs(flat).max() == pytest.approx(fk)
    a = np.abs(f)
    assert a.max() > 1.15 * fk and a.max() <= r * fk + 1e-9  # breakaway above F_k, below r F_k
    kinetic = np.abs(a - fk) < 1e-9  # sliding past d_c: the kinetic capacity
    assert kinetic.sum() > 20
    # after a stick the capacity is static again: a sample above F_k follows every kinetic run
    runs_end = np.flatnonzero(kinetic[:-1] & ~kinetic[1:])
    assert len(runs_end) >= 4 and all(np.any(a[i + 1:] > 1.15 * fk) for i in runs_end[:-2])
    assert (cycle_metrics(U1, f).energy >= -1e-12).all()


# --- rate: a strength that rises with velocity -----------------------------------------------------
def test_strength_rises_with_velocity_by_the_closed_form_to_its_plateau():
    r, vs = 0.4, 0.01
    vals = {**PL, "rate_c": 0.0, "rate_rise": r, "rate_vsat": vs}
    u = 0.004
    fb, _ = _step("plasticity", PL, u, 0.0)
    ratios = []
    for v in (-0.2, -0.005, 0.0, 1e-4, 0.003, 0.01, 0.05, 0.5):
        f, _ = _step("plasticity+rate", vals, u, v)
        assert f == pytest.approx(fb * (1 + r * (1 - np.exp(-abs(v) / vs))), rel=1e-12)
        ratios.append(f / fb)
    assert ratios[2] == 1.0  # at rest: the base strength
    assert np.all(np.diff(ratios[2:]) > 0)  # grows with the speed ...
    assert ratios[-1] == pytest.approx(1 + r, rel=1e-12)  # ... to f_max / f_min = 1 + r
    assert ratios[0] == pytest.approx(1 + r, rel=1e-8)  # either direction (within exp(-20))


def test_faster_cycles_dissipate_more_up_to_the_plateau_of_the_strength():
    r, vs = 0.4, 0.01
    energies = []
    for period in (400.0, 4.0, 0.04):  # peak velocities 0.3 mm/s, 31 mm/s, 3.1 m/s
        t = np.linspace(0.0, 3 * period, 3 * 400 + 1)
        u = 0.02 * np.sin(2 * np.pi * t / period)
        vals = {**PL, "rate_c": 0.0, "rate_rise": r, "rate_vsat": vs}
        f = simulate_force("plasticity+rate", vals, u, time=t)
        energies.append(cycle_metrics(u, f).energy.iloc[-1])
    base = cycle_metrics(u, simulate_force("plasticity", PL, u, time=t)).energy.iloc[-1]
    assert base < energies[0] < energies[1] < energies[2]
    assert energies[0] < 1.05 * base  # slow: the low-velocity strength
    assert energies[2] == pytest.approx((1 + r) * base, rel=0.03)  # fast: the plateau


def test_rate_strength_dissipates_in_every_cycle():
    """(Its tangent: tests/test_effects_shapes.py, with the other kernels' tangents.)"""
    vals = {**PL, "rate_c": 2.0, "rate_rise": 0.5, "rate_vsat": 0.004}
    f = simulate_force("plasticity+rate", vals, U1, time=T1)
    assert (cycle_metrics(U1, f).energy >= -1e-12).all()


# --- degradation: the amplitude exponent of the travel ---------------------------------------------
def _cycles(amp, n, per=40):
    """n sine cycles of amplitude amp sampled at per points a cycle, ending on the next peak."""
    k = np.arange(n * per + per // 4 + 1)
    return amp * np.sin(2 * np.pi * k / per)


@pytest.mark.parametrize("m", [0.1, 0.5, 1.0, 1.5])
def test_a_cycle_of_amplitude_a_fades_the_bearing_by_a_to_the_m(m):
    """The same number of cycles at 2 mm and at 20 mm: the damage indices D = 1 / g - 1 stand in
    the ratio (2 / 20)^m (Miner's rule over a Coffin-Manson life): m = 1 the travel, m -> 0 a
    count of cycles whatever their amplitude."""
    lin = {**PL, "qd": 1e6}  # an elastic base, so that g = f / f_b at the last peak
    d = []
    for amp in (0.002, 0.02):
        u = _cycles(amp, 6)
        f = simulate_force("plasticity+degradation",
                           {**lin, "deg_rate": 0.0, "deg_travel": 0.2, "deg_exp": m}, u)
        fb = simulate_force("plasticity", lin, u)
        d.append(fb[-1] / f[-1] - 1.0)
    assert d[0] / d[1] == pytest.approx(0.1**m, rel=1e-9)


def test_travel_measure_is_the_total_variation_of_abs_u_to_the_m_through_zero():
    m, ct = 0.4, 0.3
    fb = simulate_force("plasticity", PL, U1)
    f = simulate_force("plasticity+degradation", {**PL, "deg_rate": 0.0, "deg_travel": ct, "deg_exp": m}, U1)
    # independent: insert a sample at every zero crossing, then the total variation of |u|^m
    tv = np.zeros(U1.size)
    for i in range(1, U1.size):
        a, b = U1[i - 1], U1[i]
        path = [a, 0.0, b] if a * b < 0 else [a, b]
        tv[i] = tv[i - 1] + np.sum(np.abs(np.diff(np.abs(np.array(path)) ** m)))
    lagged = np.concatenate([[0.0], tv[:-1]])
    np.testing.assert_allclose(f, fb / (1 + ct * lagged), rtol=1e-9, atol=1e-12)
