"""A batch of independent analyses run in parallel: contiguous blocks of runs on threads.

The batch kernels of :mod:`structures.dynamics.newmark` and :mod:`structures.dynamics.plan_newmark`
call their law's compiled ``integrate`` (``@njit(nogil=True)``) once per run from the threads of
this module, ``numba.get_num_threads()`` of them (so :func:`numba.set_num_threads`, and the thread
count an executor gives its task, apply as they did to a ``prange`` kernel).  The runs
``0 .. runs - 1`` are split into ``n_blocks`` contiguous blocks (:func:`block`, the same split as
before); a thread takes the next block when it has finished one.

Why threads and not a Numba ``parallel=True`` kernel with ``prange``: Numba links a called
``@njit`` function into its caller and optimises the whole again, so a ``prange`` kernel
re-optimised the law's whole integrator inside the parallel loop body: 11 to 41 s of compilation
per law and kernel, on top of ``integrate`` itself.  The threads call the very ``integrate`` a
single run compiles (a zero-row :class:`~structures.dynamics.newmark_records.Histories` has the
same type as a full one), so a batch costs no compilation of its own; one call per run costs a
few microseconds of dispatch against milliseconds of analysis.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["block", "run_blocks"]


def block(runs: int, n_blocks: int, b: int) -> tuple[int, int]:
    """The runs [lo, hi) of block ``b`` of ``n_blocks`` contiguous blocks of ``runs`` runs."""
    return (runs * b) // n_blocks, (runs * (b + 1)) // n_blocks


def run_blocks(one: Callable[[int], None], runs: int, n_blocks: int) -> None:
    """Call ``one(run)`` for every run in ``range(runs)``, in ``n_blocks`` contiguous blocks
    spread over ``numba.get_num_threads()`` threads (in the calling thread when that is 1 or
    there is one block).  ``one`` must release the GIL for its work (a ``nogil`` kernel) and
    write only its own run's results.  An exception in a run (or Ctrl-C) is raised here once the
    blocks already started have finished; no further block starts."""
    n_blocks = max(1, min(int(n_blocks), runs))

    def run_block(b: int) -> None:
        lo, hi = block(runs, n_blocks, b)
        for run in range(lo, hi):
            one(run)

    threads = min(numba.get_num_threads(), n_blocks)
    if threads <= 1:
        for b in range(n_blocks):
            run_block(b)
        return
    pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="rrfrei-batch")
    try:
        for _ in pool.map(run_block, range(n_blocks)):
            pass
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)  # an error or Ctrl-C: no new block starts
        raise
    pool.shutdown(wait=True)
