"""The shared core of the building stack (structures.dynamics.newmark_chain): one direction of a step.

The unidirectional and the plan kernels move their chains with these functions, so the
condensation, the predictor residual, the commit and the convergence rule are written once.
Each is checked here against the dense linear algebra it stands for.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions
import structures
from structures.dynamics import newmark_chain as core
from structures.dynamics.newmark_records import Chain, Histories, Solver
from structures.dynamics.plan_newmark_records import PlanBatch, PlanHistories


def chain_of(n: int, rng: np.random.Generator) -> Chain:
    return Chain(mass=rng.uniform(50.0, 300.0, n), story_stiffness=rng.uniform(1e4, 1e5, n - 1),
                 story_damping=rng.uniform(10.0, 500.0, n - 1), ground_damping=rng.uniform(0.0, 50.0, n),
                 story_height=np.full(n - 1, 3.0))


def dense(chain: Chain, c1: float, c2: float) -> np.ndarray:
    """K_L = K_s + c1 C + c2 M of the chain [base, floor 1, ...] (stories join neighbours)."""
    n = chain.mass.size
    k = np.diag(c2 * chain.mass + c1 * chain.ground_damping)
    for j in range(1, n):
        s = chain.story_stiffness[j - 1] + c1 * chain.story_damping[j - 1]
        k[j - 1:j + 1, j - 1:j + 1] += s * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return k


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 9), seed=st.integers(0, 2**31), h=st.floats(1e-3, 0.05))
def test_the_condensation_is_the_schur_complement_of_the_superstructure(n, seed, h):
    """d_0 = K_00 - K_0s K_ss^-1 K_s0, phi = (1, -K_ss^-1 K_s0), flex = K_ss^-1 (bordered by 0)."""
    chain = chain_of(n, np.random.default_rng(seed))
    c1, c2, *_ = core.coefficients(Solver(0.5, 0.25, 1e-12, 10, 2, False), h)
    k = dense(chain, c1, c2)
    kss_inv = np.linalg.inv(k[1:, 1:])
    w = np.zeros((4, n))
    flex = np.zeros((n, n))
    d0, phi2 = core.condense(chain, c1, c2, w[0], w[1], w[2], w[3], flex)
    phi = np.concatenate(([1.0], -kss_inv @ k[1:, 0]))
    np.testing.assert_allclose(d0, k[0, 0] - k[0, 1:] @ kss_inv @ k[1:, 0], rtol=1e-10)
    np.testing.assert_allclose(w[3], phi, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(phi2, phi @ phi, rtol=1e-12)
    np.testing.assert_allclose(flex[1:, 1:], kss_inv, rtol=1e-9, atol=1e-18)
    assert not flex[0].any() and not flex[:, 0].any()


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 8), seed=st.integers(0, 2**31))
def test_residual_and_commit_solve_the_effective_system_with_the_base_correction_given(n, seed):
    """With the base moved by du_0, the committed superstructure makes the linear residual
    vanish on every floor: K_L du = R (floors), i.e. the step is the Newmark solution."""
    rng = np.random.default_rng(seed)
    chain = chain_of(n, rng)
    h = 0.01
    c1, c2, cv, cva, ca, cav = core.coefficients(Solver(0.5, 0.25, 1e-12, 10, 2, False), h)
    u, v, a = (rng.normal(0.0, s, n) for s in (0.01, 0.1, 1.0))
    ag = rng.normal()
    w = np.zeros((4, n))
    flex = np.zeros((n, n))
    core.condense(chain, c1, c2, w[0], w[1], w[2], w[3], flex)
    r = np.zeros(n)
    m, ks, cs, cg = chain.mass, chain.story_stiffness, chain.story_damping, chain.ground_damping
    r0 = core.linear_residual(m, ks, cs, cg, u, v, a, ag, cv, cva, ca, cav, w[3], r)
    # the residual of the linear part at the predictor, densely
    vp, ap = cv * v + cva * a, ca * a + cav * v
    k_s, c = dense(chain, 0.0, 0.0), dense(chain, 1.0, 0.0) - dense(chain, 0.0, 0.0)
    res = -m * (ag + ap) - c @ vp - k_s @ u
    np.testing.assert_allclose(r, res, rtol=1e-9, atol=1e-9 * np.abs(res).max())
    np.testing.assert_allclose(r0, res[0] + w[3][1:] @ res[1:], rtol=1e-9, atol=1e-9 * np.abs(res).max())
    du0 = 1e-3
    u1, v1, a1 = u.copy(), v.copy(), a.copy()
    core.commit(m, cs, cg, u1, v1, a1, u[0] + du0, vp[0] + c1 * du0, ap[0] + c2 * du0, du0, w[3], flex, r,
                ag, c1, c2, cv, cva, ca, cav)
    du = u1 - u
    resid = res - dense(chain, c1, c2) @ du
    assert np.abs(resid[1:]).max() <= 1e-8 * np.abs(res).max()
    np.testing.assert_allclose(v1, vp + c1 * du, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a1, ap + c2 * du, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("status", "finite", "it", "norm2", "verdict"), [
    (-1, True, 1, 0.0, (-1, True)),  # a law status stops, whatever the norm
    (0, False, 1, 0.0, (core.NON_FINITE, True)),
    (0, True, 0, 0.0, (core.NOT_CONVERGED, False)),  # the predictor is never converged
    (0, True, 2, 1e-26, (0, True)),
    (0, True, 2, 1e-22, (core.NOT_CONVERGED, False)),
])
def test_newton_stops_on_a_law_failure_a_non_finite_value_or_norm_disp_incr(status, finite, it, norm2,
                                                                            verdict):
    assert core.newton_verdict(status, finite, it, norm2, 1e-12) == verdict


def test_plan_histories_are_the_unidirectional_histories_per_direction():
    h = PlanHistories.allocate(7, 4)
    assert isinstance(h, Histories)
    assert h.disp.shape == (2, 7, 4) and h.energy.shape == (2, 5, 7) and h.iterations.shape == (7,)
    x = h.direction(1)
    assert type(x) is Histories and x.disp.shape == (7, 4) and x.drift.shape == (7, 3)
    x.disp[3, 2] = 1.5
    assert h.disp[1, 3, 2] == 1.5  # a view


def test_batch_results_have_the_summary_fields_with_a_run_axis():
    b = PlanBatch.allocate(3, 4)
    assert b._fields == structures.dynamics.plan_newmark_records.PlanSummary._fields
    assert b.drift_peak.shape == (3, 2, 4) and b.iso_disp_peak.shape == (3, 2)
    assert b.status.dtype == np.int64 and b.subdivided_steps.dtype == np.int64
    assert b.iso_work.dtype == np.float64 and not b.iso_work.any()


def test_an_unreadable_step_is_refused_naming_it():
    b = structures.load_building("three_story")
    r = ground_motions.load("elcentro")
    with pytest.raises(ValueError, match="dt = 'fine' is invalid for record"):
        structures.time_history(b, r, dt="fine")


def test_a_batch_of_no_parameter_sets_returns_empty_arrays():
    b = structures.load_building("three_story")
    r = ground_motions.load("elcentro")
    p = np.empty((0, len(b.isolator.spec.param_names)))
    assert structures.time_history_batch(b, r, p)["iso_disp_peak"].shape == (0,)
