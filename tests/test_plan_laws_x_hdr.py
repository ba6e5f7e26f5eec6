"""Coupled bidirectional ElastomericX and HDR (rrfrei.laws.plan) are OpenSees' 3-D elements.

The peer is the element itself in openseespy 3.7.1, both shear DOFs imposed
(``tests/opensees_plan.py``).  Required: max|F - F_os| / max|F_os| <= 1e-9 (F both components,
the peak over the history) on circular, figure-eight and random two-component paths, and where
ElastomericX's local Newton iteration fails, OpenSees' element reports its failure at the same
sample; the 2x2 tangents are the elements' basic stiffness, quirks included (ElastomericX's
doubled oblique rate, HDR's missing turn of the gap).  Along one axis each plan law is its
unidirectional law bit for bit.  Physics: a
steady circular orbit closes its force loop; the energy it dissipates per revolution is positive
and, well beyond yield, below what two independent springs would claim, tending to pi/4 of it.
"""

import math

import numpy as np
import opensees_plan
import pytest
from _law_strategies import elastomeric_x_params, hdr_params, histories, logu
from _tiers import Tier, run_examples, tiers
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from opensees_plan import _build, _CaptureStderr, check_against_opensees, element_force_and_failure

import rrfrei
from rrfrei.laws import plan
from rrfrei.laws.elastomeric_x import PI_OPENSEES

RTOL = 1e-9
LAWS = ("elastomeric_x", "hdr")
PARAMS = {"elastomeric_x": elastomeric_x_params, "hdr": hdr_params}
FIXED = {
    "elastomeric_x": dict(fy=20.0, alpha=0.08, gr=900.0, d1=0.1, d2=0.6, tr=0.01, n=20.0, tc=0.01,
                          cd=5.0),
    "hdr": dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4,
                c4=5e3),
}
SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                      HealthCheck.function_scoped_fixture])


# --- paths ------------------------------------------------------------------------------------

def circle(r, m, revs, *, center=(0.0, 0.0), phase=0.0, direction=1.0, ramp=1):
    """Ramp from rest in ``ramp`` steps to the circle of radius ``r`` [m] about ``center``, then
    ``revs`` revolutions of ``m`` steps each: (n, 2) [m]."""
    c = np.asarray(center, dtype=float)
    start = c + r * np.array([math.cos(phase), math.sin(phase)])
    a = np.linspace(0.0, 1.0, ramp + 1)[1:, None] * start
    th = phase + direction * 2.0 * np.pi * np.arange(1, m * revs + 1) / m
    return np.r_[a, c + r * np.c_[np.cos(th), np.sin(th)]]


def figure_eight(ax, ay, m, loops, angle=0.0):
    """(ax sin t, ay sin 2t) rotated by ``angle``, ``m`` steps per loop: (n, 2) [m]."""
    t = 2.0 * np.pi * np.arange(1, m * loops + 1) / m
    d = np.c_[ax * np.sin(t), ay * np.sin(2.0 * t)]
    c, s = math.cos(angle), math.sin(angle)
    return d @ np.array([[c, s], [-s, c]])


#: Path angles [rad]: exactly 0, or away from angles whose sine is subnormal (a component of
#: ~1e-310 m makes ElastomericX's r12 = d1/d2 overflow: OpenSees' own tangent is then inf,
#: which rrfrei reports as a non-finite step while openseespy, under imposed displacements,
#: never uses it).  Hypothesis found such a phase (y = 1.1e-310 m at the first sample).
ANGLES = st.just(0.0) | st.floats(1e-9, 2.0 * np.pi)


@st.composite
def circles(draw):
    r = draw(logu(1e-3, 0.06))
    return circle(r, draw(st.integers(6, 120)), draw(st.integers(1, 3)),
                  center=(draw(st.floats(-1.0, 1.0)) * r, draw(st.floats(-1.0, 1.0)) * r),
                  phase=draw(ANGLES), direction=draw(st.sampled_from([1.0, -1.0])),
                  ramp=draw(st.integers(1, 10)))


