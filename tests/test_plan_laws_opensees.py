"""Differential tests: every coupled bidirectional law equals openseespy 3.7.1's 3-D element.

The peer is the element itself under two-component displacement control
(:mod:`tests.opensees_plan`).  Required: max |F - F_os| / max |F_os| <= 1e-9 (largest force
component error over the history, relative to the peak force component of the history) on
circular orbits, figure-eights and random two-component paths; and where a law's local Newton
fails, OpenSees' element reports its failure (``update()`` warning) at the same sample.

The laws under test are those of :func:`rrfrei.laws.plan.names` with an OpenSees element that
:data:`tests.opensees_plan.PLAN_LAWS` can build; each needs a parameter strategy in
:data:`PLAN_PARAMS` (a law without one is skipped, with the reason).
"""


import numpy as np
import pytest
from _law_strategies import (
    _INCREMENT,
    bouc_wen_params,
    elastomeric_x_params,
    hdr_params,
    plasticity_params,
)
from _tiers import Tier, run_examples, tiers
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from opensees_harness import spurious_cut
from opensees_plan import (
    PLAN_LAWS,
    check_against_opensees,
    element_force,
    element_force_and_failure,
    element_force_recorder,
    rrfrei_force_and_failure,
)

import rrfrei
from rrfrei.errors import NumericalFailure
from rrfrei.laws import plan

pytestmark = pytest.mark.opensees
RTOL = 1e-9

PLAN_PARAMS = {
    "plasticity": plasticity_params,
    "bouc_wen": bouc_wen_params,
    "elastomeric_x": elastomeric_x_params,
    "hdr": hdr_params,
}
"""Parameter strategy per plan law (the unidirectional laws' strategies: same parameters)."""

LAWS = [name for name in plan.names() if plan.get(name).opensees_element and name in PLAN_LAWS]


LAW_PARAMS = LAWS


def test_every_plan_law_with_an_opensees_element_is_compared_here():
    """Each 3-D element of the harness has its plan law, and each has a parameter strategy: a
    new plan law cannot slip past the differential tests."""
    assert sorted(LAWS) == sorted(PLAN_LAWS)
    assert set(LAWS) <= set(PLAN_PARAMS)


# ---------------------------------------------------------------------------- paths [m]

@st.composite
def circles(draw):
    """Circular orbits from rest: radius 1 mm - 8 cm, 8-60 samples per revolution, 1-3
    revolutions, either sense, any starting angle (the first sample jumps onto the circle)."""
    r = draw(st.floats(1e-3, 0.08))
    per_rev = draw(st.integers(8, 60))
    revs = draw(st.integers(1, 3))
    phase = draw(st.floats(0.0, 2 * np.pi))
    sense = draw(st.sampled_from([1.0, -1.0]))
    t = phase + sense * 2 * np.pi * np.arange(1, per_rev * revs + 1) / per_rev
    return np.c_[r * np.cos(t), r * np.sin(t)]


@st.composite
def figure_eights(draw):
    """Figure-eights (a sin t, b sin 2t) rotated by any angle, 1-2 loops, ramped in."""
    a = draw(st.floats(1e-3, 0.08))
    b = draw(st.floats(0.1, 1.0)) * a
    n = draw(st.integers(12, 60))
    loops = draw(st.integers(1, 2))
    th = draw(st.floats(0.0, np.pi))
    t = 2 * np.pi * np.arange(1, n * loops + 1) / n
    ramp = np.minimum(1.0, t / (2 * np.pi))
    x, y = ramp * a * np.sin(t), ramp * b * np.sin(2 * t)
    c, s = np.cos(th), np.sin(th)
    return np.c_[c * x - s * y, s * x + c * y]


@st.composite
def plan_histories(draw, max_size=60, limit=0.06):
    """Random two-component histories from rest: each component's increments repeated (0), tiny,
    ordinary or large, of random sign, clipped to +- ``limit``; sometimes one component held."""
    steps = draw(st.lists(st.tuples(_INCREMENT, st.booleans(), _INCREMENT, st.booleans()),
                          min_size=2, max_size=max_size))
    d = np.array([[dx if sx else -dx, dy if sy else -dy] for dx, sx, dy, sy in steps])
    held = draw(st.sampled_from([None, None, None, 0, 1]))
    if held is not None:
        d[:, held] = 0.0
    return np.clip(np.cumsum(d, axis=0), -limit, limit)


PATHS = {"circle": circles, "figure_eight": figure_eights, "random": plan_histories}


# ---------------------------------------------------------------------------- tests

