"""Slow tier: frequentist coverage of the Bayesian intervals and LOO model choice, per law.

For each law, 20 synthetic tests (protocol 1, noise sd 0.1 kN, seeds 100..119) are calibrated;
the central 95 % interval of every identifiable parameter must cover the truth in >= 85 % of the
(seed, parameter) cases, and the 95 % predictive band with noise must cover between 90 % and 99 %
of the observations of each test.  Model choice: for data from each law, PSIS-LOO ranks that law
first, or within 2 dse of the first where the laws are nested (elastomeric_x is a special case of
bouc_wen; plasticity is bouc_wen's sharp-yield limit).
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from test_calibration import CHAIN, FIXED, NOT_IDENTIFIABLE, SIGMA, TRUTH, quiet_calibrate, synthetic

from rrfrei.calibration import compare, predict

SEEDS = range(100, 120)
NESTED = {("elastomeric_x", "bouc_wen"), ("plasticity", "bouc_wen")}


def _one_seed(law: str, seed: int) -> tuple[int, int, float]:
    """Calibrate one synthetic test: (interval hits, cases, predictive coverage)."""
    w, s = CHAIN[law]
    test = synthetic(law, seed)
    cal = quiet_calibrate(test, law, walkers=w, steps=2 * s, seed=seed, fixed=FIXED[law])
    lo, hi = np.quantile(cal.theta(), [0.025, 0.975], axis=0)
    truth = {**TRUTH[law], "sigma": SIGMA}
    hits = cases = 0
    for n, a, b in zip(cal.sampled, lo, hi):
        if n in NOT_IDENTIFIABLE[law]:
            continue
        cases += 1
        hits += int(a <= truth[n] <= b)
    return hits, cases, float(predict(cal, test, n=200, seed=seed).coverage)


def _single_threaded() -> None:
    import numba

    numba.set_num_threads(1)


@pytest.fixture(scope="module")
def pool():
    """Worker processes with one Numba thread each: the walker batches of these short test chains
    are too small for a multi-threaded likelihood to pay, so one seed per core is ~2x faster.
    (Set inside the workers: changing NUMBA_NUM_THREADS in this process after its threads are
    running would break later parallel calls here.)"""
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 2, initializer=_single_threaded,
                             mp_context=multiprocessing.get_context("spawn")) as ex:
        yield ex


@pytest.mark.slow
@pytest.mark.parametrize("law", ["plasticity", "bouc_wen", "elastomeric_x", "hdr"])
def test_95_percent_intervals_cover_the_truth_in_at_least_85_percent_of_cases(law, pool):
    results = list(pool.map(_one_seed, [law] * len(SEEDS), list(SEEDS)))
    hits = sum(r[0] for r in results)
    cases = sum(r[1] for r in results)
    pred_cov = [r[2] for r in results]
    assert hits / cases >= 0.85, f"{law}: 95 % intervals covered the truth in {hits}/{cases} cases"
    assert 0.90 <= min(pred_cov) and max(pred_cov) <= 0.99, f"{law}: predictive coverage {pred_cov}"


@pytest.mark.slow
@pytest.mark.parametrize("law", ["plasticity", "bouc_wen", "elastomeric_x", "hdr"])
def test_loo_ranks_the_generating_law_first_or_within_two_dse_when_nested(law):
    test = synthetic(law, 7)
    cals = {}
    for cand in ("plasticity", "bouc_wen", "elastomeric_x", "hdr"):
        if cand == "elastomeric_x" and not test.geometry:
            continue
        w, s = CHAIN[cand]
        cals[cand] = quiet_calibrate(test, cand, walkers=w, steps=2 * s, seed=7)
    t = compare(cals).table
    if t.index[0] != law:
        assert (law, t.index[0]) in NESTED, f"data from {law}: LOO ranks {list(t.index)}"
        assert t.loc[t.index[0], "elpd_loo"] - t.loc[law, "elpd_loo"] <= 2 * t.loc[law, "dse_loo"]