@st.composite
def figure_eights(draw):
    return figure_eight(draw(logu(1e-3, 0.06)), draw(logu(1e-3, 0.06)), draw(st.integers(8, 120)),
                        draw(st.integers(1, 2)), draw(ANGLES))


@st.composite
def random_paths(draw):
    """Two independent random histories (reversals, repeats, tiny and large increments)."""
    n = draw(st.integers(2, 60))
    return np.c_[draw(histories(min_size=n, max_size=n)), draw(histories(min_size=n, max_size=n))]


PATHS = {"circle": circles, "figure_eight": figure_eights, "random": random_paths}


# --- the two sides ----------------------------------------------------------------------------

def opensees_tangent(ops, law, p, disp):
    """(force (n, 2), tangent (n, 2, 2)) of the OpenSees 3-D element on the model of
    ``tests/opensees_plan.py``; the tangent is the element's basic shear stiffness
    (``eleResponse(tag, "basicStiff")``: kb22, kb23, kb32, kb33, ElastomericX.cpp and HDR.cpp
    ``setResponse``), i.e. dF_i/du_j in the harness orientation (basic y, z = global X, Y)."""
    _build(ops, law, p, disp)
    force = np.full(disp.shape, np.nan)
    tangent = np.full((disp.shape[0], 2, 2), np.nan)
    with _CaptureStderr():
        for i in range(disp.shape[0]):
            assert ops.analyze(1) == 0
            force[i] = ops.eleResponse(1, "force")[6:8]
            tangent[i] = np.reshape(ops.eleResponse(1, "basicStiff"), (2, 2))
        ops.wipe()
    return force, tangent


TANGENT_RTOL = {"elastomeric_x": 1e-7, "hdr": RTOL}
"""ElastomericX: OpenSees' global Newton calls ``update()`` twice per step here (imposed
displacement, then the correction) and each call runs the local Newton again from the previous
trial z, moving z within the local tolerance 1e-8; the tangent's (1 - z^2 t)/u_y amplifies that
(1.4e-9 seen with u_y = 2e-8 m), the force does not (4e-21).  Called twice, ours is OpenSees'
tangent bit for bit (``test_elastomeric_x_tangent_is_opensees_with_its_second_update``)."""


def _tangent_deviates(law: str, disp) -> np.ndarray:
    """Samples where the law's tangent deviates from OpenSees' by its documented rule: for
    ElastomericX, an increment component below 1/RATIO_MAX of the other is taken as zero
    (``rrfrei.laws.plan.elastomeric_x``: OpenSees' tangent there is beyond 1e100 kN/m, inf or
    nan).  The tangent of a sample depends on its own increment only, so the others compare."""
    d = np.diff(np.asarray(disp, dtype=float), axis=0, prepend=0.0)
    if law != "elastomeric_x":
        return np.zeros(len(d), dtype=bool)
    from rrfrei.laws.plan.elastomeric_x import RATIO_MAX

    a, b = np.abs(d[:, 0]), np.abs(d[:, 1])
    both = (a * b) != 0.0
    with np.errstate(divide="ignore", over="ignore"):
        return both & ((a > RATIO_MAX * b) | (b > RATIO_MAX * a))


def check_tangent_against_opensees(ops, law, p, disp):
    """Forces equal to 1e-9 and tangents (dF_i/du_j) to TANGENT_RTOL of their peaks (the samples
    of a documented deviation: finite there, and left out of the comparison)."""
    f, k = rrfrei.simulate_force(law, p, disp, return_tangent=True)
    f_os, k_os = opensees_tangent(ops, law, p, disp)
    assert np.max(np.abs(f - f_os)) <= RTOL * np.max(np.abs(f_os))
    dev = _tangent_deviates(law, disp)
    assert np.all(np.isfinite(k[dev]))
    keep = ~dev
    err = np.max(np.abs(k[keep] - k_os[keep])) / np.max(np.abs(k_os[keep]))
    assert err <= TANGENT_RTOL[law], f"max relative tangent error {err:.3g}"


