"""Global optimum (CMA-ES) then affine-invariant ensemble MCMC (emcee), with HDF5 checkpoints.

1. :func:`find_map` searches the law parameters on the unit cube spanned by their priors
   (:func:`rrfrei.calibration.priors.cube_range`) with CMA-ES (``cma``, log files off), the noise
   parameters profiled out (their maximum-likelihood values given the residuals), starting from
   the best of a batch of prior draws.  The result is the starting point, not the reported MAP
   alone: the MAP reported is the best of the optimum and every posterior sample.
2. :func:`run_chain` draws the walkers from the Laplace approximation there (:func:`_ball`) and
   runs ``emcee``, in the sampling coordinates of :mod:`.reparam` (the law's worst ridge removed;
   the chain is stored in law parameters), with a differential-evolution move mixture (ter Braak
   2006; Nelson et al. 2014), which copes with the strongly correlated parameters of hysteresis
   laws better than the stretch move.  With ``steps=None`` it runs in chunks of :data:`CHECK` steps
   until the convergence rule (:data:`CONVERGENCE_RULE`, :func:`check`) holds, at most
   ``max_steps``: on the draws that will be stored (after burn-in, :func:`burn_in`, thinned by
   :func:`thinning` to at most ``max_draws``), every sampled quantity has a bulk and a tail
   effective sample size >= :data:`ESS_TARGET` (400) and a rank-normalised split R-hat <
   :data:`RHAT_LIMIT` (1.05), walkers taken as chains (Vehtari et al. 2021), and the kept chain is
   >= :data:`MIN_TAU` (10) integrated autocorrelation times long with a stable estimate of tau.
   The stopping rule and the final check of :func:`rrfrei.calibrate` are one function on the same
   draws, so a run stopped as converged is converged (a rule on the whole chain with a separate
   check on the stored draws stopped runs that then failed the check).  The tau conditions keep a
   chain whose tau is still growing (ESS over-estimated) from stopping early.
3. ``checkpoint=path`` stores the chain in emcee's HDF5 layout every :data:`CHECK` steps (or
   :data:`FLUSH_SECONDS`) plus the optimum in the group ``rrfrei``; rerunning with the same path
   resumes from the last stored step, so an interrupted and a complete run end with the same
   number of samples.  A ``budget`` (:class:`rrfrei.budget.TimeBudget`) stops the search or the
   chain when it runs out; what was sampled is kept and written, and the run says so
   (``stopped_by="time_budget"``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import emcee
import numpy as np

from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.calibration.likelihood import Problem
from rrfrei.calibration.priors import cube_range
from rrfrei.calibration.reparam import sampling_coordinates

__all__ = ["find_map", "polish_map", "run_chain", "ensemble_size", "ChainResult", "CHECK", "MAX_STEPS",
           "CONVERGENCE_RULE", "Check", "check", "thinning"]

MAX_STEPS = 20_000


# ---------------------------------------------------------------------------------------------
# optimiser
# ---------------------------------------------------------------------------------------------
class _Cube:
    """Map between the unit cube and the free law parameters.

    The cube spans CMA-ES' search box (:func:`~.priors.cube_range`: the prior's support, or
    +-4 sd of a normal prior).  :meth:`to_x` clips to it; :meth:`x_free` extends the same map
    (linear or logarithmic) beyond it, and :meth:`support` gives the cube coordinates of the
    prior's support cut to the physical bounds, the box of the polish (:func:`_polish`): a
    posterior mode in a normal prior's tail lies outside the +-4 sd box.
    """

    def __init__(self, problem: Problem) -> None:
        kinds, lo, hi, s_lo, s_hi = [], [], [], [], []
        for j, name in enumerate(problem.free):
            prior = problem.priors[name]
            k, a, b = cube_range(prior, problem.lower[j], problem.upper[j])
            kinds.append(k == "log")
            lo.append(a)
            hi.append(b)
            sa, sb = _support(prior)
            s_lo.append(max(sa, problem.lower[j]))
            s_hi.append(min(sb, problem.upper[j]))
        self.log = np.array(kinds, dtype=bool)
        self.lo = np.array(lo, dtype=float)
        self.hi = np.array(hi, dtype=float)
        self._support = (np.array(s_lo, dtype=float), np.array(s_hi, dtype=float))

    def x_free(self, z: np.ndarray) -> np.ndarray:
        """Parameters at cube coordinates ``z``, not clipped to the cube."""
        z = np.atleast_2d(z)
        lin = self.lo + z * (self.hi - self.lo)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lg = np.exp(np.log(self.lo) + z * (np.log(self.hi) - np.log(self.lo)))
        return np.where(self.log, lg, lin)

    def to_x(self, z: np.ndarray) -> np.ndarray:
        return self.x_free(np.clip(np.atleast_2d(z), 0.0, 1.0))

    def z_free(self, x: np.ndarray) -> np.ndarray:
        """Cube coordinates of parameters ``x``, not clipped (+-inf for 0 or inf on a log scale)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        lin = (x - self.lo) / (self.hi - self.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = (np.log(np.maximum(x, 0.0)) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo))
        return np.where(self.log, lg, lin)

    def to_z(self, x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        lin = (x - self.lo) / (self.hi - self.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = (np.log(np.maximum(x, 1e-300)) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo))
        return np.clip(np.where(self.log, lg, lin), 0.0, 1.0)

    def support(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) cube coordinates of the prior's support within the physical bounds."""
        lo, hi = self.z_free(self._support[0])[0], self.z_free(self._support[1])[0]
        return np.minimum(lo, 0.0), np.maximum(hi, 1.0)


def _support(prior) -> tuple[float, float]:
    """Support of a prior: [a, b] (uniform, loguniform), the real line (normal), (0, inf)."""
    if prior.kind in ("uniform", "loguniform"):
        return prior.a, prior.b
    if prior.kind == "normal":
        return -math.inf, math.inf
    return 0.0, math.inf


def _prior_residuals(problem: Problem, x: np.ndarray) -> np.ndarray:
    """Standardised prior deviations of the free law parameters ``x`` with a normal,
    lognormal or halfnormal prior: ``-0.5 sum(r^2)`` is their log prior up to a constant (the
    lognormal's Jacobian term ``-log x`` left out)."""
    out = []
    for j, name in enumerate(problem.free):
        p = problem.priors[name]
        if p.kind == "normal":
            out.append((x[j] - p.a) / p.b)
        elif p.kind == "lognormal":
            out.append(math.log(max(x[j], 1e-300) / p.a) / p.b)
        elif p.kind == "halfnormal":
            out.append(x[j] / p.a)
    return np.array(out, dtype=float)


def find_map(problem: Problem, seed: int = 0, *, max_evals: int | None = None,
             budget: TimeBudget | None = None, progress: bool = False) -> tuple[np.ndarray, float]:
    """Global optimum of the log posterior (noise profiled): (theta, log posterior).

    Parameters
    ----------
    problem : the calibration problem.
    seed : seed of the prior draws and of CMA-ES.
    max_evals : CMA-ES evaluation limit (default ``600 k + 2000`` for k free law parameters).
    budget : wall-clock budget; when it runs out the search stops with the best point so far and
        :class:`~rrfrei.budget.BudgetExceeded` is raised (nothing sampled yet: no usable result).
    progress : show one bar for the search (evaluations) and one for the polish.
    """
    import cma

    k = len(problem.free)
    rng = np.random.default_rng(seed)
    cube = _Cube(problem)
    if k == 0:
        theta, lp = problem.profile_log_prob(np.zeros((1, 0)))
        return theta[0], float(lp[0])
    n0 = max(64, 32 * k)
    max_evals = max_evals or 600 * k + 2000
    bar = progress_bar(n0 + max_evals, "optimum (CMA-ES)", enabled=progress, unit="eval")
    try:
        Z0 = rng.uniform(0.0, 1.0, (n0, k))
        Z0[0] = 0.5
        theta, lp = problem.profile_log_prob(cube.to_x(Z0))
        bar.update(n0)
        best = int(np.argmax(lp))
        best_theta, best_lp = theta[best], float(lp[best])
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
                if budget is not None:
                    budget.check()
                Z = np.array(es.ask())
                th, l = problem.profile_log_prob(cube.to_x(Z))
                bar.update(len(Z))
                f = np.where(np.isfinite(l), -l, 1e300)
                es.tell(list(Z), list(f))
                j = int(np.argmax(l))
                if l[j] > best_lp:
                    best_lp, best_theta = float(l[j]), th[j]
    finally:
        bar.close()
    return _polish(problem, cube, np.asarray(best_theta, dtype=float), best_lp, budget=budget,
                   progress=progress)


def polish_map(problem: Problem, theta: np.ndarray, *, budget: TimeBudget | None = None,
               progress: bool = False) -> tuple[np.ndarray, float]:
    """(theta, log posterior) of the least-squares polish (:func:`_polish`) started at ``theta``
    (its noise parameters profiled again first), e.g. an optimum of a nearby problem."""
    k = len(problem.free)
    th, lp = problem.profile_log_prob(np.asarray(theta, dtype=float)[None, :k])
    return _polish(problem, _Cube(problem), th[0], float(lp[0]), budget=budget, progress=progress)


def _polish(problem: Problem, cube: _Cube, theta: np.ndarray, lp: float, *,
            budget: TimeBudget | None = None, progress: bool = False) -> tuple[np.ndarray, float]:
    """Bounded least-squares (trust-region reflective) polish of the CMA-ES optimum.

    The log posterior with the noise parameters held at their values at the start (profiled) is,
    up to a constant, ``-0.5 sum(r^2)`` of the residual vector ``r = [whitened force residuals
    (obs - F) / sigma (AR(1): innovations, :meth:`.noise.NoiseModel.whiten`), standardised
    deviations of the parameters with a normal / lognormal / halfnormal prior]``, which
    Gauss-Newton-type steps minimise far faster than an evolution strategy near the optimum
    (HDR's ten parameters were left far from it by CMA-ES alone).  The polish searches the
    prior's support within the physical bounds (:meth:`_Cube.support`), not CMA-ES' box: a
    strong test puts the mode of a parameter with a normal prior (``alpha2`` ~ N(0, 0.1))
    beyond the box's +-4 sd, where CMA-ES stops on the box's face and the chain needed
    thousands of steps to walk to the posterior.  The polished point is kept only if its log
    posterior (noise profiled again) is higher.  A budget that runs out during the polish keeps
    CMA-ES' point (the polish is an improvement, not a requirement) and the caller finds the
    budget expired.
    """
    from scipy.optimize import least_squares

    k = len(problem.free)
    obs = problem.observed
    pad = np.ones((1, problem.ndim - k))
    noise0 = np.asarray(theta[k:], dtype=float)[None, :]
    if not np.all(np.isfinite(noise0)) or noise0[0, 0] <= 0:
        return theta, lp
    n_prior = _prior_residuals(problem, theta[:k]).size
    fail = math.sqrt(max(-2.0 * lp, 1.0) / obs.size) * 10.0 + 10.0

    bar = progress_bar(100 * k, "polish (least squares)", enabled=progress, unit="eval")

    def resid(z: np.ndarray) -> np.ndarray:
        if budget is not None:
            budget.check()
        x = cube.x_free(z)[0]
        P = problem.full_params(np.concatenate([x, pad[0]])[None, :])
        F, status = problem.forces(P)
        bar.update(1)
        if status[0] != 0 or not np.all(np.isfinite(F[0])):
            return np.full(obs.size + n_prior, fail)
        r = problem.noise.whiten((obs - problem.at_points(F)[0])[:, None], noise0)[:, 0]
        return np.concatenate([r, _prior_residuals(problem, x)])

    z0 = cube.z_free(theta[:k])[0]
    lo, hi = cube.support()
    try:
        res = least_squares(resid, np.clip(z0, lo, hi), bounds=(lo, hi), method="trf",
                            x_scale="jac", max_nfev=100 * k, diff_step=1e-7)
    except (ValueError, BudgetExceeded):  # e.g. a start on the bound trf cannot handle: keep CMA-ES'
        return theta, lp
    finally:
        bar.close()
    th, lpp = problem.profile_log_prob(cube.x_free(res.x))
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
    converged: bool  # the convergence rule holds on the stored draws (Check.converged)
    tau_note: str
    evals: int
    seconds: float
    stopped_by: str = "steps"  # "converged", "steps", "max_steps" or "time_budget"
    burn: int = 0
    thin: int = 1
    ess_bulk: float = float("nan")  # smallest over parameters, stored draws, walkers as chains
    ess_tail: float = float("nan")
    rhat: float = float("nan")  # largest over parameters, stored draws
    resumed_steps: int = 0  # steps found in the checkpoint
    coordinates: str = "law parameters"  # the sampling coordinates (rrfrei.calibration.reparam)


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


def _autocov(x: np.ndarray) -> np.ndarray:
    """Sum_t (x_t - mean)(x_{t+lag} - mean) for lags 0..n-1 of chains ``x`` (draws, chains, k), by
    one zero-padded FFT along the draws (unnormalised: divide by n for the biased autocovariance)."""
    n = x.shape[0]
    xc = np.moveaxis(x - x.mean(axis=0), 0, -1).copy()  # draws contiguous: 2-3x faster FFTs
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(xc, n=nfft, axis=-1)
    acov = np.fft.irfft(f * np.conj(f), n=nfft, axis=-1)[..., :n]
    return np.ascontiguousarray(np.moveaxis(acov, -1, 0))  # (n, m, k) as the callers sum over it


def _tau(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """Integrated autocorrelation time per parameter of a chain (steps, walkers, k).

    ``emcee.autocorr.integrated_time(chain, tol=0)`` (the walkers' normalised autocorrelation
    functions averaged, Sokal's automatic window with c = 5), computed for all walkers and
    parameters in one FFT; nan for chains too short to estimate.
    """
    n, m, k = chain.shape
    if n < 4:
        return np.full(k, np.nan)
    acf = _autocov(chain)  # (n, m, k)
    with np.errstate(divide="ignore", invalid="ignore"):
        acf = np.nanmean(acf / acf[0], axis=1)  # (n, k); a stuck walker (zero variance) is skipped
    taus = 2.0 * np.cumsum(acf, axis=0) - 1.0
    out = np.full(k, np.nan)
    for j in range(k):
        if not np.all(np.isfinite(taus[:, j])):
            continue
        ok = np.arange(n) < c * taus[:, j]
        w = int(np.argmin(ok)) if not ok.all() else n - 1
        out[j] = taus[w, j]
    return out


RHAT_LIMIT = 1.05
"""Largest rank-normalised split R-hat (walkers as chains) of the stored draws of a converged run."""
ESS_TARGET = 400.0
"""Bulk and tail effective sample size every sampled quantity must reach (Vehtari et al. 2021,
"Rank-normalization, folding, and localization: an improved R-hat", recommend > 400 in total):
enough for the mean to ~5 % of a posterior sd and for the 2.5 % / 97.5 % quantiles reported."""
MIN_TAU = 10.0
"""The kept (post burn-in) chain must also be at least this many autocorrelation times long and
the estimate of tau must have changed by less than :data:`TAU_CHANGE` since the last check, so
that a short chain whose tau is still growing (its ESS over-estimated) does not stop early."""
TAU_CHANGE = 0.10
CONVERGENCE_RULE = (f"bulk and tail ESS >= {ESS_TARGET:.0f} and R-hat < {RHAT_LIMIT:g} on the "
                    f"stored (thinned) draws, from a chain >= {MIN_TAU:.0f} stable "
                    "autocorrelation times long")
"""The convergence rule in words: the one text the CLI's help, warnings and reports quote."""
CHECK = 100
"""Steps between convergence checks (and checkpoint writes) of a run to convergence."""
FLUSH_SECONDS = 10.0
"""Longest wall time between two checkpoint writes [s]."""


def burn_in(n_steps: int, tau_max: float) -> int:
    """Steps discarded as burn-in: a quarter of the chain, at least 2 tau, at most a half."""
    if not math.isfinite(tau_max):
        return n_steps // 2
    return min(n_steps // 2, max(n_steps // 4, int(math.ceil(2 * tau_max))))


def thinning(n_steps: int, burn: int, tau_max: float, walkers: int, max_draws: int) -> int:
    """Thinning of the stored draws: every ``max(tau / 2, 1)``-th step after burn-in, more when
    that would store more than ``max_draws`` draws (walkers x draws per walker)."""
    thin = max(1, int(tau_max / 2)) if math.isfinite(tau_max) else 1
    per_walker = max(int(max_draws) // max(int(walkers), 1), 1)
    need = -(-(n_steps - burn) // per_walker)  # ceil: the smallest thin storing <= per_walker each
    return int(min(max(thin, need), max(n_steps, 1)))


def _diagnose(kept: np.ndarray) -> tuple[float, float, float]:
    """(min bulk ESS, min tail ESS, max R-hat) of a chain (steps, walkers, k), walkers as chains.

    The rank-normalised split-chain bulk ESS, the tail ESS (5 % and 95 % quantile indicators)
    and the rank-normalised, folded split R-hat of Vehtari et al. (2021), the quantities of
    ``arviz.ess(method="bulk"|"tail")`` and ``arviz.rhat``, computed for all parameters at once
    (one FFT): arviz' per-parameter calls cost ~1 s per check, more than the sampling between
    two checks of a short run.
    """
    from scipy.stats import norm, rankdata

    n, m, k = kept.shape
    if n < 4:
        return float("nan"), float("nan"), float("nan")
    half = n // 2
    x = np.concatenate([kept[:half], kept[n - half:]], axis=1)  # split chains: (half, 2m, k)
    flat = x.reshape(-1, k)
    z = norm.ppf((rankdata(flat, axis=0) - 0.375) / (flat.shape[0] + 0.25)).reshape(x.shape)
    med = np.median(flat, axis=0)
    fold = np.abs(flat - med)
    zf = norm.ppf((rankdata(fold, axis=0) - 0.375) / (fold.shape[0] + 0.25)).reshape(x.shape)
    rhat = np.maximum(_split_rhat(z), _split_rhat(zf))
    bulk = _ess(z)
    q05, q95 = np.quantile(kept.reshape(-1, k), [0.05, 0.95], axis=0)  # of every draw, as arviz
    tail = np.minimum(_ess((x <= q05).astype(float)), _ess((x <= q95).astype(float)))
    return float(np.nanmin(bulk)), float(np.nanmin(tail)), float(np.nanmax(rhat))


def _split_rhat(x: np.ndarray) -> np.ndarray:
    """Potential scale reduction of chains ``x`` (draws, chains, k) (Gelman et al., BDA3 11.4)."""
    n = x.shape[0]
    w = np.mean(np.var(x, axis=0, ddof=1), axis=0)
    b = n * np.var(np.mean(x, axis=0), axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(((n - 1) / n * w + b / n) / w)


def _ess(x: np.ndarray) -> np.ndarray:
    """Effective sample size of chains ``x`` (draws, chains, k): Geyer's initial positive then
    monotone sequence on the multi-chain autocorrelation, step for step arviz' ``_ess`` (Stan's
    estimator, with its end-of-sequence correction), so that the convergence check and the
    summary's ESS are the same number on the same draws."""
    n, m, k = x.shape
    acov = (_autocov(x) / n).mean(axis=1)  # (n, k): biased autocovariance, mean over chains
    mean_var = acov[0] * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n + (np.var(x.mean(axis=0), axis=0, ddof=1) if m > 1 else 0.0)
    out = np.full(k, np.nan)
    resolution = np.finfo(float).resolution
    for j in range(k):
        xj = x[:, :, j]
        if not np.all(np.isfinite(xj)):
            continue
        if np.max(xj) - np.min(xj) < resolution:
            out[j] = float(xj.size)
            continue
        rho = 1.0 - (mean_var[j] - acov[:, j]) / var_plus[j]
        rt = np.zeros(n)
        even, odd = 1.0, float(rho[1])
        rt[0], rt[1] = even, odd
        t = 1
        while t < n - 3 and even + odd > 0.0:
            even, odd = float(rho[t + 1]), float(rho[t + 2])
            if even + odd >= 0:
                rt[t + 1], rt[t + 2] = even, odd
            t += 2
        max_t = t - 2
        if even > 0:
            rt[max_t + 1] = even
        t = 1
        while t <= max_t - 2:
            if rt[t + 1] + rt[t + 2] > rt[t - 1] + rt[t]:
                rt[t + 1] = rt[t + 2] = (rt[t - 1] + rt[t]) / 2.0
            t += 2
        tau = -1.0 + 2.0 * float(np.sum(rt[: max_t + 1])) + float(np.sum(rt[max_t + 1: max_t + 2]))
        tau = max(tau, 1.0 / math.log10(m * n))
        out[j] = np.nan if np.isnan(rt).any() else m * n / tau
    return out


@dataclass
class Check:
    """One evaluation of the convergence rule (:data:`CONVERGENCE_RULE`) on a chain of ``n`` steps:
    burn-in, tau, the thinning of the stored draws and their ESS and R-hat."""

    burn: int
    tau: np.ndarray
    tmax: float
    ess_bulk: float
    ess_tail: float
    rhat: float
    n: int = 0  # chain length checked
    diagnosed: bool = False  # ESS and R-hat computed
    thin: int = 1
    draws: int = 0  # stored draws (walkers x draws per walker)

    def tau_ok(self, n_steps: int, previous_tmax: float) -> bool:
        """The tau part of the rule: tau finite, >= MIN_TAU tau kept, tau stable since the last check."""
        return bool(
            np.all(np.isfinite(self.tau)) and n_steps - self.burn >= MIN_TAU * self.tmax
            and abs(previous_tmax - self.tmax) <= TAU_CHANGE * self.tmax
        )

    def converged(self, n_steps: int, previous_tmax: float) -> bool:
        """The whole rule: :meth:`tau_ok` and ESS and R-hat of the stored draws."""
        return bool(self.tau_ok(n_steps, previous_tmax) and self.draws_ok)

    @property
    def draws_ok(self) -> bool:
        """ESS >= :data:`ESS_TARGET` (bulk and tail) and R-hat < :data:`RHAT_LIMIT` of the stored draws."""
        return bool(self.ess_bulk >= ESS_TARGET and self.ess_tail >= ESS_TARGET
                    and self.rhat < RHAT_LIMIT)

    def text(self) -> str:
        if not self.diagnosed:
            return f"tau≈{self.tmax:.0f} (ESS, R-hat once tau is stable)"
        return (f"tau≈{self.tmax:.0f} ESS {self.ess_bulk:.0f}/{self.ess_tail:.0f} "
                f"R-hat {self.rhat:.3f}")


def check(chain: np.ndarray, max_draws: int, previous_tmax: float | None = None) -> Check:
    """Burn-in, tau, thinning and the stored draws' ESS and R-hat of a chain (steps, walkers, k):
    the convergence rule of :func:`run_chain` and the final check of :func:`rrfrei.calibrate`.

    With ``previous_tmax`` (the last check's tau) the ESS and R-hat are computed only when the
    tau part of the rule (:meth:`Check.tau_ok`) holds, the only case in which they can decide it
    (nan otherwise).
    """
    n, nw = chain.shape[0], chain.shape[1]
    t0 = _tau(chain[n // 4:])
    burn = burn_in(n, float(np.max(t0)) if np.all(np.isfinite(t0)) else math.nan)
    kept = chain[burn:]
    tau = t0 if burn == n // 4 else _tau(kept)  # same samples: same tau
    tmax = float(np.max(tau)) if np.all(np.isfinite(tau)) else math.nan
    thin = thinning(n, burn, tmax, nw, max_draws)
    stored = kept[::thin]
    chk = Check(burn, tau, tmax, math.nan, math.nan, math.nan, n=n, thin=thin,
                draws=int(stored.shape[0] * nw))
    if previous_tmax is None or chk.tau_ok(n, previous_tmax):
        chk.ess_bulk, chk.ess_tail, chk.rhat = _diagnose(stored)
        chk.diagnosed = True
    return chk


class _Store:
    """The chain in memory, appended to emcee's HDF5 layout (``mcmc`` group) in blocks.

    emcee's own ``HDFBackend`` opens the file after every step; writing every :data:`CHECK` steps
    or :data:`FLUSH_SECONDS` (whichever first) keeps a kill's loss small at a fraction of the
    cost.  Files stay readable by ``emcee.backends.HDFBackend``.
    """

    def __init__(self, path: str | Path | None, nw: int, ndim: int) -> None:
        import time

        self.path = None if path is None else str(path)
        self.chain = np.empty((0, nw, ndim))
        self.logp = np.empty((0, nw))
        self.accepted = np.zeros(nw)
        self.written = 0
        self.last = time.perf_counter()
        if self.path is not None:
            backend = emcee.backends.HDFBackend(self.path)
            n = _stored_iterations(backend) if Path(self.path).exists() else 0
            if n > 0:
                if backend.shape != (nw, ndim):
                    raise ValueError(
                        f"checkpoint {self.path} holds {backend.shape[0]} walkers x {backend.shape[1]} "
                        f"parameters, this run needs {nw} x {ndim}; use another path"
                    )
                self.chain = backend.get_chain()
                self.logp = backend.get_log_prob()
                self.accepted = np.asarray(backend.accepted, dtype=float)
                self.written = n
            else:
                backend.reset(nw, ndim)

    @property
    def n(self) -> int:
        return self.chain.shape[0]

    def append(self, coords: np.ndarray, logp: np.ndarray, accepted: np.ndarray) -> None:
        self.chain = np.concatenate([self.chain, coords])
        self.logp = np.concatenate([self.logp, logp])
        self.accepted = self.accepted + accepted

    def flush(self, force: bool = False) -> None:
        import time

        if self.path is None or self.written == self.n:
            return
        if not force and time.perf_counter() - self.last < FLUSH_SECONDS and self.n - self.written < CHECK:
            return
        import h5py

        with h5py.File(self.path, "a") as f:
            g = f["mcmc"]
            g["chain"].resize(self.n, axis=0)
            g["log_prob"].resize(self.n, axis=0)
            g["chain"][self.written:] = self.chain[self.written:]
            g["log_prob"][self.written:] = self.logp[self.written:]
            g["accepted"][:] = self.accepted
            g.attrs["iteration"] = self.n
        self.written = self.n
        self.last = time.perf_counter()


def ensemble_size(walkers: int | None, ndim: int) -> int:
    """Walkers of the ensemble: ``walkers`` (default ``max(32, 4 ndim)``) rounded up to an even
    number (emcee updates two halves); a ValueError below ``2 ndim``."""
    nw = max(32, 4 * ndim) if walkers is None else walkers
    if isinstance(nw, bool) or not isinstance(nw, (int, np.integer)) or nw < 2 * ndim:
        raise ValueError(f"walkers = {walkers!r} is too few for {ndim} sampled quantities; "
                         f"use >= {2 * ndim}")
    return int(nw) + int(nw) % 2


def moves() -> list:
    """The ensemble's move mixture: (emcee move, probability) pairs."""
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


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
    budget: TimeBudget | None = None,
    max_draws: int = 1000,
) -> ChainResult:
    """Run the ensemble (see the module docstring) and return the whole stored chain.

    Parameters
    ----------
    problem, theta0 : the problem and the optimum the walkers start around.
    walkers : ensemble size (default max(32, 4 ndim)).
    steps : fixed number of steps, or None: run to the convergence rule (:data:`CONVERGENCE_RULE`,
        checked every :data:`CHECK` steps by :func:`check`), at most ``max_steps``.
    seed : seed of the initial ensemble and of the moves (a resumed run reseeds from seed and
        the number of stored steps, so it is reproducible too).
    checkpoint : HDF5 file (emcee's layout); an existing chain in it is continued.
    progress : one bar (steps) with tau, ESS and R-hat at each check.
    max_steps : step cap of a run to convergence.
    budget : wall-clock budget: when it runs out the chain stops after the current step, is
        written to the checkpoint, and ``stopped_by`` is ``"time_budget"``.
    max_draws : most draws stored (walkers x draws per walker), which sets the thinning whose
        draws the rule checks (:func:`thinning`).
    """
    import time

    t0 = time.perf_counter()
    ndim = problem.ndim
    nw = ensemble_size(walkers, ndim)
    if steps is not None and (not isinstance(steps, (int, np.integer)) or steps < 2):
        raise ValueError(f"steps must be an integer >= 2 or None (run to convergence), got {steps!r}")
    if not isinstance(max_steps, (int, np.integer)) or isinstance(max_steps, bool) or max_steps < 2:
        raise ValueError(f"max_steps must be an integer >= 2, got {max_steps!r}")
    store = _Store(checkpoint, nw, ndim)
    resumed = store.n
    k = len(problem.free)
    cov = laplace_cov(problem, theta0) if k else None
    sd = laplace_sd(problem, theta0, cov)
    ia = problem.free.index("alpha2") if "alpha2" in problem.free else None
    coords = sampling_coordinates(problem, theta0, None if sd is None or ia is None else float(sd[ia]))

    def log_prob(phi: np.ndarray) -> np.ndarray:
        """The law posterior in the sampling coordinates: times |d theta / d phi|."""
        lp = problem.log_prob(coords.to_law(phi))
        ok = np.isfinite(lp)
        lp[ok] += coords.log_jacobian(phi[ok])
        return lp

    sampler = emcee.EnsembleSampler(nw, ndim, log_prob, vectorize=True, moves=moves())
    if resumed:
        phi = coords.to_sampling(store.chain[-1])
        state = emcee.State(phi, log_prob=store.logp[-1] + coords.log_jacobian(phi))
        sampler.random_state = np.random.RandomState([int(seed), resumed]).get_state()
    else:
        state = emcee.State(coords.to_sampling(_ball(problem, theta0, nw, np.random.default_rng(seed), cov)))
        sampler.random_state = np.random.RandomState(seed).get_state()
    evals0 = problem.n_evals
    note = ""
    target = steps if steps is not None else max_steps
    if steps is not None and resumed > steps:
        note = f"the checkpoint holds {resumed} steps, more than the {steps} asked; all are used"
    stopped_by = "steps" if steps is not None else "max_steps"
    bar = progress_bar(max(target - resumed, 0), "MCMC", enabled=progress, unit="step")
    chk = None
    previous = math.inf
    try:
        if steps is None and resumed >= 3 * CHECK:  # a resumed chain may already be converged
            previous = check(store.chain[:-CHECK], max_draws).tmax
            chk = check(store.chain, max_draws, previous)
            if chk.converged(store.n, previous):
                stopped_by = "converged"
                target = store.n
            previous = chk.tmax
        while store.n < target:
            if budget is not None and budget.expired():
                stopped_by = "time_budget"
                break
            n = min(CHECK, target - store.n)
            new_c, new_l, acc = [], [], np.zeros(nw)
            prev = state.coords
            for new in sampler.sample(state, iterations=n, store=False):
                state = new
                acc += np.any(new.coords != prev, axis=1)  # a rejected proposal keeps the walker
                prev = new.coords.copy()
                new_c.append(coords.to_law(prev))  # stored in law parameters
                new_l.append(new.log_prob - coords.log_jacobian(prev))
                bar.update(1)
                if budget is not None and budget.expired():
                    break
            if not new_c:
                break
            store.append(np.array(new_c), np.array(new_l), acc)
            store.flush()
            if budget is not None and budget.expired():
                stopped_by = "time_budget"
                break
            if steps is None and store.n >= 2 * CHECK:
                chk = check(store.chain, max_draws, previous)
                bar.set_postfix_str(chk.text())
                if chk.converged(store.n, previous):
                    stopped_by = "converged"
                    break
                previous = chk.tmax
                if math.isfinite(chk.tmax):
                    need = chk.burn + MIN_TAU * chk.tmax
                    if chk.ess_bulk > 0:  # the stored draws' ESS grows with the chain until ~ draws
                        need = max(need, store.n * ESS_TARGET / max(min(chk.ess_bulk, chk.ess_tail), 1.0))
                    _set_total(bar, min(int(need) + CHECK, max_steps) - resumed)
    finally:
        store.flush(force=True)
        bar.close()
    chain, logp = store.chain, store.logp
    if chk is None or not chk.diagnosed or chk.n != chain.shape[0]:  # else: the last check is this one
        chk = check(chain, max_draws)
    tau, tmax = chk.tau, chk.tmax
    tau_half = _tau(chain[chk.burn: chk.burn + (chain.shape[0] - chk.burn) * 4 // 5])
    long_enough = bool(np.all(np.isfinite(tau)) and chain.shape[0] - chk.burn >= MIN_TAU * tmax)
    stable = bool(np.all(np.isfinite(tau_half)) and np.all(np.abs(tau - tau_half) <= 0.2 * tau))
    converged = stopped_by == "converged" or (long_enough and stable and chk.draws_ok)
    if not long_enough:
        note = (note + "; " if note else "") + (
            f"the chain has {chain.shape[0] - chk.burn} steps after burn-in, fewer than {MIN_TAU:g} "
            f"autocorrelation times (tau = {tmax:.0f} steps)"
        )
    elif not stable and not converged:
        note = (note + "; " if note else "") + "the autocorrelation time is still changing"
    if not min(chk.ess_bulk, chk.ess_tail) >= ESS_TARGET:
        note = (note + "; " if note else "") + (
            f"effective sample size {min(chk.ess_bulk, chk.ess_tail):.0f} < {ESS_TARGET:.0f} "
            f"(stored draws)")
    if not chk.rhat < RHAT_LIMIT:
        note = (note + "; " if note else "") + f"R-hat {chk.rhat:.3f} >= {RHAT_LIMIT:g} (stored draws)"
    if stopped_by == "max_steps" and steps is None and converged:
        stopped_by = "converged"  # reached the rule exactly at the cap
    acc = float(np.mean(store.accepted / max(store.n, 1)))
    return ChainResult(
        chain=chain, log_prob=logp, acceptance=acc, tau=tau,
        converged=converged, tau_note=note,
        evals=problem.n_evals - evals0, seconds=time.perf_counter() - t0, stopped_by=stopped_by,
        burn=chk.burn, thin=chk.thin, ess_bulk=chk.ess_bulk, ess_tail=chk.ess_tail, rhat=chk.rhat,
        resumed_steps=resumed, coordinates=coords.name,
    )


def _set_total(bar, total: int) -> None:
    """Update a progress bar's expected total (the estimate of the steps to convergence)."""
    if hasattr(bar, "refresh") and total > bar.n:
        bar.total = total
        bar.refresh()


def _stored_iterations(backend: emcee.backends.HDFBackend) -> int:
    try:
        return int(backend.iteration)
    except (AttributeError, KeyError, OSError):  # no mcmc group (e.g. created by find_map only)
        return 0


# ---------------------------------------------------------------------------------------------
# checkpoint metadata (the optimum, so a resumed run does not search again)
# ---------------------------------------------------------------------------------------------
def check_checkpoint(checkpoint: str | Path) -> None:
    """A ValueError naming the file when ``checkpoint`` exists but is not an HDF5 file (or is a
    folder): h5py's own error is a traceback through its C layer."""
    import h5py

    p = Path(checkpoint)
    if p.is_dir():
        raise ValueError(f"checkpoint {p} is a folder; expected an HDF5 file path (e.g. {p / 'chain.h5'})")
    if p.exists() and not h5py.is_hdf5(str(p)):
        raise ValueError(f"checkpoint {p} exists and is not an HDF5 file: give another path (the "
                         "chain is stored there) or remove the file")


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
