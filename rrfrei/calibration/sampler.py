"""Global optimum (CMA-ES) then affine-invariant ensemble MCMC (emcee), with HDF5 checkpoints.

1. :func:`find_map` searches the law parameters on the unit cube spanned by their priors
   (:func:`rrfrei.calibration.priors.cube_range`) with CMA-ES (``cma``, log files off), the noise
   parameters profiled out (their maximum-likelihood values given the residuals), starting from
   the best of a batch of prior draws.  The result is the starting point, not the reported MAP
   alone: the MAP reported is the best of the optimum and every posterior sample.
2. :func:`run_chain` draws the walkers from the Laplace approximation there (:func:`_ball`) and
   runs ``emcee`` with a differential-evolution move mixture (ter Braak 2006; Nelson et al.
   2014), which copes with the strongly correlated parameters of hysteresis laws better than the
   stretch move.  With
   ``steps=None`` it runs in chunks until the chain is at least 50 integrated autocorrelation times
   long and the estimate of tau changed by less than 5 % over the last chunk (Foreman-Mackey et
   al. 2013, emcee docs "Saving & monitoring progress"), up to ``max_steps``.
3. ``checkpoint=path`` stores the chain in emcee's HDF5 backend after every step plus the optimum
   in the group ``rrfrei``; rerunning with the same path resumes from the last stored step, so an
   interrupted and a complete run end with the same number of samples.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import emcee
import numpy as np

from rrfrei.calibration.likelihood import Problem, pointwise_from_residuals
from rrfrei.calibration.priors import cube_range

__all__ = ["find_map", "run_chain", "ChainResult", "CHUNK", "MAX_STEPS"]

CHUNK = 250
MAX_STEPS = 20_000
TAU_FACTOR = 50.0


# ---------------------------------------------------------------------------------------------
# optimiser
# ---------------------------------------------------------------------------------------------
class _Cube:
    """Map between the unit cube and the free law parameters."""

    def __init__(self, problem: Problem) -> None:
        kinds, lo, hi = [], [], []
        for name in problem.free:
            ps = problem.spec.param(name)
            k, a, b = cube_range(problem.priors[name], ps.lower, ps.upper)
            kinds.append(k == "log")
            lo.append(a)
            hi.append(b)
        self.log = np.array(kinds, dtype=bool)
        self.lo = np.array(lo, dtype=float)
        self.hi = np.array(hi, dtype=float)

    def to_x(self, z: np.ndarray) -> np.ndarray:
        z = np.clip(np.atleast_2d(z), 0.0, 1.0)
        lin = self.lo + z * (self.hi - self.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = np.exp(np.log(self.lo) + z * (np.log(self.hi) - np.log(self.lo)))
        return np.where(self.log, lg, lin)

    def to_z(self, x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        lin = (x - self.lo) / (self.hi - self.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = (np.log(np.maximum(x, 1e-300)) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo))
        return np.clip(np.where(self.log, lg, lin), 0.0, 1.0)


def _profiled(problem: Problem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta rows with profiled noise, log posterior) for law-parameter rows ``X``."""
    P = problem.full_params(np.column_stack([X, np.ones((X.shape[0], problem.ndim - X.shape[1]))]))
    F, status = problem.forces(P)
    problem.n_evals += X.shape[0]
    noise = np.full((X.shape[0], problem.ndim - X.shape[1]), np.nan)
    ok = status == 0
    if ok.any():
        noise[ok] = problem.profile_noise(F[ok])
    theta = np.column_stack([X, noise])
    lp = problem.log_prior(np.where(np.isfinite(theta), theta, 1.0))
    lp[~ok] = -np.inf
    good = np.flatnonzero(np.isfinite(lp))
    if good.size:
        sigma, rho = problem.noise_params(theta[good])
        resid = problem._obs[None, :] - F[good]
        lp[good] += pointwise_from_residuals(resid, sigma, rho).sum(axis=1)
    lp[~np.isfinite(lp)] = -np.inf
    return theta, lp


