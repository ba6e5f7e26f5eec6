"""Physical facts every law must show: dissipation, closed symmetric loops, damage, closed
forms, and convergence of the implicit integration under sub-stepping."""

import math
import warnings

import numpy as np
import pytest
from _law_strategies import bouc_wen_params, elastomeric_x_params, hdr_params, plasticity_params
from hypothesis import given, settings
from hypothesis import strategies as st

import rrfrei
from rrfrei import laws
from rrfrei.energy import cycle_metrics
from rrfrei.protocols import protocol1
from rrfrei.simulate import LocalSolverDeviation

_, P1 = protocol1()

PHYSICAL = {
    "plasticity": plasticity_params(),
    "bouc_wen": bouc_wen_params(dissipative=True),
    "elastomeric_x": elastomeric_x_params(),
    "hdr": hdr_params(physical=True),
}
"""Dissipative parameter ranges: Bouc-Wen with beta >= |gamma| and eta >= 1 (for eta < 1 the
local Newton, as in OpenSees, often fails where z crosses 0); HDR with a positive elastic
potential and a fast approach to the bounding surface (b3 >= 100/m, |b2| <= 100 b1/m^2): with
b3 d << 1 the bounding-surface update makes F2 grow while unloading and the loop runs backwards
(negative EDC), in OpenSees as here."""


def _sine(amp, cycles, m=200):
    return amp * np.sin(2 * np.pi * np.arange(cycles * m + 1) / m)


@pytest.mark.parametrize("law", list(PHYSICAL))
@given(data=st.data())
@settings(max_examples=15, deadline=None)
def test_every_cycle_dissipates_nonnegative_energy(law, data):
    """EDC >= 0 in each of the 12 protocol-1 cycles (beta >= |gamma| for Bouc-Wen; HDR with a
    positive elastic potential and bounding surface)."""
    p = data.draw(PHYSICAL[law])
    # Bouc-Wen: OpenSees' local Newton can fail at some draws (e.g. eta = 3, qd = 0.01 at sample 1);
    # the robust solve (OpenSees' iteration, bracketed where it fails) keeps the fact testable there
    opt = {"local_solver": "robust"} if laws.get(law).step_robust is not None else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocalSolverDeviation)
        f = rrfrei.simulate_force(law, p, P1, **opt)
    e = cycle_metrics(P1, f)["energy"].to_numpy()
    assert len(e) == 12
    scale = np.max(np.abs(f)) * np.max(np.abs(P1))
    assert np.all(e >= -1e-12 * scale), e


def test_linear_dashpot_dissipates_pi_c_omega_d2_per_cycle_and_spring_nothing():
    t = np.arange(4 * 400 + 1) * (2.0 / 400)  # 2 s cycles, 400 steps
    d0, c, k = 0.02, 30.0, 500.0
    u = d0 * np.sin(2 * np.pi * t / 2.0)
    e = cycle_metrics(u, rrfrei.simulate_force("linear", dict(k=k, c=c), u, time=t))["energy"]
    np.testing.assert_allclose(e[1:], math.pi * c * (2 * np.pi / 2.0) * d0**2, rtol=2e-3)
    e0 = cycle_metrics(u, rrfrei.simulate_force("linear", dict(k=k), u))["energy"]
    np.testing.assert_allclose(e0, 0.0, atol=1e-15)


STABLE = {
    "plasticity": st.builds(dict, k_init=st.just(100.0), qd=st.floats(0.1, 3.0),
                            alpha1=st.floats(0.0, 0.5), alpha2=st.floats(0.0, 0.1),
                            mu=st.sampled_from([1.0, 2.0, 3.0])),
    "bouc_wen": st.tuples(st.floats(0.3, 1.0), st.floats(0.0, 1.0)).flatmap(
        lambda bg: st.builds(dict, k_init=st.just(1000.0), qd=st.floats(0.1, 1.0),
                             alpha1=st.floats(0.0, 0.5), alpha2=st.floats(0.0, 0.1),
                             mu=st.sampled_from([1.0, 2.0]), eta=st.floats(1.0, 4.0),
                             beta=st.just(bg[0]), gamma=st.just(bg[0] * bg[1]))),
    "elastomeric_x": st.builds(dict, fy=st.floats(0.1, 3.0), alpha=st.floats(0.02, 0.5),
                               gr=st.floats(300.0, 1500.0), d2=st.just(0.08), tr=st.just(0.002),
                               n=st.just(15.0)),
}


