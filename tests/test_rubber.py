"""rubber PRF model: accuracy against an independent scipy Radau reference, closed forms, physics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

import rubber
from rubber import PRESETS, BBChain, PRFModel, Yeoh, protocol1, protocol2, simulate


def _w1_ec(i1, nkt, n):
    x = i1 / n
    return nkt * (0.5 + x / 10 + 33 / 1050 * x**2 + 76 / 7000 * x**3 + 2595 / 673750 * x**4)


def radau_reference(p, t, lam, tau="frobenius", rtol=1e-10):
    """Nominal stress by scipy Radau (rtol 1e-10), Frobenius flow rule written out literally:
    du/dt = sqrt(2/3) C1 (lam_ch - 1 + xi)^C2 (sqrt(2/3)|Delta|)^C3 sign(Delta), restarted at kinks."""
    d = p.as_dict()
    s = np.diff(lam) / np.diff(t)
    kinks = [0] + [i for i in range(1, s.size) if abs(s[i] - s[i - 1]) > 1e-12] + [t.size - 1]
    x = lam**2 + 2 / lam - 3
    out = 2 * (d["C10"] + 2 * d["C20"] * x + 3 * d["C30"] * x**2) * (lam - lam**-2)
    ch = [tuple(d[k + "_" + c] for k in ("nkt", "N", "C1", "C2", "C3")) for c in "BC"]
    xi = d["xi"]

    def rhs(tt, y, i0, i1):
        lt = lam[i0] + (lam[i1] - lam[i0]) * (tt - t[i0]) / (t[i1] - t[i0])
        out = []
        for (nkt, n, c1, c2, c3), yk in zip(ch, y):
            lv = math.exp(yk)
            le = lt / lv
            dl = 2 * _w1_ec(le * le + 2 / le, nkt, n) * (le * le - 1 / le)
            lch = math.sqrt(max((lv * lv + 2 / lv) / 3, 1.0))
            if tau == "frobenius":
                r = math.sqrt(2 / 3) * c1 * (lch - 1 + xi) ** c2 * (math.sqrt(2 / 3) * abs(dl)) ** c3
            else:
                r = c1 * (lch - 1 + xi) ** c2 * abs(dl) ** c3
            out.append(math.copysign(r, dl))
        return out

    u = np.zeros((2, t.size))
    y0 = [0.0, 0.0]
    for a, b in zip(kinks[:-1], kinks[1:]):
        sol = solve_ivp(rhs, (t[a], t[b]), y0, method="Radau", rtol=rtol, atol=1e-14,
                        t_eval=t[a:b + 1], args=(a, b))
        u[:, a:b + 1] = sol.y
        y0 = list(sol.y[:, -1])
    for (nkt, n, _, _, _), uk in zip(ch, u):
        le = lam / np.exp(uk)
        out = out + 2 * _w1_ec(le * le + 2 / le, nkt, n) * (le * le - 1 / le) / lam
    return out


@pytest.fixture(scope="module")
def histories():
    return {"p1": protocol1(), "p2": protocol2()}


@pytest.mark.parametrize("case", ["A", "B", "C"])
@pytest.mark.parametrize("proto", ["p1", "p2"])
def test_three_parameter_sets_match_radau_reference_to_1e_4(histories, case, proto):
    t, lam = histories[proto]
    ref = radau_reference(PRESETS[case], t, lam)
    got = simulate(PRESETS[case], t, lam).nominal
    assert np.max(np.abs(got - ref)) / np.max(np.abs(ref)) <= 1e-4
    assert np.allclose(simulate(PRESETS[case], t, lam).cauchy, got * lam)


def test_mises_convention_equals_frobenius_with_rescaled_c1(histories):
    """C1_mises = C1_frob (2/3)^((C3+1)/2) exactly (docs/reference/prf_model.md section 4)."""
    t, lam = histories["p1"]
    p = PRESETS["A"]
    pm = p.replace(C1_B=p.C1_B * (2 / 3) ** ((p.C3_B + 1) / 2), C1_C=p.C1_C * (2 / 3) ** ((p.C3_C + 1) / 2))
    a = simulate(p, t, lam, rtol=1e-8).nominal
    b = simulate(pm, t, lam, tau="mises", rtol=1e-8).nominal
    assert np.max(np.abs(a - b)) < 1e-12


def test_yeoh_only_matches_closed_form():
    lam = np.linspace(1.0, 2.0, 50)
    t = np.arange(lam.size, dtype=float)
    r = simulate(Yeoh(1.2, -0.3, 0.1), t, lam)
    x = lam**2 + 2 / lam - 3
    assert np.allclose(r.nominal, 2 * (1.2 - 0.6 * x + 0.3 * x**2) * (lam - lam**-2), rtol=1e-13, atol=1e-14)
    nh = simulate(rubber.NeoHookean(0.5), t, lam)
    assert np.allclose(nh.nominal, lam - lam**-2, rtol=1e-13)


def test_locked_dashpots_give_the_three_spring_elastic_curve():
    m = Yeoh(1.0, 0.1, 0.01) & BBChain(2.0, 3.0, 0.0) & BBChain(5.0, 1.5, 0.0, C3=7.0)
    lam = np.linspace(0.8, 1.6, 41)
    r = simulate(m, np.arange(lam.size, dtype=float), lam)
    assert np.allclose(r.nominal, rubber.instantaneous_stress(m, lam), rtol=1e-13)


def test_holds_relax_monotonically_and_viscous_stretch_never_decreases(histories):
    t, lam = histories["p2"]
    for case in "ABC":
        r = simulate(PRESETS[case], t, lam)
        hold = np.r_[False, np.diff(lam) == 0] & np.r_[np.diff(lam) == 0, False]
        dp = np.diff(r.nominal)[hold[1:] & hold[:-1]]
        assert dp.size > 1000 and np.all(dp < 0)
        assert np.all(np.diff(r.viscous_stretch, axis=1) >= -1e-15)


def test_every_loop_dissipates_and_the_energy_balance_closes():
    t, lam = protocol1(dt=0.005)
    r = simulate(PRESETS["A"], t, lam, rtol=1e-8)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (r.nominal[1:] + r.nominal[:-1]) * np.diff(lam))])
    balance = work - (r.stored - r.stored[0]) - r.dissipated_total
    assert np.max(np.abs(balance)) <= 1e-4 * r.dissipated_total[-1]
    # loops: lam0 crossings going up after the first ramp
    ends = np.nonzero(np.isclose(lam, 1.2) & np.r_[True, np.diff(lam) > 0])[0]
    d = r.dissipated_total[ends]
    loops = np.diff(d)
    assert loops.size == 5 and np.all(loops > 0)
    assert np.all(np.diff(r.dissipated, axis=1) >= -1e-12)  # local dissipation rate >= 0


def test_case_a_reconstruction_reproduces_the_notes_relaxation_values(histories):
    """docs/reference/prf_model.md section 8: case A holds 2.09 -> 1.26, 2.90 -> 2.08, 3.46 -> 2.70 MPa
    (within 0.02)."""
    t, lam = histories["p2"]
    r = simulate(PRESETS["A"], t, lam)
    slope = np.diff(lam) / np.diff(t)
    knots = np.nonzero(np.r_[True, np.abs(np.diff(slope)) > 1e-9, True])[0]
    vals = r.nominal[knots[1:7]]
    assert np.allclose(vals, [2.09, 1.26, 2.90, 2.08, 3.46, 2.70], atol=0.02)


@settings(max_examples=15, deadline=None)
@given(c1=st.floats(1e-6, 5.0), c3=st.floats(1.0, 10.0), nkt=st.floats(0.01, 20.0), n=st.floats(1.0, 5.0),
       rate=st.sampled_from([0.093, 0.93]))
def test_any_chain_in_the_box_integrates_and_dissipates(c1, c3, nkt, n, rate):
    """Stable in the whole search box, including the stiff corner (C1 = 5, C3 = 10, N = 1)."""
    m = Yeoh(1.0) & BBChain(nkt, n, c1, C3=c3)
    t, lam = protocol1(rate=rate)
    r = simulate(m, t, lam)
    assert np.all(np.isfinite(r.nominal))
    assert np.all(np.diff(r.dissipated[0]) >= -1e-12)


def test_stiff_corner_matches_reference():
    p = PRESETS["A"].replace(nkt_B=20.0, N_B=1.0, C1_B=5.0, C3_B=10.0)
    t, lam = protocol1()
    ref = radau_reference(p, t, lam)
    got = simulate(p, t, lam, rtol=1e-7).nominal
    assert np.max(np.abs(got - ref)) / np.max(np.abs(ref)) <= 1e-4


def test_second_order_convergence_in_tolerance():
    """A second-order method under error-per-step control: global error ~ rtol^(2/3)."""
    t, lam = protocol1()
    ref = simulate(PRESETS["A"], t, lam, rtol=1e-11).nominal
    rt = np.array([1e-4, 1e-6, 1e-8])
    errs = [np.max(np.abs(simulate(PRESETS["A"], t, lam, rtol=r).nominal - ref)) for r in rt]
    slope = np.polyfit(np.log(rt), np.log(errs), 1)[0]
    assert 0.5 <= slope <= 0.8


def test_bad_inputs_raise_clear_value_errors():
    with pytest.raises(ValueError, match="C1"):
        BBChain(1.0, 2.0, -1.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        simulate(PRESETS["A"], [0.0, 1.0, 1.0], [1.0, 1.1, 1.2])
    with pytest.raises(ValueError, match="tau"):
        simulate(PRESETS["A"], [0.0, 1.0], [1.0, 1.1], tau="tresca")
    with pytest.raises(ValueError, match="stretch"):
        simulate(PRESETS["A"], [0.0, 1.0], [1.0, -1.1])


def test_composition_keeps_one_state_per_chain():
    m = Yeoh(1.0) & BBChain(2.0, 3.0, 1e-3, C3=3.0) & BBChain(5.0, 2.0, 1.0, C3=6.0) & BBChain(1.0, 4.0, 0.1)
    assert isinstance(m, PRFModel) and len(m.chains) == 3
    t, lam = protocol1()
    r = simulate(m, t, lam)
    assert r.viscous_stretch.shape == (3, t.size) and r.chain_cauchy.shape == (4, t.size)
    assert np.allclose(r.chain_cauchy.sum(axis=0), r.cauchy)