PROTOCOL_PARAMS = {
    "plasticity": dict(k_init=3e4, qd=40.0, alpha1=0.02, alpha2=0.2, mu=2.7),
    "bouc_wen": dict(k_init=2e3, qd=5.0, alpha1=0.05, alpha2=0.05, mu=1.5, eta=1.37, beta=0.8,
                     gamma=-0.3),
}


@pytest.mark.parametrize("law", [law for law in LAWS if law in PROTOCOL_PARAMS])
@pytest.mark.parametrize("path", ["circle", "figure_eight", "diagonal", "spiral"])
def test_fixed_orbits_equal_opensees(ops, law, path):
    """Long, finely sampled orbits (several revolutions, growing and shrinking)."""
    t = np.linspace(0.0, 6 * np.pi, 601)[1:]
    env = 0.08 * np.sin(t / 6) ** 2 + 0.002
    disp = {
        "circle": np.c_[0.05 * np.cos(t), 0.05 * np.sin(t)],
        "figure_eight": np.c_[0.06 * np.sin(t), 0.03 * np.sin(2 * t)],
        "diagonal": np.c_[0.05 * np.sin(t), 0.05 * np.sin(t)] * [1.0, -0.7],
        "spiral": np.c_[env * np.cos(3 * t), env * np.sin(3 * t)],
    }[path]
    check_against_opensees(ops, law, PROTOCOL_PARAMS[law], disp)


@pytest.mark.parametrize("law", [law for law in LAWS if law in PROTOCOL_PARAMS])
def test_recorder_fast_path_equals_step_by_step_harness(ops, law):
    """The benchmark's one-analyze() recorder path returns the same forces (17 digits)."""
    t = np.linspace(0.0, 4 * np.pi, 301)[1:]
    disp = np.c_[0.05 * np.sin(t), 0.03 * np.sin(2 * t)]
    f_step, n_ok = element_force(ops, law, PROTOCOL_PARAMS[law], disp)
    assert n_ok == disp.shape[0]
    np.testing.assert_allclose(element_force_recorder(ops, law, PROTOCOL_PARAMS[law], disp), f_step,
                               rtol=1e-15, atol=0)


@pytest.mark.parametrize("tier", tiers(Tier(40), Tier(150, max_size=300)))
@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize("law", LAW_PARAMS)
def test_random_paths_equal_opensees(ops, law, path, tier):
    """Hypothesis orbits, figure-eights and random histories (up to ``tier.max_size`` samples)."""
    disp = plan_histories(max_size=tier.max_size) if path == "random" else PATHS[path]()
    run_examples(tier, lambda p, d: check_against_opensees(ops, law, p, d), p=PLAN_PARAMS[law](),
                 d=disp)


def test_bouc_wen_local_newton_failure_matches_opensees(ops):
    """A diagonal step far beyond u_y with a steep exponent defeats the 25-iteration Newton on
    the two-component z in both, at the same sample."""
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=9.181247277429936,
             beta=0.1979643833210143, gamma=0.28589263260021625)
    disp = np.array([[0.001, 0.0005], [0.002, 0.001], [-0.169674, -0.12]])
    f, fail = rrfrei_force_and_failure("bouc_wen", p, disp)
    _, _, fail_os = element_force_and_failure(ops, "bouc_wen", p, disp)
    assert fail == fail_os == 2


def test_bouc_wen_from_rest_with_eta_below_one_fails_as_opensees_3d_where_the_1d_law_converges(ops):
    """With eta < 1 the 3-D residual's term z |z|^(eta - 2) (z du) has a singular Jacobian at z = 0:
    OpenSees' 3-D element reports its local Newton failed on the first step from rest along one
    axis, and the plan law fails there too, while the 1-D law (the 2-D element's residual
    (du/u_y)(A - |z|^eta s)) converges.  Found by hypothesis in
    tests/test_plan_laws_physics.py::test_bouc_wen_along_one_axis_is_the_unidirectional_law."""
    p = {"k_init": 21.69573086215917, "qd": 1.0, "alpha1": 0.515625, "alpha2": 0.0, "mu": 1.0,
         "eta": 0.25, "beta": 0.5078125, "gamma": 2.0}
    disp = np.array([[0.0, 0.0], [-0.03125, 0.0]])
    _, fail = rrfrei_force_and_failure("bouc_wen", p, disp)
    _, _, fail_os = element_force_and_failure(ops, "bouc_wen", p, disp)
    assert fail == fail_os == 1
    f1 = rrfrei.simulate_force("bouc_wen", p, disp[:, 0])
    assert np.all(np.isfinite(f1))