@pytest.mark.parametrize("law", list(STABLE))
@given(data=st.data())
@settings(max_examples=10, deadline=None)
def test_stabilised_loop_is_closed_and_odd_symmetric(law, data):
    """After a few cycles at constant amplitude the loop repeats itself and F(u) = -F(-u)."""
    p = data.draw(STABLE[law])
    m = 200
    u = _sine(0.03, 10, m)
    f = rrfrei.simulate_force(law, p, u)
    scale = np.max(np.abs(f))
    last = f[-m - 1:]
    prev = f[-2 * m - 1:-m]
    assert np.max(np.abs(last - prev)) <= 1e-8 * scale
    half = m // 2
    assert np.max(np.abs(last[:half] + last[half:2 * half])) <= 1e-8 * scale


def test_hdr_strength_decays_from_cycle_to_cycle():
    """Mullins damage (c3 < 1, c4 > 0): at DD and DM each repeated cycle is weaker, while the
    same law without damage (c3 = 1, c4 = 0) repeats its peak force."""
    p = dict(a1=60.0, a2=2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4, c4=20.0)
    damaged = cycle_metrics(P1, rrfrei.simulate_force("hdr", p, P1))
    intact = cycle_metrics(P1, rrfrei.simulate_force("hdr", {**p, "c3": 1.0, "c4": 0.0}, P1))
    for g in (2, 3):  # cycles at DD and at DM
        rows = slice(3 * g, 3 * g + 3)
        assert np.all(np.diff(damaged["f_pos"][rows]) < 0)
        assert np.all(np.diff(-damaged["f_neg"][rows]) < 0)
        assert np.all(damaged["f_pos"][rows] < intact["f_pos"][rows])
        steady = intact["f_pos"][rows].to_numpy()[1:]
        assert abs(steady[1] - steady[0]) <= 1e-6 * steady[0]


@given(n_d=st.integers(10, 60), data=st.data(), qd=st.floats(0.1, 10.0),
       alpha1=st.floats(0.0, 0.8), alpha2=st.floats(0.0, 0.2), mu=st.sampled_from([1.0, 2.0, 3.0]))
@settings(max_examples=40, deadline=None)
def test_plasticity_energy_per_cycle_is_4_qd_d_minus_uy(n_d, data, qd, alpha1, alpha2, mu):
    """Triangular cycles sampled on a grid through the yield corners: the trapezoidal EDC is the
    exact loop area 4 qd (d - u_y), u_y = qd / ((1 - alpha1) k_init); the hardening is elastic."""
    j = data.draw(st.integers(1, n_d - 1))
    du = 1e-3
    d, uy = n_d * du, j * du
    k_init = qd / uy / (1.0 - alpha1)
    cycle = np.concatenate([np.arange(0, n_d), np.arange(n_d, -n_d, -1), np.arange(-n_d, 0)])
    u = np.append(np.tile(cycle, 3), 0).astype(float) * du  # 0 -> d -> -d -> 0, three times
    f = rrfrei.simulate_force("plasticity", dict(k_init=k_init, qd=qd, alpha1=alpha1,
                                                 alpha2=alpha2, mu=mu), u)
    e = cycle_metrics(u, f)["energy"].to_numpy()
    assert len(e) == 3
    np.testing.assert_allclose(e[1:], 4 * qd * (d - uy), rtol=1e-9)


@pytest.mark.parametrize("law, p", [
    ("bouc_wen", dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=1.37, beta=0.6,
                      gamma=0.4)),
    ("elastomeric_x", dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0)),
    ("hdr", dict(a1=60.0, a2=2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4,
                 c4=5e3)),
    ("plasticity", dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.05, mu=2.0)),
])
def test_energy_per_cycle_converges_under_substepping(law, p):
    """The implicit one-step-per-increment scheme converges: 32 -> 64 substeps changes every
    cycle's energy by < 0.1 %, and less than 1 -> 2 substeps did."""
    e = {n: cycle_metrics(P1, rrfrei.simulate_force(law, p, P1, substeps=n))["energy"].to_numpy()
         for n in (1, 2, 32, 64)}
    tiny = 1e-12 * np.max(e[64])  # elastic cycles of plasticity dissipate nothing
    change_fine = np.abs(e[64] - e[32]) / (e[64] + tiny)
    assert np.all(change_fine < 1e-3)
    if law != "plasticity":  # exact return mapping: step-size independent
        assert np.max(change_fine) < np.max(np.abs(e[2] - e[1]) / e[2])
