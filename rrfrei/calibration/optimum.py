"""The optimum the chain starts from: CMA-ES on the unit cube spanned by the priors, then a
least-squares polish (step 1 of :mod:`rrfrei.calibration.sampler`).

:func:`find_map` searches the law parameters on the unit cube spanned by their priors
(:func:`rrfrei.calibration.priors.cube_range`) with CMA-ES (``cma``, log files off), the noise
parameters profiled out (their maximum-likelihood values given the residuals), starting from the
best of a batch of prior draws; :func:`polish_map` polishes a point by least squares.
"""

from __future__ import annotations

import math

import numpy as np

from rrfrei.blas import one_blas_thread
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.calibration.likelihood import Problem
from rrfrei.calibration.priors import cube_range

__all__ = ["find_map", "polish_map"]


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
    max_evals : CMA-ES evaluation limit (default ``200 k + 700`` for k free law parameters),
        shared by the three starts; each start's best point is then polished
        (:func:`_polish_until_stalled`) and the best polished point returned.
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
    max_evals = max_evals or MAX_EVALS_PER_PARAM * k + MAX_EVALS_BASE
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
        ends = []  # (theta, log posterior) of each start's best point
        for r, z0 in enumerate(starts):
            opts = {
                "bounds": [0.0, 1.0], "seed": int(seed) * 97 + r + 1, "verbose": -9, "verb_log": 0,
                "verb_disp": 0, "maxfevals": max_evals // len(starts), "tolfun": 1e-9, "tolx": 1e-7,
                "popsize": max(12, 4 + int(3 * math.log(k)) * 2),
            }
            es = cma.CMAEvolutionStrategy(list(z0), 0.15, opts)
            end_theta, end_lp = None, -math.inf
            while not es.stop():
                if budget is not None:
                    budget.check()
                Z = np.array(es.ask())
                th, l = problem.profile_log_prob(cube.to_x(Z))
                bar.update(len(Z))
                f = np.where(np.isfinite(l), -l, 1e300)
                es.tell(list(Z), list(f))
                j = int(np.argmax(l))
                if l[j] > end_lp:
                    end_lp, end_theta = float(l[j]), th[j]
                if l[j] > best_lp:
                    best_lp, best_theta = float(l[j]), th[j]
            if math.isfinite(end_lp):
                ends.append((np.asarray(end_theta, dtype=float), end_lp))
    finally:
        bar.close()
    if not ends:
        ends = [(np.asarray(best_theta, dtype=float), best_lp)]
    polished = [_polish_until_stalled(problem, cube, th, lp, budget=budget, progress=progress)
                for th, lp in ends]
    return max(polished, key=lambda t: t[1])


MAX_EVALS_PER_PARAM, MAX_EVALS_BASE = 200, 700
"""CMA-ES evaluations of :func:`find_map` by default: ``200 k + 700`` for k free law parameters,
over three starts.  CMA-ES brings each start into the optimum's basin; the least-squares polish
(:func:`_polish_until_stalled`) finds the optimum itself: on the 2,401-sample bouc_wen test of
``benchmarks/bench_calibration.py`` three times as many CMA-ES evaluations and a single polish
ended log-units below the optimum that these reach from every start."""
DIFF_STEP = 1e-7
"""Relative forward-difference step of the polish's Jacobian (unit-cube coordinates)."""
POLISH_GAIN = 0.01
"""A polish that raises the log posterior by more than this is followed by another one."""


def _polish_until_stalled(problem: Problem, cube: _Cube, theta: np.ndarray, lp: float, *,
                          budget: TimeBudget | None = None, progress: bool = False,
                          max_rounds: int = 10) -> tuple[np.ndarray, float]:
    """:func:`_polish` repeated from its own result while it gains more than :data:`POLISH_GAIN`
    (at most ``max_rounds`` rounds).  Why: a trust-region polish started far from the optimum
    stops early, its variable scaling (``x_scale="jac"``) and trust radius set by the start; a
    new polish from its end starts with both fresh (on the 2,401-sample bouc_wen test, one polish
    from a prior draw ends hundreds of log-units below the optimum and a second one reaches it)."""
    for _ in range(max_rounds):
        th, new = _polish(problem, cube, theta, lp, budget=budget, progress=progress)
        if not new > lp + POLISH_GAIN:
            return (th, new) if new > lp else (theta, lp)
        theta, lp = th, new
        if budget is not None and budget.expired():
            break
    return theta, lp


def polish_map(problem: Problem, theta: np.ndarray, *, budget: TimeBudget | None = None,
               progress: bool = False) -> tuple[np.ndarray, float]:
    """(theta, log posterior) of the least-squares polish (:func:`_polish_until_stalled`) started at ``theta``
    (its noise parameters profiled again first), e.g. an optimum of a nearby problem."""
    k = len(problem.free)
    th, lp = problem.profile_log_prob(np.asarray(theta, dtype=float)[None, :k])
    return _polish_until_stalled(problem, _Cube(problem), th[0], float(lp[0]), budget=budget,
                                 progress=progress)


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

    def resid_rows(Z: np.ndarray) -> np.ndarray:
        """Residual vectors of cube rows ``Z``, the law run for all rows in one batch."""
        if budget is not None:
            budget.check()
        X = cube.x_free(Z)
        F, status = problem.forces(problem.full_params(np.column_stack([X, np.repeat(pad, len(X), 0)])))
        bar.update(len(X))
        out = np.full((len(X), obs.size + n_prior), fail)
        for i in np.flatnonzero((status == 0) & np.all(np.isfinite(F), axis=1)):
            r = problem.noise.whiten((obs - problem.at_points(F[i:i + 1])[0])[:, None], noise0)[:, 0]
            out[i] = np.concatenate([r, _prior_residuals(problem, X[i])])
        return out

    def resid(z: np.ndarray) -> np.ndarray:
        return resid_rows(np.asarray(z, dtype=float)[None, :])[0]

    def jac(z: np.ndarray) -> np.ndarray:
        """Forward differences (scipy's ``2-point`` steps, ``diff_step`` 1e-7, turned back at an
        upper bound), the base point and the k perturbed points evaluated as one batch: one
        Numba call instead of k + 1 single-row calls, which leave the other cores idle."""
        z = np.asarray(z, dtype=float)
        h = DIFF_STEP * np.maximum(1.0, np.abs(z))
        h = np.where(z + h > hi, -h, h)
        R = resid_rows(np.vstack([z, z + np.diag(h)]))
        return ((R[1:] - R[0]) / h[:, None]).T

    z0 = cube.z_free(theta[:k])[0]
    lo, hi = cube.support()
    try:
        with one_blas_thread():  # trf's SVD of a thin Jacobian: one thread is 25x faster on shared cores
            res = least_squares(resid, np.clip(z0, lo, hi), jac=jac, bounds=(lo, hi), method="trf",
                                x_scale="jac", max_nfev=100 * k)
    except (ValueError, BudgetExceeded):  # e.g. a start on the bound trf cannot handle: keep CMA-ES'
        return theta, lp
    finally:
        bar.close()
    th, lpp = problem.profile_log_prob(cube.x_free(res.x))
    if float(lpp[0]) > lp:
        return np.asarray(th[0], dtype=float), float(lpp[0])
    return theta, lp