# --- the peer ---------------------------------------------------------------------------------

def test_plan_laws_are_registered_with_their_opensees_element():
    assert plan.get("elastomeric_x").opensees_element == "ElastomericX"
    assert plan.get("hdr").opensees_element == "HDR"
    for law in LAWS:
        assert plan.get(law).law is rrfrei.laws.get(law)


@pytest.mark.opensees
@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("path", [
    circle(0.04, 100, 2, center=(-0.01, 0.005), ramp=5),
    figure_eight(0.05, 0.03, 150, 2),
    np.cumsum(np.random.default_rng(1).normal(0.0, 0.004, (300, 2)), axis=0),
], ids=["circle", "figure_eight", "random_walk"])
def test_fixed_paths_equal_opensees(ops, law, path):
    check_against_opensees(ops, law, FIXED[law], path)


@pytest.mark.opensees
@pytest.mark.parametrize("tier", tiers(Tier(60), Tier(500)))
@pytest.mark.parametrize("kind", list(PATHS))
@pytest.mark.parametrize("law", LAWS)
def test_hypothesis_paths_equal_opensees(ops, law, kind, tier):
    run_examples(tier, lambda p, d: check_against_opensees(ops, law, p, d), p=PARAMS[law](),
                 d=PATHS[kind]())


@pytest.mark.opensees
@pytest.mark.parametrize("law", LAWS)
def test_tangent_is_the_elements_basic_stiffness(ops, law):
    """The 2x2 tangent, off-diagonal terms included (ElastomericX's is far from symmetric)."""
    d = np.cumsum(np.random.default_rng(1).normal(0.0, 0.004, (60, 2)), axis=0)
    d[10:13, 1] = d[9, 1]  # x-only increments: ElastomericX's r12 = r21 = 0 branch
    check_tangent_against_opensees(ops, law, FIXED[law], d)


@pytest.mark.opensees
@pytest.mark.parametrize("law", LAWS)
@given(data=st.data())
@settings(max_examples=15, **SETTINGS)
def test_hypothesis_tangents_equal_opensees(ops, law, data):
    check_tangent_against_opensees(ops, law, data.draw(PARAMS[law]()),
                                   data.draw(st.one_of(random_paths(), circles())))


@pytest.mark.opensees
def test_elastomeric_x_tangent_deviates_from_opensees_only_where_a_component_is_below_1e100_of_the_other(ops):
    """Hypothesis's circle whose first point has y = 4.2e-278 of x = 0.01: OpenSees' tangent there
    is ~1e277 kN/m (a Newmark step on it overflows, ``test_plan_building.py``); ours takes that
    component as zero.  Every other sample equals OpenSees'."""
    p = dict(fy=1.0, alpha=0.5, gr=100.0, d1=0.0, d2=1.0, tr=0.01, n=1.0, tc=0.0, cd=0.0)
    c, s_ = np.cos(np.arange(7) * np.pi / 3), np.sin(np.arange(7) * np.pi / 3)
    disp = 0.01 * np.c_[c, s_]
    disp[0, 1] = 4.21971275e-278
    dev = _tangent_deviates("elastomeric_x", disp)
    assert dev.tolist() == [True] + [False] * 6
    _, k = rrfrei.simulate_force("elastomeric_x", p, disp, return_tangent=True)
    _, k_os = opensees_tangent(ops, "elastomeric_x", p, disp)
    assert np.max(np.abs(k_os[0])) > 1e270 and np.max(np.abs(k[0])) < 1e6
    check_tangent_against_opensees(ops, "elastomeric_x", p, disp)