def test_bouc_wen_step_onto_a_spurious_root_is_where_the_comparison_stops(ops):
    """One step drives z from 0 to 2633 (eta 0.375): a root of the backward-Euler equation far
    beyond the bound |z| <= (beta + gamma)^(-1/eta) = 0.19, where a physical step cannot go.
    OpenSees' first update() converges there in 12 iterations and its second oscillates between
    two doubles 3 ulp apart (|dz| = 1.5e-12 > tol) until iter 25; ours, rounding differently,
    settles on that root.  Which of the two happens is decided by the last bit, so the
    differential tests compare up to such a sample (``spurious_cut``): here sample 1, with
    sample 0 equal."""
    p = dict(k_init=10**4.5, qd=1.0, alpha1=0.0, alpha2=0.0, mu=1.0, eta=0.375, beta=0.34375,
             gamma=1.5078125)
    disp = np.array([[0.0, 0.0], [0.0, -0.00390625]])
    f_os, _, fail_os = element_force_and_failure(ops, "bouc_wen", p, disp)
    assert fail_os == 1
    f, fail = rrfrei_force_and_failure("bouc_wen", p, disp)
    assert fail == -1 and np.array_equal(f[0], f_os[0])
    z_max = (p["beta"] + p["gamma"]) ** (-1.0 / p["eta"])
    assert np.hypot(*f[1]) / p["qd"] > 1e4 * z_max  # ours: the spurious root, as OpenSees' first call
    assert spurious_cut("bouc_wen", p, disp, f_os, fail_os,
                        lambda d: rrfrei_force_and_failure("bouc_wen", p, d)) == 1


def test_bouc_wen_forces_equal_opensees_to_rounding(ops):
    """With OpenSees' iteration and its two update() calls per step, the forces of a long
    figure-eight with growing amplitude (the benchmark's path, 1,500 steps) are openseespy's to
    rounding at every sample: within 1e-14 of the peak force.  (Its powers are Taylor-updated
    near convergence and its 2x2 solve is Cramer's rule, each good to a few ulp, where OpenSees
    calls ``pow`` and LAPACK: measured 3.4e-16 on the 5,000-step benchmark path.)"""
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.37, beta=0.6, gamma=0.4)
    k = np.arange(1, 1501)
    amp = 0.002 + 0.038 * k / k.size
    disp = np.c_[amp * np.sin(2 * np.pi * k / 200), 0.8 * amp * np.sin(2 * np.pi * k / 150 + 0.7)]
    f, fail = rrfrei_force_and_failure("bouc_wen", p, disp)
    assert fail == -1
    f_os = element_force_recorder(ops, "bouc_wen", p, disp)
    err = np.max(np.abs(f - f_os)) / np.max(np.abs(f_os))
    assert err <= 1e-14, f"{err:.2e} of the peak; {np.sum(np.any(f != f_os, axis=1))} samples differ"


def _drive(drive, p, disp, substeps):
    """Run a plan driver from the virgin state: (status, index, force, tangent, sc, st)."""
    sc = np.zeros(plan.get("bouc_wen").state_size)
    st_ = sc.copy()
    n = disp.shape[0]
    force = np.full((n, 2), np.nan)
    tangent = np.full((n, 2, 2), np.nan)
    status, index = drive(p, sc, st_, disp, np.zeros(n), False, substeps, force, tangent)
    return int(status), int(index), force, tangent, sc, st_


def _same_bits(a, b):
    """Bit for bit, every NaN equal to every NaN (their sign and payload depend on operand
    order inside the compiled code, not on the arithmetic)."""
    a, b = np.asarray(a), np.asarray(b)
    na, nb = np.isnan(a), np.isnan(b)
    return np.array_equal(na, nb) and np.array_equal(a[~na].view(np.int64), b[~nb].view(np.int64))


def _assert_bouc_wen_drivers_agree(p_dict, disp, substeps=1):
    spec = plan.get("bouc_wen")
    p = spec.law.pack(p_dict)
    own = _drive(plan.registry.driver(spec), p, disp, substeps)
    generic = _drive(plan.registry.generic_driver(spec), p, disp, substeps)
    assert own[:2] == generic[:2], f"status, sample {own[:2]} != {generic[:2]}"
    for name, a, b in zip(("force", "tangent", "sc", "st"), own[2:], generic[2:]):
        assert _same_bits(a, b), f"{name} differs: {a} != {b}"
    return own[0]