def find_map(problem: Problem, seed: int = 0, *, max_evals: int | None = None) -> tuple[np.ndarray, float]:
    """Global optimum of the log posterior (noise profiled): (theta, log posterior)."""
    import cma

    k = len(problem.free)
    rng = np.random.default_rng(seed)
    cube = _Cube(problem)
    if k == 0:
        theta, lp = _profiled(problem, np.zeros((1, 0)))
        return theta[0], float(lp[0])
    n0 = max(64, 32 * k)
    Z0 = rng.uniform(0.0, 1.0, (n0, k))
    Z0[0] = 0.5
    theta, lp = _profiled(problem, cube.to_x(Z0))
    best = int(np.argmax(lp))
    best_theta, best_lp = theta[best], float(lp[best])
    max_evals = max_evals or 600 * k + 2000
    starts = [cube.to_z(theta[best, :k])[0]]
    for i in np.argsort(lp)[::-1][1:3]:  # two more starts from the next best prior draws
        starts.append(cube.to_z(theta[i, :k])[0])
    for r, z0 in enumerate(starts):
        opts = {
            "bounds": [0.0, 1.0], "seed": int(seed) * 97 + r + 1, "verbose": -9, "verb_log": 0,
            "verb_disp": 0, "maxfevals": max_evals // len(starts), "tolfun": 1e-9, "tolx": 1e-7,
            "popsize": max(12, 4 + int(3 * math.log(k)) * 2),
        }
        es = cma.CMAEvolutionStrategy(list(z0), 0.15, opts)
        while not es.stop():
            Z = np.array(es.ask())
            th, l = _profiled(problem, cube.to_x(Z))
            f = np.where(np.isfinite(l), -l, 1e300)
            es.tell(list(Z), list(f))
            j = int(np.argmax(l))
            if l[j] > best_lp:
                best_lp, best_theta = float(l[j]), th[j]
    return _polish(problem, cube, np.asarray(best_theta, dtype=float), best_lp)


def _polish(problem: Problem, cube: _Cube, theta: np.ndarray, lp: float) -> tuple[np.ndarray, float]:
    """Bounded least-squares (trust-region reflective) polish of the CMA-ES optimum.

    The log likelihood is a residual sum of squares, which Gauss-Newton-type steps minimise far
    faster than an evolution strategy near the optimum (HDR's ten parameters were left far from
    it by CMA-ES alone).  The polished point is kept only if its log posterior is higher.
    """
    from scipy.optimize import least_squares

    k = len(problem.free)
    obs = problem._obs
    scale = float(np.std(obs)) or 1.0
    pad = np.ones((1, problem.ndim - k))

    def resid(z: np.ndarray) -> np.ndarray:
        P = problem.full_params(np.column_stack([cube.to_x(z), pad]))
        F, status = problem.forces(P)
        problem.n_evals += 1
        if status[0] != 0 or not np.all(np.isfinite(F[0])):
            return np.full(obs.size, 1e3)
        return (F[0] - obs) / scale

    z0 = cube.to_z(theta[:k])[0]
    try:
        res = least_squares(resid, z0, bounds=(0.0, 1.0), method="trf", x_scale="jac",
                            max_nfev=100 * k, diff_step=1e-7)
    except ValueError:  # e.g. a start on the bound that trf cannot handle: keep CMA-ES' point
        return theta, lp
    th, lpp = _profiled(problem, cube.to_x(res.x))
    if float(lpp[0]) > lp:
        return np.asarray(th[0], dtype=float), float(lpp[0])
    return theta, lp