@pytest.mark.opensees
def test_elastomeric_x_tangent_is_opensees_with_its_second_update(ops):
    """Run the step twice per sample from the same committed state, as OpenSees' Newton runs
    ``update()`` in this harness: the tangent is then OpenSees' bit for bit (once: 9e-13)."""
    p = dict(fy=1.0, alpha=0.015625, gr=1000.0, d1=0.0, d2=1.0, tr=0.001, n=1.0, tc=0.0, cd=0.0)
    d = figure_eight(0.01, 0.03, 40, 2)
    spec = plan.get("elastomeric_x")
    pp = spec.law.pack(p)
    sc = np.array(spec.initial_state)
    st_ = sc.copy()
    f, k = np.zeros(2), np.zeros((2, 2))
    tangent = np.empty((len(d), 2, 2))
    for i, u in enumerate(d):
        for _ in range(2):
            assert spec.step(pp, sc, u, np.zeros(2), 1.0, st_, f, k) == 0
        tangent[i] = k
        sc[:] = st_
    _, k_os = opensees_tangent(ops, "elastomeric_x", p, d)
    np.testing.assert_array_equal(tangent, k_os)
    _, k_once = rrfrei.simulate_force("elastomeric_x", p, d, return_tangent=True)
    assert 0.0 < np.max(np.abs(k_once - k_os)) <= TANGENT_RTOL["elastomeric_x"] * np.max(np.abs(k_os))


# positions in the element argument lists (tests/opensees_harness.py) of the vertical, torsional
# and rotational constants (tags 1-4 of ElastomericX stay 0: the law assumes the defaults)
VERTICAL = {
    "elastomeric_x": {7: 4.0e6, 10: 0.003, 19: 3.0, 20: 0.2, 21: 2.0, 22: 0.3},  # Kbulk ts kc PhiM ac sD
    "hdr": {4: 900.0, 5: 4.0e6, 6: 0.05, 7: 0.5, 8: 0.003, 9: 0.008, 10: 12.0, 27: 3.0, 28: 0.2,
            29: 2.0, 30: 0.3},  # Gr Kbulk D1 D2 ts tr n kc PhiM ac sD
}


@pytest.mark.opensees
@pytest.mark.parametrize("law", LAWS)
def test_the_harness_vertical_constants_do_not_enter_the_shear_law(ops, law, monkeypatch):
    """Other rubber bulk modulus, shims, cavitation, damage and shear-distance constants (and
    HDR's geometry, which sets only its vertical terms) leave OpenSees' shear forces unchanged,
    also on an orbit wider than HDR's diameter (acos(|U|/D2) is NaN there, unused)."""
    d = circle(0.4, 60, 2, ramp=8)
    f_os, n_ok, _ = element_force_and_failure(ops, law, FIXED[law], d)
    assert n_ok == len(d)
    plain = opensees_plan._plan_element_args

    def other_vertical(law_, p):
        args = plain(law_, p)
        for i, value in VERTICAL[law_].items():
            args[i] = value
        return args

    monkeypatch.setattr(opensees_plan, "_plan_element_args", other_vertical)
    f_other, _, _ = element_force_and_failure(ops, law, FIXED[law], d)
    np.testing.assert_array_equal(f_other, f_os)
    check_against_opensees(ops, law, FIXED[law], d)


@pytest.mark.opensees
def test_a_sharp_turn_defeats_elastomeric_x_newton_at_the_same_sample_as_opensees(ops):
    """Loaded along y (z = (0, ~1)), a huge x increment starts the x component of z at exactly
    0: the first Newton step jumps to z_x = d_x/u_y (1e29 here, u_y = 1e-30 m at the parameter
    bounds) and the quadratic return needs more than the element's 100 iterations."""
    p = dict(fy=1e-9, alpha=1e-4, gr=1e8, d1=0.0, d2=100.0, tr=1e-5, n=1.0, tc=10.0, cd=0.0)
    disp = np.array([[0.0, 1e-3], [0.0, 2e-3], [1.0, 2e-3]])
    with pytest.raises(ValueError, match=r"failed at sample 2 .*did not converge; committed state"):
        rrfrei.simulate_force("elastomeric_x", p, disp)
    check_against_opensees(ops, "elastomeric_x", p, disp)
    # the same increment along the loaded direction converges in both
    check_against_opensees(ops, "elastomeric_x", p, np.array([[0.0, 1e-3], [0.0, 2e-3], [0.0, 1.0]]))


