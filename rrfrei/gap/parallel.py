"""The candidates' refits shared with a second, forked process.

The refits of the candidate effects (step 2 of :mod:`rrfrei.gap.diagnose`) are independent of one
another: each starts from the baseline's fits.  With ``workers=2`` a forked process fits them from
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
from rrfrei.gap.checkpoint import Checkpoint, _fit_or_restore, effect_step

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
    model, data, effects, starts, seed, budget : what the refits need, as the diagnosis calls them:
        ``model.augment([e]).fit(data, seed=seed, start=starts)`` for each ``e`` of ``effects``.
    workers : processes in all; 1 (or no folder, or no fork): none is started.
    """

    def __init__(self, ck: Checkpoint, model, data, effects: Sequence[str], starts, seed: int,
                 budget: TimeBudget, workers: int = 1) -> None:
        self.ck, self.model, self.data = ck, model, data
        self.starts, self.seed, self.budget = starts, seed, budget
        self.effects = list(effects)
        self.proc = None
        self.helped: set[str] = set()
        if workers < 2 or ck.folder is None or "fork" not in multiprocessing.get_all_start_methods():
            return
        if multiprocessing.current_process().daemon:  # a pool's worker may not have children
            return
        if len(self.effects) < 2:
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
        for e in self.effects:
            try:
                os.unlink(self._claim_path(effect_step(e)))
            except FileNotFoundError:
                pass

    def _work(self) -> None:
        """The forked process: fit the candidates from the end of the list, each claimed first, each
        fit in this process alone (the diagnosis's fits keep to theirs meanwhile)."""
        with sharing(1):
            self._fit_from_the_end()

    def _fit_from_the_end(self) -> None:
        for e in reversed(self.effects):
            if self.budget.expired():
                return
            if self.model.cannot_judge(e, self.data) or not self._claim(effect_step(e)):
                continue
            try:
                _fit_or_restore(self.ck, effect_step(e), self.model.augment([e]), self.data, self.budget,
                                seed=self.seed, start=self.starts)
            except BaseException:  # noqa: BLE001 - the diagnosis refits it and reports the failure
                continue

    def acquire(self, effect: str) -> bool:
        """Before the diagnosis fits ``effect``: claim it, or wait until the other process has saved
        its fit (or has ended: the diagnosis then fits it).  Whether the other process made it."""
        if self.proc is None:
            return False
        step = effect_step(effect)
        if self._claim(step):
            return False
        path = self.ck._path(step)
        while self.proc.is_alive() and not path.is_file():
            time.sleep(POLL_S)
        if path.is_file():
            self.helped.add(step)
            return True
        return False

    def close(self) -> None:
        """End the other process (its remaining claims are fitted by nobody: the loop is done)."""
        if self.proc is None:
            return
        if self.proc.is_alive():
            self.proc.terminate()
        self.proc.join()
        self._unclaim()
