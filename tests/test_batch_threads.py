"""A batch of analyses runs the single analysis's compiled integrator on threads.

Numba links a called ``@njit`` function into its caller and optimises the whole again, so a
``prange`` batch kernel re-optimised the law's whole Newmark integrator (11 to 41 s of compilation
per law, measured with Numba's compile events).  The batch now calls the compiled ``integrate``
once per run from ``numba.get_num_threads()`` threads: it compiles nothing of its own, and its
results do not depend on the number of threads or blocks.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numba
import numpy as np
import pytest
from numba.core.registry import CPUDispatcher

import ground_motions
import structures
from rrfrei.laws import plan as plan_laws
from structures.dynamics import blocks, history, plan_history


def _short_linear():
    rec = ground_motions.load("elcentro")
    short = ground_motions.Record(rec.name, rec.dt, np.array(rec.accel[:300]), rec.meta)
    b = structures.load_building("three_story")
    bld = replace(b, isolator=structures.Isolator("linear", {"k": 300.0, "c": 0.0}, b.isolator.count,
                                                  b.isolator.length_scale))
    return bld, short


def _signatures(module) -> dict[str, int]:
    """Number of compiled signatures of every Numba dispatcher of a kernel instance."""
    return {name: len(obj.signatures) for name, obj in vars(module).items() if isinstance(obj, CPUDispatcher)}


def test_a_batch_compiles_nothing_beyond_the_single_analysis():
    bld, rec = _short_linear()
    rows = np.array([[300.0, 0.0], [250.0, 0.0], [350.0, 0.0]])
    structures.time_history(bld, rec)
    module = history.kernel(bld.isolator.spec)
    before = _signatures(module)
    out = structures.time_history_batch(bld, rec, rows, n_blocks=2)
    assert out["converged"].all()
    assert _signatures(module) == before

    ag = np.column_stack((rec.accel, 0.5 * rec.accel))
    structures.plan_time_history(bld, None, None, ag, dt=rec.dt)
    pmodule = plan_history.kernel(plan_laws.get("linear"))
    pbefore = _signatures(pmodule)
    pout = structures.plan_time_history_batch(bld, None, rows, ag, dt=rec.dt, n_blocks=2)
    assert pout["converged"].all()
    assert _signatures(pmodule) == pbefore


def _batch_on(threads, n_blocks, bld, rec, rows):
    was = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        return structures.time_history_batch(bld, rec, rows, n_blocks=n_blocks)
    finally:
        numba.set_num_threads(was)


def test_the_batch_is_the_same_on_any_number_of_threads_and_blocks():
    """(That a batch's row is the single analysis of its parameters is
    tests/test_structures.py::test_batch_returns_the_peaks_of_single_runs_and_flags_failures.)"""
    bld, rec = _short_linear()
    rows = np.array([[300.0, 0.0], [250.0, 0.01], [350.0, 0.0], [200.0, 0.02], [320.0, 0.0]])
    ref = _batch_on(1, 1, bld, rec, rows)
    assert ref["converged"].all()
    assert len(set(ref["iso_disp_peak"])) == len(rows)  # every row its own analysis
    for threads, n_blocks in [(1, 3), (2, 2), (2, 5), (2, 100)]:
        out = _batch_on(threads, n_blocks, bld, rec, rows)
        assert out.keys() == ref.keys()
        for key, value in ref.items():
            np.testing.assert_array_equal(out[key], value, err_msg=f"{key}: {threads}, {n_blocks}")


def test_the_blocks_cover_every_run_once_and_run_on_the_numba_thread_count():
    seen: list[int] = []
    names: set[str] = set()
    lock = threading.Lock()

    def one(run):
        with lock:
            seen.append(run)
            names.add(threading.current_thread().name)

    was = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        blocks.run_blocks(one, 7, 3)
    finally:
        numba.set_num_threads(was)
    assert sorted(seen) == list(range(7))
    assert names == {threading.current_thread().name}  # one thread: the caller's
    seen.clear()
    blocks.run_blocks(one, 0, 4)
    assert seen == []
    blocks.run_blocks(one, 10, 100)  # more blocks than runs: one run each
    assert sorted(seen) == list(range(10))
    assert [blocks.block(10, 3, b) for b in range(3)] == [(0, 3), (3, 6), (6, 10)]


def test_an_error_in_a_run_is_raised_by_the_batch():
    def one(run):
        if run == 5:
            raise ValueError("run 5")

    with pytest.raises(ValueError, match="run 5"):
        blocks.run_blocks(one, 8, 4)
