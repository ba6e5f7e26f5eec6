"""The evaluations of one fit spread over forked processes.

A building's output-error fit spends its time in simulations that do not depend on one another:
the population of a CMA-ES generation, the columns of a finite-difference Jacobian, the draws of
the importance check.  :class:`ForkMap` evaluates such a batch in ``workers`` forked processes
(``concurrent.futures.ProcessPoolExecutor`` with the ``fork`` start method, so the model, its data
and its compiled kernels are inherited, never pickled), in order, and returns what one process
would: the same function on the same arguments, so a fit is bit for bit the one a single process
makes.

How many processes a fit may use is the process's share of the machine
(:func:`evaluation_workers`, set with :func:`sharing`): the gap diagnosis gives its processes to
the fits while it runs one fit at a time, and takes them back while a second process of its own
fits other candidates (:mod:`rrfrei.gap.parallel`), so the machine is never oversubscribed.

Where processes cannot be forked (no ``fork``, a daemonic pool worker, a child of a map) or none
can be started, and when a process of the pool dies, the batch is evaluated in this process: a
broken pool costs time, never an evaluation.
"""

from __future__ import annotations

import contextlib
import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

__all__ = ["ForkMap", "evaluation_workers", "sharing"]

_SHARE = [1]
"""Processes the fits of this process may use (a stack: :func:`sharing`)."""
_TASK: list = [None]
"""The function of the open map, inherited by its forked processes."""


def evaluation_workers() -> int:
    """Processes the fits of this process may use for their evaluations (1 unless a caller gave
    it more with :func:`sharing`)."""
    return _SHARE[-1]


@contextlib.contextmanager
def sharing(workers: int) -> Iterator[None]:
    """Within the block, the fits of this process may use ``workers`` processes."""
    _SHARE.append(max(1, int(workers)))
    try:
        yield
    finally:
        _SHARE.pop()


def _call(arg):
    return _TASK[0](arg)


def _can_fork() -> bool:
    return ("fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon and _TASK[0] is None)


class ForkMap:
    """``fn`` mapped over batches of arguments in ``workers`` forked processes (module docstring).

    Use as a context manager; :meth:`map` returns ``[fn(a) for a in args]``.  ``workers`` <= 1,
    or no fork: everything in this process.  The processes start at the first batch of two or
    more arguments and end with the block.
    """

    def __init__(self, fn: Callable, workers: int | None = None) -> None:
        self.fn = fn
        self.workers = evaluation_workers() if workers is None else int(workers)
        self.pool: ProcessPoolExecutor | None = None
        self.broken = False
        self.parallel_calls = 0

    def __enter__(self) -> ForkMap:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _open(self) -> ProcessPoolExecutor | None:
        if self.pool is None and not self.broken and self.workers > 1 and _can_fork():
            _TASK[0] = self.fn
            try:
                self.pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("fork"))
            except OSError:
                self.broken = True
            finally:
                if self.pool is None:
                    _TASK[0] = None
        return self.pool

    def map(self, args: Sequence) -> list:
        """``[fn(a) for a in args]``, in order."""
        args = list(args)
        pool = self._open() if len(args) > 1 else None
        if pool is not None:
            try:
                out = list(pool.map(_call, args))
                self.parallel_calls += len(args)
                return out
            except (BrokenProcessPool, OSError):  # a process died: this batch here, the rest too
                self.broken = True
                self.close()
        return [self.fn(a) for a in args]

    def close(self) -> None:
        """End the processes."""
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
            _TASK[0] = None