# ---------------------------------------------------------------------------------------------
# MCMC
# ---------------------------------------------------------------------------------------------
@dataclass
class ChainResult:
    chain: np.ndarray  # (steps, walkers, ndim), all stored steps
    log_prob: np.ndarray  # (steps, walkers)
    acceptance: float
    tau: np.ndarray  # (ndim,), may hold nan for very short chains
    converged_tau: bool
    tau_note: str
    evals: int
    seconds: float


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
    z0 = cube.to_z(theta0[:k])[0]
    h = np.where(z0 + LAPLACE_STEP <= 1.0, LAPLACE_STEP, -LAPLACE_STEP)
    Z = np.repeat(z0[None, :], k + 1, axis=0)
    Z[1:] += np.diag(h)
    pad = np.ones((k + 1, problem.ndim - k))
    F, status = problem.forces(problem.full_params(np.column_stack([cube.to_x(Z), pad])))
    if np.any(status != 0) or not np.all(np.isfinite(F)):
        return None
    J = ((F[1:] - F[0]) / h[:, None]).T  # (points, k)
    sigma, rho = problem.noise_params(theta0[None, :])
    s = float(sigma[0])
    if rho is None:
        Jw = J / s
    else:
        r = float(rho[0])
        Jw = np.vstack([J[:1] * math.sqrt(max(1.0 - r * r, 0.0)), J[1:] - r * J[:-1]]) / s
    H = Jw.T @ Jw + np.eye(k) / LAPLACE_RIDGE**2
    try:
        cov = np.linalg.inv(H)
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return None
    return cov if np.all(np.isfinite(cov)) else None


def _ball(problem: Problem, theta0: np.ndarray, nw: int, rng: np.random.Generator) -> np.ndarray:
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
    n = problem.n_points
    cov = laplace_cov(problem, theta0) if k else None
    chol = np.linalg.cholesky(cov) if cov is not None else 1e-3 * np.eye(k)
    z = cube.to_z(theta0[:k])[0] if k else np.zeros(0)
    sd_noise = np.array([1.0 / math.sqrt(2.0 * n)] + ([1.0] if problem.noise == "ar1" else []))
    out = np.empty((nw, problem.ndim))
    filled = 0
    scale = 1.0
    for _ in range(50):
        Z = z + scale * rng.standard_normal((nw, k)) @ chol.T
        inside = np.all((Z >= 0.0) & (Z <= 1.0), axis=1)
        X = cube.to_x(Z) if k else np.zeros((nw, 0))
        noise = theta0[k:] * (1.0 + scale * sd_noise * rng.standard_normal((nw, problem.ndim - k)))
        if problem.noise == "ar1":
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


def _tau(chain: np.ndarray) -> np.ndarray:
    try:
        return np.asarray(emcee.autocorr.integrated_time(chain, tol=0), dtype=float)
    except (emcee.autocorr.AutocorrError, ValueError, FloatingPointError):  # too short a chain
        return np.full(chain.shape[2], np.nan)


RHAT_STOP = 1.04
"""The chunked run also waits for the rank-normalised split R-hat (walkers as chains) to fall
below this, a margin under the 1.05 that :func:`rrfrei.calibrate` requires of the stored draws."""


def _rhat_max(chain: np.ndarray) -> float:
    """Largest rank-normalised split R-hat over parameters of an emcee chain (steps, walkers, k)."""
    import arviz as az

    by_walker = np.swapaxes(chain, 0, 1)  # (walkers as chains, draws, k)
    return float(max(az.rhat(by_walker[:, :, j]) for j in range(chain.shape[2])))