@pytest.mark.parametrize("path", list(PATHS))
@given(data=st.data())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_bouc_wen_own_driver_equals_the_generic_driver(path, data):
    """bouc_wen's history driver (state in local scalars, both update() calls in one loop) gives
    the generic plan driver's results with the step: status, failure sample, forces, tangents,
    and the committed and trial states left behind, bit for bit, with and without substeps."""
    p = data.draw(bouc_wen_params(), label="params")
    disp = data.draw(PATHS[path](), label="disp")
    substeps = data.draw(st.sampled_from([1, 1, 2, 3]), label="substeps")
    _assert_bouc_wen_drivers_agree(p, disp, substeps)


@pytest.mark.parametrize("case", ["newton", "second_call"])
def test_bouc_wen_own_driver_fails_as_the_generic_driver(case):
    """The failures: 25 iterations used up in the first update() call, and in the second one
    (the state left behind holds the first call's force and tangent; a case found by a search
    over steep steps onto spurious roots, where OpenSees fails at the same sample): same status,
    sample and states."""
    if case == "newton":
        p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=9.181247277429936,
                 beta=0.1979643833210143, gamma=0.28589263260021625)
        disp, want = np.array([[0.001, 0.0005], [0.002, 0.001], [-0.169674, -0.12]]), -2
    elif case == "second_call":
        p = dict(k_init=72952.68639726922, qd=1.0, alpha1=0.0, alpha2=0.0, mu=1.0, eta=0.3125,
                 beta=0.25, gamma=1.0)
        disp, want = np.array([[0.0, 0.0], [0.001953125, -0.00390625]]), -2
    assert _assert_bouc_wen_drivers_agree(p, disp) == want


@pytest.mark.parametrize("law", ["bouc_wen", "plasticity"])
def test_a_non_finite_plan_sample_is_a_value_error_before_any_step(law):
    """The drivers (bouc_wen's own, the generic one) scan the history before the first step, so
    simulate_force still raises the ValueError naming the sample and component, also where the
    law would fail earlier in the history (here bouc_wen's local Newton at sample 2)."""
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=9.181247277429936,
             beta=0.1979643833210143, gamma=0.28589263260021625)
    if law == "plasticity":
        p = {k: p[k] for k in ("k_init", "qd", "alpha1", "alpha2", "mu")}
    disp = np.array([[0.001, 0.0005], [0.002, 0.001], [-0.169674, -0.12], [0.0, 0.0],
                     [0.01, 0.0]])
    if law == "bouc_wen":
        with pytest.raises(NumericalFailure, match="sample 2"):
            rrfrei.simulate_force(law, p, disp)
    for value, comp in ((np.nan, 1), (np.inf, 0), (-np.inf, 1)):
        bad = disp.copy()
        bad[3, comp] = value
        with pytest.raises(ValueError, match=f"disp is not finite at sample 3, component "
                                             f"{'xy'[comp]}"):
            rrfrei.simulate_force(law, p, bad)
    spec = plan.get(law)
    bad = disp.copy()
    bad[4, 0] = np.nan
    for drive in (plan.registry.driver(spec), plan.registry.generic_driver(spec)):
        status, index, *_ = _drive(drive, spec.law.pack(p), bad, 1)
        assert (status, index) == (plan.registry.NONFINITE_DISP, 4)


def test_bouc_wen_own_driver_needs_equal_initial_states():
    """The driver carries one state through its loop: sc and st must be equal on entry."""
    spec = plan.get("bouc_wen")
    sc = np.zeros(spec.state_size)
    st_ = sc.copy()
    st_[2] = 0.5
    disp = np.zeros((2, 2))
    with pytest.raises(ValueError, match="sc and st must both hold the initial state"):
        plan.registry.driver(spec)(spec.law.pack(PROTOCOL_PARAMS["bouc_wen"]), sc, st_, disp,
                                   np.zeros(2), False, 1, np.zeros((2, 2)), np.zeros((2, 2, 2)))


def test_bouc_wen_exact_threshold_constants():
    """|dz|^2 >= DZ2_TOL and |du|^2 > DU2_MIN decide exactly as OpenSees' sqrt(.) >= 1e-12 and
    sqrt(.) > DBL_EPSILON: sqrt is correctly rounded and monotone, so checking both sides of
    each threshold covers every double."""
    import math

    from rrfrei.laws.plan import bouc_wen as bw

    assert math.sqrt(bw.DZ2_TOL) >= bw.TOL
    assert not math.sqrt(math.nextafter(bw.DZ2_TOL, 0.0)) >= bw.TOL
    assert not math.sqrt(bw.DU2_MIN) > bw.DBL_EPSILON
    assert math.sqrt(math.nextafter(bw.DU2_MIN, 1.0)) > bw.DBL_EPSILON