# --- one axis is the unidirectional law -------------------------------------------------------

@pytest.mark.parametrize("law", LAWS)
@given(data=st.data())
@settings(max_examples=40, **SETTINGS)
def test_a_path_along_one_axis_is_the_unidirectional_law_bit_for_bit(law, data):
    p = data.draw(PARAMS[law]())
    u = data.draw(histories(max_size=80))
    axis = data.draw(st.sampled_from([0, 1]))
    time = np.cumsum(data.draw(st.lists(logu(1e-3, 0.1), min_size=u.size, max_size=u.size))) \
        if data.draw(st.booleans()) else None
    d = np.zeros((u.size, 2))
    d[:, axis] = u
    f, k = rrfrei.simulate_force(law, p, d, time=time, return_tangent=True)
    f1, k1 = rrfrei.simulate_force(law, p, u, time=time, return_tangent=True)
    np.testing.assert_array_equal(f[:, axis], f1)
    np.testing.assert_array_equal(f[:, 1 - axis], 0.0)
    np.testing.assert_array_equal(k[:, axis, axis], k1)
    np.testing.assert_array_equal(k[:, 0, 1], 0.0)
    np.testing.assert_array_equal(k[:, 1, 0], 0.0)


@given(p=elastomeric_x_params(), d=random_paths())
@settings(max_examples=25, **SETTINGS)
def test_elastomeric_x_tangent_counts_the_park_wen_rate_twice_on_oblique_increments(p, d):
    """OpenSees' dz/du (ratios r12 = d1/d2, r21 = d2/d1) applied to the increment d gives
    (1/u_y)(d - z t3) when d1 d2 == 0 but twice that otherwise: an element quirk kept, since the
    tangent steers the global Newton iteration of a building model (OpenSees' does the same)."""
    spec = plan.get("elastomeric_x")
    pp = spec.law.pack(p)
    fy, cd = p["fy"], p["cd"]
    uy = _elastomeric_x_uy(p)
    ke = fy / uy / (1.0 / p["alpha"] - 1.0)
    sc = np.array(spec.initial_state)
    st_ = sc.copy()
    f, k = np.zeros(2), np.zeros((2, 2))
    for u in d:
        inc = u - sc[:2]
        assert spec.step(pp, sc, u, np.zeros(2), 1.0, st_, f, k) == 0
        if np.any(inc != 0.0):
            z = st_[2:4]
            t = 0.1 + 0.9 * np.sign(z * inc)
            rate = fy / uy * (inc - z * np.sum(z * inc * t))
            factor = 2.0 if inc[0] * inc[1] != 0.0 else 1.0
            np.testing.assert_allclose(k @ inc - (ke + cd) * inc, factor * rate, rtol=1e-9,
                                       atol=1e-9 * np.max(np.abs(ke * inc)))
        sc[:] = st_


