"""A fit's evaluations spread over forked processes (rrfrei.forkmap) give what one process gives,
in order, bit for bit; a process of the map that dies costs time, never an evaluation; and the
share of the machine a fit may use is the caller's to give."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest

from rrfrei.forkmap import ForkMap, evaluation_workers, sharing
from structures.shake_table.simulation import BuildingData, Superstructure
from tests._shake_table_truth import PL, model_of

pytestmark = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(),
                                reason="needs the fork start method")


def _heavy(x):
    """A deterministic evaluation that is not trivial to reorder: (pid, value)."""
    v = np.sin(np.arange(2000) * float(x)).cumsum()
    return os.getpid(), v


def test_two_processes_return_the_evaluations_of_one_in_order():
    args = [0.1 * i for i in range(9)]
    with ForkMap(_heavy, workers=2) as fm:
        out = fm.map(args)
        assert fm.parallel_calls == len(args)
    for a, (pid, v) in zip(args, out):
        assert pid != os.getpid()  # evaluated by a process of the map
        np.testing.assert_array_equal(v, _heavy(a)[1])


def test_one_worker_or_one_argument_runs_here():
    with ForkMap(_heavy, workers=1) as fm:
        assert {pid for pid, _ in fm.map([0.1, 0.2, 0.3])} == {os.getpid()}
    with ForkMap(_heavy, workers=2) as fm:
        assert fm.map([0.5])[0][0] == os.getpid()
        assert fm.pool is None  # no process started for a single evaluation


def test_a_process_that_dies_costs_no_evaluation():
    parent = os.getpid()

    def dies_in_a_child(x):
        if os.getpid() != parent and x > 0.25:
            os._exit(1)
        return _heavy(x)[1]

    args = [0.1, 0.2, 0.3, 0.4]
    with ForkMap(dies_in_a_child, workers=2) as fm:
        out = fm.map(args)
        assert fm.broken and fm.pool is None
        again = fm.map(args)  # the rest of the fit runs here
    for a, v, w in zip(args, out, again):
        np.testing.assert_array_equal(v, _heavy(a)[1])
        np.testing.assert_array_equal(w, v)


def test_a_map_inside_a_map_process_runs_in_that_process():
    """A child of a map never forks a map of its own (no nested pools oversubscribing the cores)."""
    def inner_pids(x):
        with ForkMap(_heavy, workers=2) as fm:
            return os.getpid(), {pid for pid, _ in fm.map([x, 2 * x, 3 * x])}

    with ForkMap(inner_pids, workers=2) as fm:
        for pid, pids in fm.map([0.1, 0.2]):
            assert pids == {pid}


def test_the_share_is_given_by_the_caller_and_taken_back():
    assert evaluation_workers() == 1  # a fit alone uses one process unless told otherwise
    with sharing(2):
        assert evaluation_workers() == 2 and ForkMap(_heavy).workers == 2
        with sharing(1):
            assert evaluation_workers() == 1
        assert evaluation_workers() == 2
    assert evaluation_workers() == 1


def test_a_building_fit_in_two_processes_is_the_fit_in_one(truth, monkeypatch):
    """The output-error fit's CMA-ES generations, Jacobians and importance draws evaluated in two
    processes: the same optimum, draws, weights and counts, bit for bit."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), {**PL, "qd": 0.8 * PL["qd"]}, draws=6)
    monkeypatch.setattr(m, "global_evals", 24)
    monkeypatch.setattr(m, "max_nfev", 4)
    cal = BuildingData(tuple(runs), observed=("run1",))
    one = m.fit(cal, seed=3)
    calls = []
    real_map = ForkMap.map

    def spy(self, args):
        out = real_map(self, args)
        calls.append(self.parallel_calls)
        return out

    monkeypatch.setattr(ForkMap, "map", spy)
    with sharing(2):
        two = m.fit(cal, seed=3)
    assert max(calls) > 0  # batches did run in the processes of the map
    np.testing.assert_array_equal(two.x_opt, one.x_opt)
    np.testing.assert_array_equal(two.X, one.X)
    assert (two.ess, two.nfev, two.failed, two.sigma_c, two.rho_c) == (one.ess, one.nfev, one.failed,
                                                                        one.sigma_c, one.rho_c)


def test_the_laws_fitted_in_two_processes_are_those_fitted_in_one(truth, tmp_path):
    """``--law auto`` fits its laws to the isolation loops in forked processes: the same fits, the
    same leave-one-cycle-out ranking as one process."""
    from rrfrei.budget import TimeBudget
    from structures.shake_table.gap import _pick_law
    from structures.shake_table.simulation import calibration_test

    _, runs = truth
    cal = calibration_test(runs[:1], 10.0)
    laws = ("plasticity", "bouc_wen")
    budget = TimeBudget.of(None, "test")
    picks = [_pick_law(cal, laws, 10, 0, budget, [], tmp_path / str(w), w) for w in (1, 2)]
    (law1, df1, fits1), (law2, df2, fits2) = picks
    assert law1 == law2
    np.testing.assert_array_equal(df1["loco_elpd"].to_numpy(), df2["loco_elpd"].to_numpy())
    for law in laws:
        np.testing.assert_array_equal(fits1[law].p_opt, fits2[law].p_opt)
        np.testing.assert_array_equal(fits1[law].P, fits2[law].P)
