"""A walker stuck far below the ensemble is restarted at a healthy walker's position, and the
chain before the restart is never kept (issue 28.7: on the CLT record SPC1, one or two of 32
walkers stayed 20-36 log-units below the others for thousands of steps, out in the k_init tail,
and R-hat stayed at 1.1-1.2 until the time budget ran out).

The trap, a ridge as in SPC1: a Gaussian posterior in 4 dimensions, sd 1 across the direction
``e = (1, 1, 1, 1) / 2`` and 0.001 along it, with a narrow secondary mode 3 along ``e`` (3,000
sd) whose peak is 30 log-units below the main one.  A walker that starts in it rarely leaves
under the ensemble's moves: a differential-evolution step is the size of the other walkers'
spread, far wider than the trap across ``e`` and far shorter than the way back along it, and a
snooker jump must land within ~0.001 of the ridge along ``e``.  With the seed used here it stays
in the trap for all 1,500 steps and the old sampler's stored draws fail the rule.
"""

from __future__ import annotations

import math

import emcee
import numpy as np
import pytest

from rrfrei.calibration.convergence import CHECK, RHAT_LIMIT, check
from rrfrei.calibration.sampler import STUCK_SD, moves, restart_walkers, stuck_walkers

NDIM, WALKERS = 4, 32
E = np.full(NDIM, 0.5)  # unit vector: the posterior's narrow direction
TRAP = 3.0 * E


def log_prob(x: np.ndarray) -> np.ndarray:
    along = x @ E
    across = x - along[:, None] * E
    main = -0.5 * (np.sum(across * across, axis=1) + (along / 0.001) ** 2)
    trap = -30.0 - 0.5 * np.sum(((x - TRAP) / 0.05) ** 2, axis=1)
    return np.logaddexp(main, trap)


def run(steps: int, restart: bool, seed: int = 0) -> tuple[np.ndarray, np.ndarray, int, int]:
    """(chain, log_prob, restart step, walkers restarted) of the ensemble with one walker in the
    trap, in chunks of CHECK steps as run_chain runs it."""
    rng = np.random.default_rng(seed)
    x0 = rng.standard_normal((WALKERS, NDIM))
    x0 -= (0.999 * (x0 @ E))[:, None] * E  # the main mode's shape
    x0[0] = TRAP
    sampler = emcee.EnsembleSampler(WALKERS, NDIM, log_prob, vectorize=True, moves=moves())
    sampler.random_state = np.random.RandomState(seed).get_state()
    state = emcee.State(x0)
    chain, lp, start, restarted = [], [], 0, 0
    while len(chain) < steps:
        for new in sampler.sample(state, iterations=CHECK, store=False):
            state = new
            chain.append(new.coords.copy())
            lp.append(new.log_prob.copy())
        stuck = stuck_walkers(np.array(lp[-CHECK:]), NDIM)
        if restart and stuck.any():
            state = restart_walkers(state, stuck, np.random.default_rng([seed, len(chain)]), log_prob)
            start, restarted = len(chain), restarted + int(stuck.sum())
    return np.array(chain), np.array(lp), start, restarted


SEED = 2


def test_a_walker_in_a_far_trap_stays_there_without_restarts_so_the_rule_fails():
    chain, lp, _, _ = run(1500, restart=False, seed=SEED)
    assert np.all(np.abs(chain[:, 0] - TRAP) < 0.5)  # in the trap all along the 1,500 steps
    assert not check(chain, 1000).draws_ok  # R-hat and tail ESS of the stored draws


def test_the_stuck_walker_is_restarted_and_the_kept_chain_passes_the_rule():
    chain, lp, start, restarted = run(1500, restart=True, seed=SEED)
    assert restarted == 1 and start == CHECK  # found at the first check, the only one
    chk = check(chain, 1000, start=start)
    assert chk.burn >= start  # nothing from before the restart is kept
    assert chk.draws_ok and chk.rhat < RHAT_LIMIT
    kept = chain[chk.burn:]
    assert np.max(np.abs(kept @ E)) < 0.1  # no draw from the trap


def test_a_healthy_ensemble_has_no_stuck_walker():
    rng = np.random.default_rng(1)
    # log posterior of draws from an 8-dimensional Gaussian posterior: -chi2_8 / 2
    recent = -0.5 * rng.chisquare(8, size=(CHECK, WALKERS))
    assert not stuck_walkers(recent, 8).any()
    recent[:, 5] -= STUCK_SD * math.sqrt(8 / 2) + 1.0
    assert np.flatnonzero(stuck_walkers(recent, 8)).tolist() == [5]


def test_when_most_walkers_are_low_none_is_called_stuck():
    recent = np.zeros((CHECK, WALKERS))
    recent[:, : WALKERS // 2 + 1] -= 100.0  # the ensemble has not settled yet: no restarts
    assert not stuck_walkers(recent, NDIM).any()


@pytest.mark.parametrize("seed", [0, 1])
def test_restarted_walkers_land_next_to_healthy_walkers_never_onto_one(seed):
    """Two walkers at one point make the snooker move's proposal 0 / 0 (NaN coordinates)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((8, NDIM))
    state = emcee.State(x, log_prob=log_prob(x))
    stuck = np.zeros(8, dtype=bool)
    stuck[[2, 5]] = True
    new = restart_walkers(state, stuck, np.random.default_rng(seed), log_prob)
    spread = np.ptp(x[~stuck], axis=0)
    for w in (2, 5):
        gap = np.min(np.linalg.norm(x[~stuck] - new.coords[w], axis=1))
        assert 0 < gap <= 0.02 * np.linalg.norm(spread)  # next to a healthy walker, not on it
        assert new.log_prob[w] == log_prob(new.coords[w][None, :])[0]
    assert np.all(new.coords[~stuck] == x[~stuck]) and np.all(new.log_prob[~stuck] == state.log_prob[~stuck])
    assert len({tuple(c) for c in new.coords}) == 8


def test_a_run_with_a_restart_never_proposes_nan():
    """The production move mixture keeps going after restarts (it raised on NaN coordinates when
    a restarted walker sat exactly on its donor)."""
    chain, lp, start, restarted = run(400, restart=True, seed=SEED)
    assert restarted >= 1 and np.all(np.isfinite(chain)) and np.all(np.isfinite(lp))
