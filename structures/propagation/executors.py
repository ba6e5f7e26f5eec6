"""Where the chunks of a propagation run: here, or on any executor with ``.submit``.

:func:`run_chunk` is the task: one record x one scale x a block of parameter draws through the
batched Newmark kernel (:func:`structures.dynamics.history.time_history_batch`, threads over
blocks of draws).  The other functions adapt ``concurrent.futures`` executors and a
``dask.distributed.Client`` to one interface.  A task on an executor sets its Numba thread count
to ``max(1, cores // workers)`` so that threads x workers never exceeds the cores.

Units: m, s, kN, tonnes.
"""

from __future__ import annotations

import os
from concurrent.futures import as_completed as futures_completed

import numba
import numpy as np

from structures.dynamics.history import time_history_batch

__all__ = ["as_completed", "is_dask", "run_chunk", "set_threads", "submit", "workers"]


def run_chunk(building, record, scale: float, params: np.ndarray, threads: int | None = None) -> dict:
    """Run ``params`` (m, n_params) on ``record`` x ``scale``: dict of per-run demand arrays.

    ``threads`` sets this thread's Numba thread count (executors pass ``cores // workers``);
    None keeps the default (all cores).
    """
    set_threads(threads)
    rec = record if scale == 1.0 else record.scaled(scale)
    out = time_history_batch(building, rec, np.ascontiguousarray(params, dtype=float))
    return {k: np.asarray(v) for k, v in out.items()}


def set_threads(threads: int | None) -> None:
    """Set this thread's Numba thread count to ``threads`` (clipped to [1, the Numba maximum]);
    None keeps it."""
    if threads is not None:
        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


# ---------------------------------------------------------------------------------------------
# executors
# ---------------------------------------------------------------------------------------------
def is_dask(executor) -> bool:
    """True for a ``dask.distributed.Client``."""
    return type(executor).__module__.split(".")[0] == "distributed"


def workers(executor) -> int:
    """Worker threads of the executor (Dask: summed over workers; else ``_max_workers`` or the cores)."""
    if is_dask(executor):
        return max(1, int(sum(executor.nthreads().values())))
    n = getattr(executor, "_max_workers", None)
    return max(1, int(n)) if n else (os.cpu_count() or 1)


def submit(executor, fn, *args):
    """``executor.submit(fn, *args)`` (Dask: ``pure=False``, each chunk is run)."""
    if is_dask(executor):
        return executor.submit(fn, *args, pure=False)
    return executor.submit(fn, *args)


def as_completed(executor, futures):
    """The futures in the order they finish (Dask's or ``concurrent.futures``' iterator)."""
    if is_dask(executor):
        from distributed import as_completed as dask_completed  # optional (rrfrei[dask]), only for a Client

        return dask_completed(futures)
    return futures_completed(futures)
