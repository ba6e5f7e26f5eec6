"""Physics of the coupled bidirectional laws (no peer needed): energy, yield surface, isotropy,
and the unidirectional law along one axis.

Energy is the line integral of F . du along the sampled path, by the trapezoidal rule over each
increment, sum_i (F_i + F_{i+1}) / 2 . (u_{i+1} - u_i), exact for a force linear along the
increment; paths are fine (thousands of samples per cycle), so what remains is the error at the
few increments where the branch changes, and, on orbits, the first-order error of the
backward-Euler (return-mapping) steady state in the angular step.
"""

import numpy as np
import pytest
from _law_strategies import bouc_wen_params, histories, plasticity_params
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import rrfrei
from rrfrei.errors import NumericalFailure
from rrfrei.laws.plan import bouc_wen as plan_bouc_wen
from rrfrei.laws.plan import plasticity as plan_plasticity

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def line_integral(force, disp):
    """Work of ``force`` (n, 2) [kN] along ``disp`` (n, 2) [m], trapezoidal per increment [kJ]."""
    return float(np.sum(0.5 * (force[1:] + force[:-1]) * np.diff(disp, axis=0)))


def u_y(p):
    return p["qd"] / ((1.0 - p["alpha1"]) * p["k_init"])


def orbit(r, per_rev, revs, ramp=200):
    """Ramp out along x to radius r, then ``revs`` counter-clockwise revolutions."""
    t = 2 * np.pi * np.arange(0, per_rev * revs + 1) / per_rev
    out = np.c_[np.linspace(0.0, r, ramp, endpoint=False), np.zeros(ramp)]
    return np.r_[out, np.c_[r * np.cos(t), r * np.sin(t)]], ramp


def rotate(a, th):
    c, s = np.cos(th), np.sin(th)
    return a @ np.array([[c, s], [-s, c]])  # rows rotated counter-clockwise by th


# ---------------------------------------------------------------------------- plasticity

@given(p=plasticity_params(), angle=st.floats(0.0, 2 * np.pi), ratio=st.floats(1.5, 20.0))
@SETTINGS
def test_plasticity_dissipates_4_qd_d_minus_uy_per_cycle_along_any_straight_line(p, angle, ratio):
    """A cycle of amplitude d along any direction in plan: the 1-D loop, 4 qd (d - u_y); the
    hardening terms (linear, and per-component nonlinear) are elastic and add nothing."""
    d = ratio * u_y(p)
    assume(d <= 0.5)
    n = 4000
    s = d * np.sin(2 * np.pi * np.arange(0, 2 * n + 1) / n)
    path = np.c_[s * np.cos(angle), s * np.sin(angle)]
    f = rrfrei.simulate_force("plasticity", p, path)
    energy = line_integral(f[n:], path[n:])  # the second cycle
    expected = 4 * p["qd"] * (d - u_y(p))
    assert energy == pytest.approx(expected, rel=1e-5, abs=1e-9 * p["qd"] * d)


@given(p=plasticity_params(), ratio=st.floats(2.0, 30.0))
@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_plasticity_dissipates_2_pi_qd_sqrt_r2_minus_uy2_per_revolution_of_a_circular_orbit(p, ratio):
    """A steady circular orbit of radius r: the plastic displacement settles on a circle of
    radius sqrt(r^2 - u_y^2) (u - u_p, of length u_y, is tangent to it), so the dissipation per
    revolution is 2 pi qd sqrt(r^2 - u_y^2), where two independent springs would claim
    8 qd (r - u_y) (more for r > 4.2 u_y, up to 8 / (2 pi) = 1.27 times).  The return mapping's
    steady state converges at first order in the angular step dtheta: the error is below dtheta
    and halves when dtheta halves."""
    uy = u_y(p)
    r = ratio * uy
    assume(r <= 0.5)
    expected = 2 * np.pi * p["qd"] * np.sqrt(r * r - uy * uy)
    errors = []
    for per_rev in (2000, 4000):
        path, start = orbit(r, per_rev, 4)
        f = rrfrei.simulate_force("plasticity", p, path)
        last = slice(start + 3 * per_rev, None)
        energy = line_integral(f[last], path[last])
        errors.append(energy / expected - 1.0)
        assert abs(errors[-1]) <= 2 * np.pi / per_rev
    assert abs(errors[1]) <= 0.6 * abs(errors[0]) + 1e-9
    two_springs = 0.0  # each component alone through the unidirectional law
    for a in (0, 1):
        fa = rrfrei.simulate_force("plasticity", p, path[:, a])
        two_springs += float(np.sum((0.5 * (fa[1:] + fa[:-1]) * np.diff(path[:, a]))[last]))
    assert two_springs == pytest.approx(8 * p["qd"] * (r - uy), rel=1e-4)
    # independent springs overstate it by up to 8 / (2 pi) (r >> u_y); below
    # r = (16 + pi^2) / (16 - pi^2) u_y = 4.2 u_y they understate it
    assert two_springs / energy < 8 / (2 * np.pi)
    if r > 4.3 * uy:
        assert two_springs > energy
    elif r < 4.1 * uy:
        assert two_springs < energy


