"""The candidates' refits shared with a second, forked process.

The refits of the candidate effects (step 2 of :mod:`rrfrei.gap.diagnose`) are independent of one
another: each starts from the baseline's fits; so are the refits of one combination step (step 5),
each from the current combination.  With ``workers=2`` a forked process fits them from
the end of the list while the diagnosis works from the front, both through the checkpoint folder:
a fit is claimed by creating ``<step>.claim`` next to its ``.npz`` (``O_CREAT | O_EXCL``, so only
one process fits it), and saved atomically when done; the diagnosis restores the other process's
fits from the folder and scores every effect itself, in its own order.  The fits are those of a
sequential run (same model, data, seed and starts), so the report is too.  A refit the other
process cannot finish (failure, time budget, a process that died) is fitted by the diagnosis, which
reports what fails.  Where processes cannot be forked (no ``fork``, a daemonic pool worker, no
process to spare), or without a checkpoint folder, everything runs in one process.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Sequence

from rrfrei.budget import TimeBudget
from rrfrei.forkmap import sharing
from rrfrei.gap.checkpoint import Checkpoint, _fit_or_restore

__all__ = ["SharedRefits", "default_workers"]

POLL_S = 0.05
"""Interval at which the diagnosis looks for a fit the other process is making [s]."""


def default_workers() -> int:
    """Processes for the candidates' refits when the user gives none: 2 on a machine with two or
    more cores, else 1."""
    return 2 if (os.cpu_count() or 1) >= 2 else 1


class SharedRefits:
    """The candidates' refits shared with a forked process (module docstring).

    Parameters
    ----------
    ck : the diagnosis's checkpoint (its folder is where the processes meet).
    jobs : (checkpoint step, model) of each refit, in the diagnosis's order: what the refits need, as
        the diagnosis calls them, ``model.fit(data, seed=seed, start=starts)``.
    data, starts, seed, budget : as those calls take them.
    workers : processes in all; 1 (or no folder, or no fork): none is started.
    """

    def __init__(self, ck: Checkpoint, jobs: Sequence[tuple[str, object]], data, starts, seed: int,
                 budget: TimeBudget, workers: int = 1) -> None:
        self.ck, self.data = ck, data
        self.starts, self.seed, self.budget = starts, seed, budget
        self.jobs = list(jobs)
        self.proc = None
        self.helped: set[str] = set()
        if workers < 2 or ck.folder is None or "fork" not in multiprocessing.get_all_start_methods():
            return
        if multiprocessing.current_process().daemon:  # a pool's worker may not have children
            return
        if len(self.jobs) < 2:
            return
        self._unclaim()  # claims left by an interrupted run
        ck.folder.mkdir(parents=True, exist_ok=True)
        proc = multiprocessing.get_context("fork").Process(target=self._work, daemon=True)
        try:
            proc.start()
        except OSError:  # no process to spare: everything in this one
            return
        self.proc = proc

    def _claim_path(self, step: str):
        p = self.ck._path(step)
        return p.with_name(p.stem + ".claim")

    def _claim(self, step: str) -> bool:
        try:
            fd = os.open(self._claim_path(step), os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return False
        os.close(fd)
        return True

    def _unclaim(self) -> None:
        for step, _ in self.jobs:
            try:
                os.unlink(self._claim_path(step))
            except FileNotFoundError:
                pass

    def _work(self) -> None:
        """The forked process: fit the candidates from the end of the list, each claimed first, each
        fit in this process alone (the diagnosis's fits keep to theirs meanwhile)."""
        with sharing(1):
            self._fit_from_the_end()

    def _fit_from_the_end(self) -> None:
        for step, model in reversed(self.jobs):
            if self.budget.expired():
                return
            if not self._claim(step):
                continue
            try:
                _fit_or_restore(self.ck, step, model, self.data, self.budget, seed=self.seed,
                                start=self.starts)
            except BaseException:  # noqa: BLE001 - the diagnosis refits it and reports the failure
                continue

    def acquire(self, step: str) -> bool:
        """Before the diagnosis makes the fit of checkpoint ``step``: claim it, or wait until the other
        process has saved it (or has ended: the diagnosis then fits it).  Whether the other process
        made it."""
        if self.proc is None:
            return False
        if self._claim(step):
            return False
        path = self.ck._path(step)
        while self.proc.is_alive() and not path.is_file():
            time.sleep(POLL_S)
        if path.is_file():
            self.helped.add(step)
            return True
        return False

    def fit(self, step: str, model, workers: int):
        """The fit of checkpoint ``step`` (``model`` from the starts): restored when the other
        process made it (:meth:`acquire`), else made here, over ``workers`` processes when no
        second process runs and in this one alone while it does.  A fit the other process made is
        not counted as a reuse of an earlier run's."""
        helped = self.acquire(step)
        with sharing(1 if self.proc is not None else workers):
            fit = _fit_or_restore(self.ck, step, model, self.data, self.budget, seed=self.seed,
                                  start=self.starts)
        if helped and step in self.ck.reused:
            self.ck.reused.remove(step)
        return fit

    def close(self) -> None:
        """End the other process (its remaining claims are fitted by nobody: the loop is done)."""
        if self.proc is None:
            return
        if self.proc.is_alive():
            self.proc.terminate()
        self.proc.join()
        self._unclaim()