def test_hdr_tangent_omits_the_turn_of_the_gap_as_opensees_does():
    """HDR.cpp's "consistent" tangent holds Delta_C = |R_C n - F2_C| fixed although n turns
    with U in plan (exact in 1-D, where n = +-1): the step's central-difference derivative
    differs from it by O(1) on a random walk, and equals it once -mu (x) dDelta_C/dU / (1 + b3 dU)
    is added (c4 = 0, so the element's dKM/dDM typo is silent)."""
    p = dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4, c4=0.0)
    spec = plan.get("hdr")
    pp = spec.law.pack(p)
    sc = np.array(spec.initial_state)
    st_ = sc.copy()
    f, k, scratch = np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2))
    worst_element, worst_completed = 0.0, 0.0
    for u in np.cumsum(np.random.default_rng(3).normal(0.0, 0.01, (40, 2)), axis=0):
        before = st_.copy()
        assert spec.step(pp, sc, u, np.zeros(2), 1.0, st_, f, k) == 0
        h = 1e-7 * max(1e-3, np.max(np.abs(u - sc[:2])))
        fd = np.zeros((2, 2))
        for j in range(2):
            e = h * np.eye(2)[j]
            fp, fm = np.zeros(2), np.zeros(2)
            spec.step(pp, sc, u + e, np.zeros(2), 1.0, before.copy(), fp, scratch)
            spec.step(pp, sc, u - e, np.zeros(2), 1.0, before.copy(), fm, scratch)
            fd[:, j] = (fp - fm) / (2.0 * h)
        du = np.linalg.norm(u - sc[:2])
        n = (u - sc[:2]) / du
        r_c = p["b1"] + math.exp(-p["c2"] * sc[6] ** 3) * p["b2"] * (sc[0] ** 2 + sc[1] ** 2)
        gap = r_c * n - sc[2:4]
        d_delta_c = gap / np.linalg.norm(gap) @ (r_c * (np.eye(2) - np.outer(n, n)) / du)
        r = p["b1"] + math.exp(-p["c2"] * st_[6] ** 3) * p["b2"] * (u @ u)
        mu = (r * n - sc[2:4]) / np.linalg.norm(r * n - sc[2:4])
        completed = k - np.outer(mu, d_delta_c) / (1.0 + p["b3"] * du)
        worst_element = max(worst_element, np.max(np.abs(fd - k)) / np.max(np.abs(fd)))
        worst_completed = max(worst_completed, np.max(np.abs(fd - completed)) / np.max(np.abs(fd)))
        sc[:] = st_
    assert worst_element > 0.5
    assert worst_completed < 1e-6


# --- symmetry ---------------------------------------------------------------------------------

@pytest.mark.parametrize("law", LAWS)
@given(data=st.data())
@settings(max_examples=25, **SETTINGS)
def test_swapping_or_mirroring_the_axes_swaps_or_mirrors_the_forces_exactly(law, data):
    """Both elements treat x and y alike and are odd in each axis (the square's symmetries)."""
    p = data.draw(PARAMS[law]())
    d = data.draw(st.one_of(random_paths(), figure_eights()))
    f = rrfrei.simulate_force(law, p, d)
    np.testing.assert_array_equal(rrfrei.simulate_force(law, p, d[:, ::-1]), f[:, ::-1])
    mirror = np.array([-1.0, 1.0])
    np.testing.assert_array_equal(rrfrei.simulate_force(law, p, d * mirror), f * mirror)


@given(p=hdr_params(), d=st.one_of(random_paths(), circles()), angle=st.floats(0.0, 2.0 * np.pi))
@settings(max_examples=25, **SETTINGS)
def test_hdr_is_isotropic_rotating_the_path_rotates_the_forces(p, d, angle):
    """HDR's law is written in vector norms: a circular bounding surface, radial damage."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, s], [-s, c]])  # row vectors: d @ rot rotates by -angle
    f = rrfrei.simulate_force("hdr", p, d)
    f_rot = rrfrei.simulate_force("hdr", p, d @ rot)
    assert np.max(np.abs(f_rot - f @ rot)) <= 1e-9 * np.max(np.abs(f))


@given(p=elastomeric_x_params(), u=st.lists(logu(1e-5, 0.01), min_size=1, max_size=30),
       angle=st.just(0.0) | st.floats(1e-9, 2.0 * np.pi))  # not 1e-308: r12 = d1/d2 overflows
@settings(max_examples=25, **SETTINGS)
def test_elastomeric_x_pushed_along_any_ray_yields_as_along_an_axis(p, u, angle):
    """Monotonic loading from rest along a ray: every z_i d_i >= 0, so the sign terms are all 1
    and the yield surface is the circle |z| = 1 whatever the direction (Park et al. 1986)."""
    r = np.cumsum(u)
    e = np.array([math.cos(angle), math.sin(angle)])
    f = rrfrei.simulate_force("elastomeric_x", p, r[:, None] * e)
    f1 = rrfrei.simulate_force("elastomeric_x", p, r)
    scale = np.max(np.abs(f1))
    np.testing.assert_allclose(f @ e, f1, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(f @ np.array([-e[1], e[0]]), 0.0, rtol=0, atol=1e-12 * scale)


def test_elastomeric_x_is_not_isotropic_on_a_figure_eight():
    """Its sign terms act per axis: a rotated figure-eight gives another response (a fact of the
    element, not of this port; HDR's above is exact)."""
    p = FIXED["elastomeric_x"]
    d = figure_eight(0.02, 0.015, 200, 2)
    angle = np.pi / 6
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, s], [-s, c]])
    f = rrfrei.simulate_force("elastomeric_x", p, d)
    f_rot = rrfrei.simulate_force("elastomeric_x", p, d @ rot)
    assert np.max(np.abs(f_rot - f @ rot)) > 1e-3 * np.max(np.abs(f))


