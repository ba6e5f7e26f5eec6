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
   Stuck walkers (:func:`stuck_walkers`: a mean log posterior over the last :data:`CHECK` steps
   far below the ensemble's median walker's) are restarted at the position of a randomly chosen
   healthy walker, at most :data:`MAX_RESTARTS` times, and the chain before the restart is never
   kept (:func:`check`'s ``start``).  Why: on the CLT record SPC1 one or two of 32 walkers could
   stay for thousands of steps tens of log-units below the others, far out in the ``k_init``
   tail (a differential-evolution proposal is as large as the other walkers' spread, far too
   small to bring one back along the ridge), and R-hat stayed above the rule's limit until the
   time budget ran out.
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

import math
from dataclasses import dataclass
from pathlib import Path

import emcee
import numpy as np

from rrfrei.budget import TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.calibration.convergence import (
    CHECK,
    CONVERGENCE_RULE,
    ESS_TARGET,
    MIN_TAU,
    RHAT_LIMIT,
    Check,
    _tau,
    check,
    thinning,
)
from rrfrei.calibration.laplace import _ball, laplace_cov, laplace_sd
from rrfrei.calibration.likelihood import Problem
from rrfrei.calibration.optimum import find_map, polish_map
from rrfrei.calibration.reparam import sampling_coordinates
from rrfrei.calibration.store import _Store, check_checkpoint, load_optimum, save_optimum

__all__ = ["find_map", "polish_map", "run_chain", "ensemble_size", "ChainResult", "CHECK", "MAX_STEPS",
           "MAX_RESTARTS", "STUCK_SD", "stuck_walkers", "restart_walkers",
           "CONVERGENCE_RULE", "Check", "check", "thinning", "check_checkpoint", "load_optimum",
           "save_optimum"]

MAX_STEPS = 20_000


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
    restarted: int = 0  # walkers restarted (stuck_walkers), over the whole run



def ensemble_size(walkers: int | None, ndim: int) -> int:
    """Walkers of the ensemble: ``walkers`` (default ``max(32, 4 ndim)``) rounded up to an even
    number (emcee updates two halves); a ValueError below ``2 ndim``."""
    nw = max(32, 4 * ndim) if walkers is None else walkers
    if isinstance(nw, bool) or not isinstance(nw, (int, np.integer)) or nw < 2 * ndim:
        raise ValueError(f"walkers = {walkers!r} is too few for {ndim} sampled quantities; "
                         f"use >= {2 * ndim}")
    return int(nw) + int(nw) % 2


STUCK_SD = 5.0
"""A walker is stuck when its mean log posterior over the last :data:`CHECK` steps lies more than
``STUCK_SD sqrt(ndim / 2)`` below the median walker's: ``sqrt(ndim / 2)`` is the sd of the log
density of a draw from an ndim-dimensional Gaussian posterior, and a mean over a hundred steps
spreads less than one draw, so a healthy walker is never that far below."""
MAX_RESTARTS = 3
"""Most walker restarts of one run (each restarts the kept chain)."""


def stuck_walkers(recent_logp: np.ndarray, ndim: int) -> np.ndarray:
    """Walkers stuck far below the ensemble: boolean (walkers,) from their log posterior over the
    last steps ``recent_logp`` (steps, walkers); see :data:`STUCK_SD`.  None are stuck when more
    than half would be (then the ensemble itself has not settled)."""
    mean = np.mean(np.asarray(recent_logp, dtype=float), axis=0)
    mean = np.where(np.isfinite(mean), mean, -np.inf)
    stuck = mean < np.median(mean) - STUCK_SD * math.sqrt(ndim / 2.0)
    return stuck if 2 * int(stuck.sum()) < stuck.size else np.zeros_like(stuck)


def restart_walkers(state: emcee.State, stuck: np.ndarray, rng: np.random.Generator,
                    log_prob) -> emcee.State:
    """``state`` with each ``stuck`` walker moved next to a healthy walker drawn at random by
    ``rng``: at ``x_d + s (x_a - x_b)`` (``x_a``, ``x_b`` two other healthy walkers, ``s`` =
    1e-2, halved until ``log_prob`` (vectorised) is finite there), never onto ``x_d`` itself: two
    walkers at one point make the snooker move's proposal 0 / 0.  A walker with no finite
    position near its donor keeps the donor's position and log probability."""
    coords, lp = np.array(state.coords, copy=True), np.array(state.log_prob, copy=True)
    idx = np.flatnonzero(stuck)
    healthy = np.flatnonzero(~stuck)
    donors = rng.choice(healthy, size=idx.size, replace=True)
    pairs = np.array([rng.choice(healthy, size=2, replace=False) for _ in idx]).reshape(-1, 2)
    step = coords[pairs[:, 0]] - coords[pairs[:, 1]]
    todo = np.ones(idx.size, dtype=bool)
    scale = 1e-2
    for _ in range(20):
        cand = coords[donors[todo]] + scale * step[todo]
        new_lp = np.asarray(log_prob(cand), dtype=float)
        ok = np.isfinite(new_lp)
        where = np.flatnonzero(todo)[ok]
        coords[idx[where]], lp[idx[where]] = cand[ok], new_lp[ok]
        todo[np.flatnonzero(todo)[ok]] = False
        if not todo.any():
            break
        scale *= 0.5
    left = np.flatnonzero(todo)
    coords[idx[left]], lp[idx[left]] = coords[donors[left]], lp[donors[left]]
    return emcee.State(coords, log_prob=lp, random_state=state.random_state)


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
    restarts, restarted = 0, 0
    try:
        if steps is None and resumed >= 3 * CHECK:  # a resumed chain may already be converged
            previous = check(store.chain[:-CHECK], max_draws, start=store.restart).tmax
            chk = check(store.chain, max_draws, previous, start=store.restart)
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
                chk = check(store.chain, max_draws, previous, start=store.restart)
                bar.set_postfix_str(chk.text())
                if chk.converged(store.n, previous):
                    stopped_by = "converged"
                    break
                previous = chk.tmax
                stuck = stuck_walkers(store.logp[-CHECK:], ndim)
                if restarts < MAX_RESTARTS and stuck.any() and store.n - store.restart >= CHECK:
                    state = restart_walkers(state, stuck, np.random.default_rng([int(seed), store.n]),
                                            log_prob)
                    store.restart = store.n
                    restarts, restarted = restarts + 1, restarted + int(stuck.sum())
                    previous = math.inf  # tau of the chain from the restart on: no previous one
                    chk = None  # checked the chain before the restart: not the final check
                    continue
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
        chk = check(chain, max_draws, start=store.restart)
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
        resumed_steps=resumed, coordinates=coords.name, restarted=restarted,
    )


def _set_total(bar, total: int) -> None:
    """Update a progress bar's expected total (the estimate of the steps to convergence)."""
    if hasattr(bar, "refresh") and total > bar.n:
        bar.total = total
        bar.refresh()