def run_chain(
    problem: Problem,
    theta0: np.ndarray,
    *,
    walkers: int | None,
    steps: int | None,
    seed: int,
    checkpoint: str | Path | None,
    progress: bool,
    max_steps: int = MAX_STEPS,
) -> ChainResult:
    """Run the ensemble (see the module docstring) and return the whole stored chain."""
    import time

    t0 = time.perf_counter()
    ndim = problem.ndim
    nw = walkers if walkers is not None else max(32, 4 * ndim)
    nw += nw % 2
    if nw < 2 * ndim:
        raise ValueError(f"walkers = {nw} is too few for {ndim} sampled parameters; use >= {2 * ndim}")
    if steps is not None and (not isinstance(steps, (int, np.integer)) or steps < 2):
        raise ValueError(f"steps must be an integer >= 2 or None (run to convergence), got {steps!r}")
    backend = None
    resume = False
    if checkpoint is not None:
        backend = emcee.backends.HDFBackend(str(checkpoint))
        if Path(checkpoint).exists() and _stored_iterations(backend) > 0:
            if backend.shape != (nw, ndim):
                raise ValueError(
                    f"checkpoint {checkpoint} holds {backend.shape[0]} walkers x {backend.shape[1]} "
                    f"parameters, this run needs {nw} x {ndim}; use another path"
                )
            resume = True
        else:
            backend.reset(nw, ndim)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(nw, ndim, problem.log_prob, vectorize=True, backend=backend, moves=moves)
    rng = np.random.default_rng(seed)
    if resume:
        start = None
    else:
        start = _ball(problem, theta0, nw, rng)
        sampler.random_state = np.random.RandomState(seed).get_state()
    evals0 = problem.n_evals
    note = ""
    if steps is not None:
        done = sampler.iteration
        if done < steps:
            sampler.run_mcmc(start, steps - done, progress=progress)
        elif done > steps:
            note = f"the checkpoint holds {done} steps, more than the {steps} asked; all are used"
    else:
        old = np.inf
        while sampler.iteration < max_steps:
            n = min(CHUNK, max_steps - sampler.iteration)
            sampler.run_mcmc(start, n, progress=progress)
            start = None
            chain = sampler.get_chain()
            tau = _tau(chain[chain.shape[0] // 4:])
            tmax = float(np.max(tau))
            if (np.all(np.isfinite(tau)) and sampler.iteration >= TAU_FACTOR * tmax
                    and abs(old - tmax) / tmax < 0.05
                    and _rhat_max(chain[chain.shape[0] // 4:]) < RHAT_STOP):
                break
            old = tmax
    chain = sampler.get_chain()
    logp = sampler.get_log_prob()
    burn = chain.shape[0] // 4
    tau = _tau(chain[burn:])
    tau_half = _tau(chain[burn: burn + (chain.shape[0] - burn) * 4 // 5])
    tmax = float(np.max(tau)) if tau.size else 0.0
    long_enough = bool(np.all(np.isfinite(tau)) and chain.shape[0] >= TAU_FACTOR * tmax)
    stable = bool(np.all(np.isfinite(tau_half)) and np.all(np.abs(tau - tau_half) <= 0.2 * tau))
    if not long_enough:
        note = (note + "; " if note else "") + (
            f"the chain has {chain.shape[0]} steps, fewer than {TAU_FACTOR:g} autocorrelation times "
            f"(tau = {tmax:.0f} steps)"
        )
    elif not stable:
        note = (note + "; " if note else "") + "the autocorrelation time is still changing"
    acc = float(np.mean(sampler.acceptance_fraction)) if not resume or chain.shape[0] else float("nan")
    if backend is not None:
        acc = float(np.mean(backend.accepted / max(backend.iteration, 1)))
    return ChainResult(
        chain=chain, log_prob=logp, acceptance=acc, tau=tau, converged_tau=long_enough and stable,
        tau_note=note, evals=problem.n_evals - evals0, seconds=time.perf_counter() - t0,
    )


def _stored_iterations(backend: emcee.backends.HDFBackend) -> int:
    try:
        return int(backend.iteration)
    except (AttributeError, KeyError, OSError):  # no mcmc group (e.g. created by find_map only)
        return 0


# ---------------------------------------------------------------------------------------------
# checkpoint metadata (the optimum, so a resumed run does not search again)
# ---------------------------------------------------------------------------------------------
def save_optimum(checkpoint: str | Path, meta: dict) -> None:
    import h5py

    with h5py.File(checkpoint, "a") as f:
        g = f.require_group("rrfrei")
        g.attrs["optimum"] = json.dumps(meta)


def load_optimum(checkpoint: str | Path) -> dict | None:
    import h5py

    if not os.path.exists(checkpoint):
        return None
    try:
        with h5py.File(checkpoint, "r") as f:
            if "rrfrei" not in f:
                return None
            return json.loads(f["rrfrei"].attrs["optimum"])
    except (OSError, KeyError):
        return None