# --- steady circular orbit: closure and dissipated energy -------------------------------------

M, REVS, RAMP = 720, 5, 20  # steps per revolution, revolutions, ramp steps to the circle


def _loop_work(f, d):
    """Work done on the bearing around the path, trapezoidal in the displacement [kN m]."""
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(d, axis=0)))


def _orbit_energies(law, p, r):
    """(W_plan, W_independent, closure) on the last revolution of a steady orbit of radius r.

    W_independent: the unidirectional law driven separately by the x and the y component (two
    independent springs).  closure: max |F(last revolution) - F(the one before)| / max |F|."""
    d = circle(r, M, REVS, ramp=RAMP)
    last = slice(RAMP + M * (REVS - 1) - 1, RAMP + M * REVS)
    prev = slice(RAMP + M * (REVS - 2) - 1, RAMP + M * (REVS - 1))
    f = rrfrei.simulate_force(law, p, d)
    w_plan = _loop_work(f[last], d[last])
    w_ind = sum(_loop_work(rrfrei.simulate_force(law, p, d[:, a])[last], d[last, a]) for a in (0, 1))
    return w_plan, w_ind, np.max(np.abs(f[last] - f[prev])) / np.max(np.abs(f))


def _elastomeric_x_uy(p):
    area = PI_OPENSEES / 4.0 * ((p["d2"] + p["tc"]) ** 2 - p["d1"] ** 2)
    ke = p["gr"] * area / (p["n"] * p["tr"])
    return p["fy"] / ((1.0 / p["alpha"] - 1.0) * ke)


def _elastoplastic_ratio(x):
    """W_plan / W_independent of the coupled elastoplastic law at r = x u_y (issue 14):
    2 pi qd sqrt(r^2 - u_y^2) / (8 qd (r - u_y)) = (pi/4) sqrt((x + 1)/(x - 1))."""
    return math.pi / 4.0 * math.sqrt((x + 1.0) / (x - 1.0))


@pytest.mark.parametrize("x, ratio", [(2.0, 1.266), (5.0, 0.947), (20.0, 0.823), (100.0, 0.793)])
def test_elastomeric_x_orbit_closes_and_dissipates_like_a_circular_yield_surface(x, ratio):
    """Measured W_plan / W_independent at r = x u_y: 1.266, 0.947, 0.823, 0.793 (720 steps per
    revolution).  Beyond about 4 u_y the orbit dissipates less than two independent springs
    claim, tending to pi/4 as the elastoplastic closed form (pi/4) sqrt((x+1)/(x-1)) does (0.4 %
    from it at 20 u_y); near yield it dissipates more, as that closed form also says (an orbit
    keeps the hysteresis engaged where an axis cycle of the same amplitude barely yields)."""
    p = dict(FIXED["elastomeric_x"], cd=0.0)
    w_plan, w_ind, closure = _orbit_energies("elastomeric_x", p, x * _elastomeric_x_uy(p))
    assert closure <= 1e-10
    assert w_plan > 0.0
    assert w_plan / w_ind == pytest.approx(ratio, abs=1e-3)
    if x >= 5.0:
        assert math.pi / 4.0 < w_plan / w_ind < 1.0
        assert w_plan / w_ind == pytest.approx(_elastoplastic_ratio(x), rel=0.02)