@given(p=plasticity_params(), ratio=st.floats(2.0, 30.0))
@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_plasticity_plastic_displacement_settles_on_a_circle_under_a_circular_orbit(p, ratio):
    """On the orbit the hysteretic force is qd (on the yield circle) and the plastic displacement
    u_p = u - q / k0 moves on the circle of radius sqrt(r^2 - u_y^2) (to first order in dtheta)."""
    p = {**p, "alpha2": 0.0}
    uy = u_y(p)
    r = ratio * uy
    assume(r <= 0.5)
    per_rev = 4000
    path, start = orbit(r, per_rev, 5)
    f = rrfrei.simulate_force("plasticity", p, path)
    k0 = (1 - p["alpha1"]) * p["k_init"]
    q = f - p["alpha1"] * p["k_init"] * path
    tail = slice(start + 4 * per_rev, None)
    np.testing.assert_allclose(np.hypot(*q[tail].T), p["qd"], rtol=1e-12)
    up = path - q / k0
    rho = np.hypot(*up[tail].T)
    assert np.ptp(rho) <= 1e-9 * r
    assert rho[-1] == pytest.approx(np.sqrt(r * r - uy * uy), rel=2 * np.pi / per_rev)


@st.composite
def plan_paths(draw):
    a = draw(histories(min_size=5, max_size=80))
    b = draw(histories(min_size=a.size, max_size=a.size))
    return np.c_[a, b]


@given(p=plasticity_params(), path=plan_paths())
@SETTINGS
def test_plasticity_hysteretic_force_never_leaves_the_yield_circle(p, path):
    """|F - hardening| <= qd on every path: a diagonal push yields at qd / sqrt(2) per axis,
    where two independent springs would carry qd per axis."""
    f = rrfrei.simulate_force("plasticity", p, path)
    k2, k3, mu = p["alpha1"] * p["k_init"], p["alpha2"] * p["k_init"], p["mu"]
    q = f - k2 * path - k3 * np.sign(path) * np.abs(path) ** mu
    assert np.all(np.hypot(*q.T) <= p["qd"] * (1 + 1e-9) + 1e-9 * np.max(np.abs(f)))


def test_a_diagonal_push_yields_at_qd_over_sqrt2_per_axis():
    p = dict(k_init=100.0, qd=2.0, alpha1=0.0, alpha2=0.0, mu=2.0)
    s = np.linspace(0.0, 0.1, 101)[1:]
    f = rrfrei.simulate_force("plasticity", p, np.c_[s, s])
    np.testing.assert_allclose(f[-1], [2.0 / np.sqrt(2), 2.0 / np.sqrt(2)], rtol=1e-15)
    f_two_springs = rrfrei.simulate_force("plasticity", p, s)
    assert f_two_springs[-1] == 2.0


@given(p=plasticity_params(), u=histories(max_size=80), axis=st.sampled_from([0, 1]),
       sign=st.sampled_from([1.0, -1.0]))
@SETTINGS
def test_plasticity_along_one_axis_is_the_unidirectional_law_bit_for_bit(p, u, axis, sign):
    """n = q / |q| = (+-1, 0) exactly and |q| = sqrt(q_x^2) = |q_x|: the same expressions."""
    path = np.zeros((u.size, 2))
    path[:, axis] = sign * u
    f, k = rrfrei.simulate_force("plasticity", p, path, return_tangent=True)
    f1, k1 = rrfrei.simulate_force("plasticity", p, sign * u, return_tangent=True)
    np.testing.assert_array_equal(f[:, axis], f1)
    np.testing.assert_array_equal(k[:, axis, axis], k1)
    assert np.all(f[:, 1 - axis] == 0.0)


