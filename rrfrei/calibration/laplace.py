"""The Laplace approximation at the optimum and the walkers' start drawn from it (step 2 of
:mod:`rrfrei.calibration.sampler`)."""

from __future__ import annotations

import math

import numpy as np

from rrfrei.calibration.likelihood import Problem
from rrfrei.calibration.optimum import _Cube

__all__ = ["LAPLACE_RIDGE", "LAPLACE_STEP", "laplace_cov", "laplace_sd"]


LAPLACE_STEP = 1e-6
"""Forward-difference step of the Jacobian of the forces in unit-cube coordinates."""
LAPLACE_RIDGE = 0.1
"""Prior scale (unit-cube units) added to the Laplace precision: one tenth of a prior range in
directions the data do not fix (non-identifiable parameters), so the start never exceeds it."""


def laplace_cov(problem: Problem, theta0: np.ndarray) -> np.ndarray | None:
    """Laplace covariance of the free law parameters at ``theta0`` in unit-cube coordinates.

    Gauss-Newton: ``Sigma = (J_w^T J_w + I / LAPLACE_RIDGE^2)^-1`` with ``J_w`` the Jacobian of
    the *whitened* residuals (divided by sigma; for AR(1) noise the innovations
    ``(r_t - rho r_{t-1}) / sigma`` and ``sqrt(1 - rho^2) r_0 / sigma``, the densities of
    :func:`.likelihood.pointwise_from_residuals`), by forward differences evaluated as one batch.
    None if a perturbed parameter set fails or the result is not finite.
    """
    k = len(problem.free)
    cube = _Cube(problem)
    z0 = cube.z_free(theta0[:k])[0]
    h = np.where(z0 + LAPLACE_STEP <= cube.support()[1], LAPLACE_STEP, -LAPLACE_STEP)
    Z = np.repeat(z0[None, :], k + 1, axis=0)
    Z[1:] += np.diag(h)
    pad = np.ones((k + 1, problem.ndim - k))
    F, status = problem.forces(problem.full_params(np.column_stack([cube.x_free(Z), pad])))
    if np.any(status != 0) or not np.all(np.isfinite(F)):
        return None
    F = problem.at_points(F)
    J = ((F[1:] - F[0]) / h[:, None]).T  # (likelihood points, k)
    Jw = problem.noise.whiten(J, theta0[None, k:])
    H = Jw.T @ Jw + np.eye(k) / LAPLACE_RIDGE**2
    try:
        cov = np.linalg.inv(H)
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return None
    return cov if np.all(np.isfinite(cov)) else None


def laplace_sd(problem: Problem, theta0: np.ndarray, cov: np.ndarray | None) -> np.ndarray | None:
    """Laplace standard deviations of the free law parameters at ``theta0`` in their own units
    (``cov`` from :func:`laplace_cov`, mapped by the cube's slope ``dx/dz``); None without ``cov``."""
    k = len(problem.free)
    if cov is None or k == 0:
        return None
    cube = _Cube(problem)
    z0 = cube.z_free(theta0[:k])[0]
    h = 1e-7
    slope = (cube.x_free(z0 + h)[0] - cube.x_free(z0 - h)[0]) / (2 * h)
    return np.sqrt(np.diag(cov)) * np.abs(slope)


def _ball(problem: Problem, theta0: np.ndarray, nw: int, rng: np.random.Generator,
          cov: np.ndarray | None | str = "compute") -> np.ndarray:
    """Walkers drawn from the Laplace approximation at ``theta0``, each with finite log posterior.

    Law parameters: ``N(z0, Sigma)`` in unit-cube coordinates (:func:`laplace_cov`); noise: sigma
    with its large-sample relative sd ``1/sqrt(2n)``, rho with sd ``sqrt((1 - rho^2)/n)``.  Starting
    at the posterior's own scale and shape spares the ensemble the slow expansion from a point
    (a differential-evolution proposal is as large as the ensemble's spread), which otherwise
    dominates the autocorrelation time measured over the run.  Draws outside the prior box or with
    -inf log posterior are redrawn with the spread halved; without a usable Jacobian the spread is
    a ball of radius 1e-3 in the unit cube.
    """
    cube = _Cube(problem)
    k = len(problem.free)
    n = problem.n_like
    if isinstance(cov, str):
        cov = laplace_cov(problem, theta0) if k else None
    chol = np.linalg.cholesky(cov) if cov is not None else 1e-3 * np.eye(k)
    z = cube.z_free(theta0[:k])[0] if k else np.zeros(0)
    z_lo, z_hi = cube.support()
    sd_noise = np.array([1.0 / math.sqrt(2.0 * n)] + ([1.0] if problem.noise.ar1 else []))
    out = np.empty((nw, problem.ndim))
    filled = 0
    scale = 1.0
    for _ in range(50):
        Z = z + scale * rng.standard_normal((nw, k)) @ chol.T
        inside = np.all((Z >= z_lo) & (Z <= z_hi), axis=1)
        X = cube.x_free(Z) if k else np.zeros((nw, 0))
        noise = theta0[k:] * (1.0 + scale * sd_noise * rng.standard_normal((nw, problem.ndim - k)))
        if problem.noise.ar1:
            r0 = theta0[k + 1]
            noise[:, 1] = r0 + scale * math.sqrt(max(1.0 - r0 * r0, 1e-6) / n) * rng.standard_normal(nw)
        cand = np.column_stack([X, noise])[inside]
        lp = problem.log_prob(cand)
        good = cand[np.isfinite(lp)]
        take = min(good.shape[0], nw - filled)
        out[filled: filled + take] = good[:take]
        filled += take
        if filled == nw:
            return out
        scale *= 0.5
    raise ValueError(
        "could not place the walkers: the log posterior is -inf around the optimum "
        f"{dict(zip(problem.names, np.round(theta0, 6)))}"
    )