@pytest.mark.parametrize("r, ratio", [(0.01, 1.372), (0.05, 0.891), (0.2, 0.812)])
def test_hdr_orbit_closes_and_its_dissipation_tends_to_pi_over_4_of_independent_springs(r, ratio):
    """Undamaged HDR (c1 = c2 = c4 = 0), bounding surface b1 = 0.8 kN, b3 = 150 /m: measured
    W_plan / W_independent = 1.372, 0.891, 0.812 at r = 0.01, 0.05, 0.2 m; the hysteretic force
    saturates on the circle |F2| = R, so the ratio tends to 2 pi r R / (8 r R) = pi/4 as b3 r
    grows."""
    p = dict(a1=60.0, a2=0.0, a3=0.0, b1=0.8, b2=0.0, b3=150.0, c1=0.0, c2=0.0, c3=1.0, c4=0.0)
    w_plan, w_ind, closure = _orbit_energies("hdr", p, r)
    assert closure <= 1e-10
    assert w_plan > 0.0
    assert w_plan / w_ind == pytest.approx(ratio, abs=1e-3)
    if r >= 0.05:
        assert math.pi / 4.0 < w_plan / w_ind < 1.0


def test_a_centred_orbit_never_scrags_hdr_its_damage_follows_only_the_radius():
    """HDR's scragging and Mullins trackers see only |U|, constant on an orbit about the origin:
    the orbit keeps the virgin strength while the two axis cycles of the same amplitude are
    damaged, so with damage the orbit dissipates *more* than two independent springs claim."""
    p = FIXED["hdr"]
    w_plan, w_ind, closure = _orbit_energies("hdr", p, 0.05)
    undamaged = dict(p, c1=0.0, c2=0.0, c4=0.0)
    w_plan0, _, _ = _orbit_energies("hdr", undamaged, 0.05)
    assert closure <= 1e-10
    assert w_plan == pytest.approx(w_plan0, rel=1e-9)
    assert w_plan > w_ind


@pytest.mark.parametrize("fy, alpha, gr, d2, tr, n", [
    (1.0, 0.05, 500.0, 0.3, 0.005, 20.0),
    # r12 = 9e307 is finite but fy dz/du overflows (hypothesis found this one too)
    (100.0, 0.5, 100.0, 0.1, 0.01, 1.0),
])
def test_a_subnormal_component_leaves_elastomeric_x_finite_with_the_force_of_a_zero_one(fy, alpha, gr, d2,
                                                                                         tr, n):
    """A component of 1e-310 m (OpenSees' r12 = d1/d2 overflows, or the tangent built from it, to
    an infinite tangent) is the exact zero it is physically: the step succeeds, its force is the
    force with that component 0 to rounding, and its tangent is finite (hypothesis found these
    paths: y = 1.1e-310 m)."""
    p = {"fy": fy, "alpha": alpha, "gr": gr, "d1": 0.0, "d2": d2, "tr": tr, "n": n, "tc": 0.0, "cd": 0.0}
    d = np.array([[0.01, 2.2e-315], [0.02, 1.1e-310], [0.015, 0.0]])
    f, k = rrfrei.simulate_force("elastomeric_x", p, d, return_tangent=True)
    f0 = rrfrei.simulate_force("elastomeric_x", p, np.c_[d[:, 0], np.zeros(3)])
    assert np.all(np.isfinite(k))
    np.testing.assert_allclose(f, f0, rtol=0, atol=1e-12 * np.max(np.abs(f0)))
