"""The numerics of a gap model's least-squares fit: the guard that ends a creeping or screened
start (:class:`_Guard`), the rule that keeps a screened start (:func:`_worth_continuing`), and the
Laplace covariance at the optimum (:func:`laplace_cov`) and its square-root factor
(:func:`laplace_factor`), shared by every gap model (isolator, building, rubber)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rrfrei.errors import NumericalFailure

__all__ = ["STALL_ITERATIONS", "STALL_REL"]

STALL_ITERATIONS = 30
"""Window [iterations] of the least-squares stall guard (:class:`_Guard`)."""
STALL_REL = 1e-4
"""A start whose cost fell by less than this fraction over the last ``STALL_ITERATIONS``
iterations is stopped at its current point (:class:`_Guard`)."""


class _Guard:
    """``least_squares`` ``callback`` (scipy >= 1.16, required) that ends a start early.

    * stall: once the cost ``C_i`` at iteration ``i`` satisfies ``C_(i-W) - C_i < STALL_REL C_i``
      (``W`` = :data:`STALL_ITERATIONS`) the search ends at its current point (status -2: ``x``,
      ``fun`` and ``jac`` are those of the point reached).  Starts that converge end by scipy's
      ``ftol`` (relative decrease below 1e-8 in one iteration) long before: the guard ends the
      starts that creep along a valley, which otherwise ran to ``max_nfev`` (measured on
      validation case mullins/erf_energy/seed3: three of the eight starts of ``+pinching`` took
      2,000 evaluations each, 77 of the case's 95 s of CPU, and ended at a cost of 0.884 against
      the winner's 0.311); with ``STALL_REL`` = 1e-3 the stiffening fits of case
      stiffening/cubic/seed3 stopped 0.2 % above the optimum that 1e-4 reaches (its held-out shrink
      0.95 against 1.00), hence 1e-4;
    * cut: after ``cut`` iterations (None: never) the search ends and :attr:`cut` is True (the
      multi-start screen of :meth:`IsolatorModel.fit`; :func:`_worth_continuing` decides).
    """

    def __init__(self, cut: int | None) -> None:
        self.limit = cut
        self.cut = False
        self.costs: list[float] = []

    def __call__(self, intermediate_result) -> None:
        f = intermediate_result.fun
        c = self.costs
        c.append(0.5 * float(f @ f))
        if len(c) > STALL_ITERATIONS and c[-1 - STALL_ITERATIONS] - c[-1] < STALL_REL * c[-1]:
            raise StopIteration
        if self.limit is not None and len(c) >= self.limit:
            self.cut = True
            raise StopIteration


def _worth_continuing(costs: Sequence[float], lead: float) -> bool:
    """Whether a start cut after its screen (costs per iteration) may still beat ``lead`` (the
    lowest cost any start reached): it leads within 5 %, or its descent over its last 10
    iterations, carried on linearly for 200 more, would take it below ``lead``.  A start that
    creeps far above the others' optimum (e.g. 3x the leader's cost, descending 1 % per 10
    iterations) is dropped at its screen."""
    c = costs[-1]
    if c <= 1.05 * lead:
        return True
    back = costs[-11] if len(costs) > 10 else costs[0]
    return c - 20.0 * max(back - c, 0.0) < lead


def laplace_cov(J: np.ndarray, s2: float, k: int, where: str) -> tuple[np.ndarray, str]:
    """``(J^T J / s2 + I)^-1`` in scaled coordinates, and a note ("" unless regularised).

    When the precision is singular in floating point (collinear Jacobian columns of size > 1e8,
    where the unit ridge is lost to rounding: ``np.linalg.inv`` raises "Singular matrix"), it is
    inverted through its eigen-decomposition with the eigenvalues clipped at the ridge (1), the
    exact-arithmetic lower bound, and the note says so.  A non-finite Jacobian is a
    :class:`NumericalFailure` naming ``where``.
    """
    if not k:
        return np.zeros((0, 0)), ""
    J = np.asarray(J, dtype=float)
    if not np.all(np.isfinite(J)):
        raise NumericalFailure(f"Laplace covariance of {where}: the Jacobian at the optimum is not finite")
    A = J.T @ J / s2 + np.eye(k)
    if not np.all(np.isfinite(A)):
        raise NumericalFailure(f"Laplace covariance of {where}: J^T J / s^2 overflows")
    try:
        cov = np.linalg.inv(A)
        if np.all(np.isfinite(cov)):
            return cov, ""
    except np.linalg.LinAlgError:
        pass
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    cov = (V / np.maximum(w, 1.0)) @ V.T
    return cov, (f"Laplace precision of {where} singular in floating point: inverted with its "
                 "eigenvalues clipped at the ridge (1)")


def laplace_factor(cov: np.ndarray) -> np.ndarray:
    """A factor ``L`` with ``L @ L.T == cov``: the Cholesky factor, or, when rounding makes ``cov``
    lose positive definiteness, ``V sqrt(max(w, 0))`` from its eigen-decomposition.  Draws from the
    Laplace approximation are ``x_opt + L @ u`` with ``u`` standard normal."""
    cov = np.asarray(cov, dtype=float)
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (cov + cov.T))
        return V * np.sqrt(np.clip(w, 0.0, None))