@given(p=plasticity_params(), path=plan_paths(), angle=st.floats(0.0, 2 * np.pi))
@SETTINGS
def test_plasticity_without_nonlinear_hardening_is_isotropic(p, path, angle):
    """Rotating the path rotates the force (alpha2 = 0: the yield circle and k2 u are
    isotropic; the k3 term acts per component and is not)."""
    p = {**p, "alpha2": 0.0}
    f = rrfrei.simulate_force("plasticity", p, path)
    f_rot = rrfrei.simulate_force("plasticity", p, rotate(path, angle))
    # rounding: the trial force k0 (u - u_p) cancels, so the error scales with k_init |u| eps
    noise = 1e-12 * np.max(np.abs(f)) + 64 * np.finfo(float).eps * p["k_init"] * np.max(np.abs(path))
    assert np.max(np.abs(rotate(f, angle) - f_rot)) <= noise


@given(p=plasticity_params(), up=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
       u=st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1)))
@SETTINGS
def test_plasticity_tangent_is_the_derivative_of_the_return_mapping(p, up, u):
    """K = dF/du from a committed plastic displacement (central differences), away from the
    yield circle and from u_i = 0 (where |u_i|^mu may be non-smooth)."""
    law = rrfrei.laws.get("plasticity")
    pv = law.pack(p)
    sc = np.array(up)
    u = np.array(u)
    k0 = (1 - p["alpha1"]) * p["k_init"]
    y = k0 * np.hypot(*(u - sc)) - p["qd"]
    assume(abs(y) > 1e-3 * p["qd"] and np.all(np.abs(u) > 1e-4))
    h = 1e-7 * max(np.hypot(*(u - sc)), 1e-3)
    f = np.zeros(2)
    k = np.zeros((2, 2))
    plan_plasticity.step(pv, sc, u, np.zeros(2), 1.0, sc.copy(), f, k)
    kt = k.copy()
    fd = np.zeros((2, 2))
    for j in (0, 1):
        e = np.zeros(2)
        e[j] = h
        fp, fm = np.zeros(2), np.zeros(2)
        plan_plasticity.step(pv, sc, u + e, np.zeros(2), 1.0, sc.copy(), fp, k)
        plan_plasticity.step(pv, sc, u - e, np.zeros(2), 1.0, sc.copy(), fm, k)
        fd[:, j] = (fp - fm) / (2 * h)
    np.testing.assert_allclose(kt, fd, rtol=1e-5, atol=1e-5 * np.max(np.abs(kt)))


# ---------------------------------------------------------------------------- Bouc-Wen

@st.composite
def normalised_bouc_wen_params(draw):
    """Bouc-Wen parameters with beta + gamma = 1 (z saturates at 1: qd is the characteristic
    strength), beta in [0.3, 1.5], eta in [1, 4]."""
    p = draw(plasticity_params())
    beta = draw(st.floats(0.3, 1.5))
    return {**p, "eta": draw(st.floats(1.0, 4.0)), "beta": beta, "gamma": 1.0 - beta}


@given(p=normalised_bouc_wen_params(), ratio=st.floats(3.0, 20.0))
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_bouc_wen_loop_closes_under_a_steady_circular_orbit(p, ratio):
    """Revolution after revolution the force history repeats: the vector z settles on a limit
    cycle (the loop closes), with positive dissipation per revolution."""
    r = ratio * u_y(p)
    assume(r <= 0.5)
    per_rev, revs = 200, 8
    path, start = orbit(r, per_rev, revs)
    f = rrfrei.simulate_force("bouc_wen", p, path)
    loops = f[start + 1:].reshape(revs, per_rev, 2)
    drift = np.max(np.abs(loops[-1] - loops[-2]))
    assert drift <= 1e-9 * np.max(np.abs(f))
    last = slice(start + (revs - 1) * per_rev, None)
    assert line_integral(f[last], path[last]) > 0.0