@pytest.mark.parametrize("seed", range(4))
def test_bouc_wen_skipped_second_call_is_exact(seed):
    """The history driver skips the second call of a step when the first flags it settled; the
    step called twice at every sample (no skip) gives the same forces, tangents and state bit
    for bit."""
    rng = np.random.default_rng(seed)
    p_dict = dict(k_init=float(10 ** rng.uniform(2, 4.5)), qd=float(10 ** rng.uniform(-1, 1)),
                  alpha1=float(rng.uniform(0, 0.5)), alpha2=float(rng.uniform(0, 0.1)),
                  mu=float(rng.choice([2.0, 2.7])), eta=float(rng.uniform(0.5, 4.0)),
                  beta=float(rng.uniform(0.1, 1.0)), gamma=float(rng.uniform(-0.1, 0.9)))
    disp = np.cumsum(rng.normal(0.0, 2e-3, (300, 2)) * rng.integers(0, 2, (300, 1)), axis=0)
    f, kt = rrfrei.simulate_force("bouc_wen", p_dict, disp, return_tangent=True)
    spec = plan.get("bouc_wen")
    p = spec.law.pack(p_dict)
    sc = spec.initial_state.copy()
    st = sc.copy()
    fi, ki, v = np.zeros(2), np.zeros((2, 2)), np.zeros(2)
    for i in range(disp.shape[0]):
        for _ in range(2):
            assert spec.step(p, sc, disp[i].copy(), v, 1.0, st, fi, ki) == 0
        sc[:] = st
        assert np.array_equal(fi, f[i]) and np.array_equal(ki, kt[i]), f"sample {i}"


def test_bouc_wen_pow_is_libm_pow_bit_for_bit():
    """The kernel's power (``bouc_wen._pow``: glibc's ``__ieee754_pow`` called without its
    wrappers where the C library has it, ``pow`` otherwise) returns the values of ``pow`` as
    Numba's ``x ** y`` and Python's ``math.pow`` call it: 10^6 random arguments (the kernel's
    |z|^(eta-2), |z|^(eta-4) range, wide magnitudes of both signs, integer exponents) and the
    special values (zeros, infinities, NaN, subnormals, overflow and underflow), bit for bit
    (NaN: any NaN)."""
    import math

    from numba import njit

    from rrfrei.laws.plan import bouc_wen as bw

    @njit
    def both(xs, ys):
        ours = np.empty_like(xs)
        libm = np.empty_like(xs)
        for i in range(xs.size):
            ours[i] = bw._pow(xs[i], ys[i])
            libm[i] = xs[i] ** ys[i]
        return ours, libm

    rng = np.random.default_rng(5)
    n = 250_000
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 2.0 ** -1022, 1.0,
                        -1.0, 0.5, 2.0, 1.7976931348623157e308, -3.0, 1e-300, 1e300])
    sx, sy = np.meshgrid(special, np.concatenate([special, [3.0, -3.0, 0.5, -0.5, 2.5, -2.63]]))
    xs = np.concatenate([
        10.0 ** rng.uniform(-3.0, 1.0, n),  # |z| in the kernel
        rng.choice([-1.0, 1.0], n) * 2.0 ** rng.uniform(-1074.0, 1023.0, n),
        rng.uniform(-4.0, 4.0, 2 * n),
        sx.ravel(),
    ])
    ys = np.concatenate([
        rng.uniform(0.2, 6.0, n) - rng.choice([2.0, 4.0], n),  # eta - 2, eta - 4
        rng.uniform(-3.0, 3.0, n),
        np.where(rng.random(2 * n) < 0.5, rng.integers(-40, 40, 2 * n), rng.uniform(-40, 40, 2 * n)),
        sy.ravel(),
    ])
    ours, libm = both(xs, ys)
    nan = np.isnan(libm)
    assert np.array_equal(np.isnan(ours), nan)
    assert np.array_equal(ours[~nan].view(np.int64), libm[~nan].view(np.int64)), \
        f"{np.sum(ours[~nan].view(np.int64) != libm[~nan].view(np.int64))} arguments differ"
    with np.errstate(all="ignore"):
        ref = []
        for x, y in zip(xs[:20_000], ys[:20_000]):
            try:
                ref.append(math.pow(x, y))
            except (OverflowError, ValueError):  # Python raises where C returns inf / NaN
                ref.append(np.nan)
    ref = np.array(ref)
    ok = ~np.isnan(ref)
    assert np.array_equal(ours[:20_000][ok].view(np.int64), ref[ok].view(np.int64))
    assert bw.POW_ENTRY in ("__pow_finite@GLIBC_2.15", "pow")
