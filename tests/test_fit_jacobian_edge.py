"""A fit that starts on the edge of a law's local-iteration failures can still move: its
Jacobian takes the backward difference where the forward step fails (the optimum of the real
BNCS isolation loop sits on such an edge; its rounded parameters fail)."""

import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative

from rrfrei.gap.isolator import DIFF_STEP, one_sided_jacobian

BIG = 1e6
T = np.linspace(0.0, 1.0, 40)


def _model(x):
    return x[0] * T + x[1] * T**2


Y = _model(np.array([0.8, 0.3]))  # the augmented model's optimum lies inside the edge


def _resid_with_edge(edge):
    """Residuals of a fit whose 'law' fails (a wall of BIG) beyond ``x[0] > edge``."""
    def resid(x):
        if x[0] > edge:
            return np.full(T.size, BIG)
        return _model(x) - Y
    return resid


def test_without_failures_it_is_the_forward_difference_least_squares_takes():
    resid = _resid_with_edge(np.inf)
    lb, ub = np.array([-5.0, -5.0]), np.array([5.0, 5.0])
    fun, jac = one_sided_jacobian(resid, lb, ub, BIG)
    x = np.array([0.7, 0.1])
    ref = approx_derivative(resid, x, method="2-point", rel_step=DIFF_STEP, f0=resid(x), bounds=(lb, ub))
    fun(x)
    assert np.array_equal(jac(x), ref)


def test_a_failed_forward_step_takes_the_backward_difference_and_the_fit_moves_off_the_edge():
    edge = 1.0  # the start sits on the edge: every forward step in x0 fails
    resid = _resid_with_edge(edge)
    lb, ub = np.array([-5.0, -5.0]), np.array([5.0, 5.0])
    fun, jac = one_sided_jacobian(resid, lb, ub, BIG)
    x = np.array([edge, 0.0])  # on the edge, the second parameter (the "effect") off its optimum
    J = jac(x)
    assert np.all(np.abs(J) < 10.0)  # no column of size BIG / h
    assert np.allclose(J[:, 0], T, atol=1e-4) and np.allclose(J[:, 1], T**2, atol=1e-4)
    # scipy's own differences see the wall and the trust region cannot leave the start
    stuck = least_squares(resid, x, bounds=(lb, ub), method="trf", diff_step=DIFF_STEP, max_nfev=50)
    moved = least_squares(fun, x, bounds=(lb, ub), method="trf", jac=jac, max_nfev=50)
    assert abs(stuck.x[0] - edge) < 1e-9 and stuck.cost > 1e-2  # it stays on the edge
    assert abs(moved.x[1] - 0.3) < 1e-3 and abs(moved.x[0] - 0.8) < 1e-3
    assert moved.cost < 1e-12


def test_a_column_whose_both_steps_fail_is_zero():
    def resid(x):
        if abs(x[0] - 0.5) > 0.0:
            return np.full(T.size, BIG) if x[0] != 0.5 else _model(x) - Y
        return _model(x) - Y
    lb, ub = np.array([-5.0, -5.0]), np.array([5.0, 5.0])
    _, jac = one_sided_jacobian(resid, lb, ub, BIG)
    J = jac(np.array([0.5, 0.1]))
    assert np.all(J[:, 0] == 0.0) and np.allclose(J[:, 1], T**2, atol=1e-4)