@given(p=bouc_wen_params(dissipative=True), angle=st.floats(0.0, 2 * np.pi))
@SETTINGS
def test_bouc_wen_push_in_any_direction_is_the_push_along_an_axis_rotated(p, angle):
    """A long monotonic push (60 u_y) in any direction: z points along the push with the
    magnitude it reaches along an axis (towards (beta + gamma)^(-1/eta)), so the hysteretic
    force is bounded by a circle, not a square (alpha2 = 0)."""
    p = {**p, "alpha2": 0.0}
    s = np.linspace(0.0, 60 * u_y(p), 3001)[1:]
    path = np.c_[s * np.cos(angle), s * np.sin(angle)]
    try:
        f = rrfrei.simulate_force("bouc_wen", p, path)
        f1 = rrfrei.simulate_force("bouc_wen", p, s)
    except ValueError:
        assume(False)
    z = (f[-1] - p["alpha1"] * p["k_init"] * path[-1]) / p["qd"]
    z1 = (f1[-1] - p["alpha1"] * p["k_init"] * s[-1]) / p["qd"]
    assert np.hypot(*z) == pytest.approx(abs(z1), rel=1e-9)
    # the angle between z and the push, wrapped to (-pi, pi] (a push at 2 pi has z at -1e-16 rad)
    assert (np.arctan2(z[1], z[0]) - angle + np.pi) % (2 * np.pi) - np.pi == pytest.approx(0.0, abs=1e-9)


@given(p=bouc_wen_params(), u=histories(max_size=80), axis=st.sampled_from([0, 1]),
       sign=st.sampled_from([1.0, -1.0]))
@SETTINGS
def test_bouc_wen_along_one_axis_is_the_unidirectional_law(p, u, axis, sign):
    """Same iteration, same status and failure sample; OpenSees writes the 3-D residual as
    (1/u_y)(A du - z |z|^(eta-2) (z du) s) and the 2-D one as (du/u_y)(A - |z|^eta s), which
    round differently: forces agree to 1e-14 of the peak force, not bit for bit, or to what
    either local Newton pins z to, |dz| < 1e-12 (times qd), whichever is larger.  The second
    term matters only for a peak force near qd 1e-12/1e-14: with eta < 1 the Jacobian is
    singular at z = 0, and a 1e-9 m path (hypothesis: eta = 0.21875, forces ~1e-8 kN)
    converges to the two roundings 5e-14 of the peak apart."""
    path = np.zeros((u.size, 2))
    path[:, axis] = sign * u
    fail = fail1 = -1
    f = f1 = None
    try:
        f = rrfrei.simulate_force("bouc_wen", p, path)
    except NumericalFailure as exc:
        fail = str(exc).split("failed at sample ")[1].split()[0]
    try:
        f1 = rrfrei.simulate_force("bouc_wen", p, sign * u)
    except NumericalFailure as exc:
        fail1 = str(exc).split("failed at sample ")[1].split()[0]
    # eta < 1: the 3-D residual's Jacobian is singular at z = 0, and OpenSees' 3-D Newton fails
    # where the 1-D one converges; the plan law fails with the 3-D element (pinned to openseespy
    # in tests/test_plan_laws_opensees.py, ..._fails_as_opensees_3d_where_the_1d_law_converges)
    assume(not (p["eta"] < 1.0 and fail != -1 and fail1 == -1))
    assert fail == fail1
    if f is not None:
        assert np.all(f[:, 1 - axis] == 0.0)
        scale = np.max(np.abs(f1))
        assert np.max(np.abs(f[:, axis] - f1)) <= max(1e-14 * scale, 1e-12 * p["qd"])


@given(p=bouc_wen_params(dissipative=True), path=plan_paths(), angle=st.floats(0.0, 2 * np.pi))
@SETTINGS
def test_bouc_wen_without_nonlinear_hardening_is_isotropic(p, path, angle):
    """Rotating the path rotates the force (alpha2 = 0): the vector z law has no preferred
    direction (to the rounding of the local Newton solve)."""
    p = {**p, "alpha2": 0.0}
    try:
        f = rrfrei.simulate_force("bouc_wen", p, path)
        f_rot = rrfrei.simulate_force("bouc_wen", p, rotate(path, angle))
    except ValueError:
        assume(False)
    scale = max(np.max(np.abs(f)), 1e-300)
    assert np.max(np.abs(rotate(f, angle) - f_rot)) <= 1e-9 * scale


def test_bouc_wen_keeps_the_previous_force_below_a_dbl_epsilon_increment():
    """OpenSees skips the update while |du| <= DBL_EPSILON (Euclidean norm of the increment)."""
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5)
    path = np.array([[0.01, 0.02], [0.01 + 1e-16, 0.02 - 1e-16]])
    f = rrfrei.simulate_force("bouc_wen", p, path)
    np.testing.assert_array_equal(f[1], f[0])
    assert plan_bouc_wen.DBL_EPSILON == np.finfo(float).eps
