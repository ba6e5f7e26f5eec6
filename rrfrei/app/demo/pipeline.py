"""The demo's pipeline: run the steps in order, each into its section, and write the page."""

from __future__ import annotations

import os
import pickle
import time
import traceback
from collections.abc import Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rrfrei import __version__
from rrfrei.app.demo import steps as _steps
from rrfrei.app.demo.context import EXPECTED_FAILURES, SYNTHETIC, DemoContext, DemoSettings, Placeholder, Step
from rrfrei.app.report import Report, Section
from rrfrei.budget import stderr_is_tty


@dataclass(frozen=True)
class DemoResult:
    """Where the page is, the report object and the status of every step."""

    page: Path
    report: Report
    seconds: float

    @property
    def ok(self) -> bool:
        return self.report.ok

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(s.key for s in self.report.sections if s.status != "ok")


def run_step(step: Step, ctx: DemoContext) -> Section:
    """Run one step into a fresh section; errors and placeholders are caught into the section."""
    sec = Section(step.key, step.title)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        step.func(ctx, sec)
        if not sec.reading:
            raise RuntimeError(f"step {step.key!r} produced no reading")
    except Placeholder as exc:
        sec.placeholder = True
        sec.reading = f"Placeholder: {exc}."
    except EXPECTED_FAILURES as exc:  # a failing step must not kill the page; a bug (TypeError,
        # AttributeError, ...) is not caught: it must show, not hide in a page
        tb = traceback.extract_tb(exc.__traceback__)[-3:]
        where = "".join(traceback.format_list(tb))
        sec.error = f"{type(exc).__name__}: {exc}\n\nWhere:\n{where}"
    sec.seconds = time.perf_counter() - t0
    sec.cpu_seconds = time.process_time() - c0
    return sec


def _side_process() -> None:
    """Initialiser of the second process: figures off-screen, one Numba thread (the main process
    keeps the machine's threads for its batched kernels; two processes need not oversubscribe)."""
    import matplotlib
    import numba

    matplotlib.use("Agg")
    numba.set_num_threads(1)


def _can_run_aside(step: Step) -> bool:
    """An ``alone`` step whose function a second process can import (a module-level function)."""
    if not step.alone:
        return False
    try:
        pickle.dumps(step)
    except (pickle.PicklingError, AttributeError, TypeError):
        return False
    return True


def _handoff(ctx: DemoContext) -> DemoContext:
    """What a step run aside may read of the steps before it: the settings, the tests and the best
    law (picklable; the calibrations stay here)."""
    return DemoContext(settings=ctx.settings, progress=False, tests=dict(ctx.tests), best_law=ctx.best_law)


def _ahead(work, ctx: DemoContext) -> None:
    """Run ``work(ctx)`` ahead of a step (compiling its kernels); a failure on valid input is left
    to the step itself to meet and show."""
    try:
        work(ctx)
    except EXPECTED_FAILURES:
        pass


def _run_steps(steps: Sequence[Step], ctx: DemoContext, aside: set[str],
               progress: bool) -> dict[str, Section]:
    """Run ``steps``: those in ``aside`` in one second (spawned) process, in the order they become
    ready (at once, or when the step they come ``after`` has finished here), the others here in
    page order.  The second process first does the work :data:`~rrfrei.app.demo.steps.AHEAD`
    lists for the steps that run here, which run last here.  If the second process cannot run
    (it died, or a script without a ``__main__`` guard re-ran itself in it), the steps it had
    not finished run here.
    Returns the sections by key."""
    by_key = {s.key: s for s in steps}
    sections: dict[str, Section] = {}
    pending: dict[str, Future] = {}
    here = [s for s in steps if s.key not in aside]
    waiting = [s for s in steps if s.key in aside]
    pool = None
    if waiting:
        # a step whose kernels the second process compiles ahead runs last here, when they are
        # compiled (:data:`~rrfrei.app.demo.steps.AHEAD`: no later step reads its results)
        here.sort(key=lambda h: h.key in _steps.AHEAD)
        import multiprocessing

        # spawn, not fork: the parent's Numba thread pool and BLAS threads do not survive a fork
        pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_side_process)
    done_here: set[str] = set()

    def submit_ready() -> None:
        for s in list(waiting):
            if s.after is None or s.after in done_here or s.after not in {h.key for h in here}:
                try:
                    pending[s.key] = pool.submit(run_step, s, _handoff(ctx))
                except BrokenProcessPool:
                    return  # left waiting: run here below
                waiting.remove(s)

    ahead: list[Future] = []
    try:
        if pool is not None:
            try:
                ahead = [pool.submit(_ahead, _steps.AHEAD[h.key], _handoff(ctx))
                         for h in here if h.key in _steps.AHEAD]
            except BrokenProcessPool:
                pass
            submit_ready()
        bar = _steps.tqdm_or_plain(steps, progress, desc="rrfrei demo", unit="step")
        order = iter(bar)
        for step in here:
            next(order, None)
            if hasattr(bar, "set_postfix_str"):
                bar.set_postfix_str(step.key)
            sections[step.key] = run_step(step, ctx)
            done_here.add(step.key)
            if waiting:
                submit_ready()
        for key in [*pending, *(s.key for s in waiting)]:
            next(order, None)
            if hasattr(bar, "set_postfix_str"):
                bar.set_postfix_str(key)
            try:
                # a bug in a step run aside is raised here, as it would be here
                sections[key] = pending[key].result() if key in pending else run_step(by_key[key], ctx)
            except BrokenProcessPool:
                sections[key] = run_step(by_key[key], ctx)
        for fut in ahead:
            try:
                fut.result()
            except BrokenProcessPool:
                pass
        for _ in order:
            pass
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    return sections


def run_demo(
    out: str | Path = "rrfrei-report",
    *,
    quick: bool = False,
    seed: int = 0,
    progress: bool = True,
    settings: DemoSettings | None = None,
    steps: Sequence[Step] | None = None,
    parallel: bool | None = None,
) -> DemoResult:
    """Run every step and write the page ``out/index.html`` with its tables and manifest.

    Parameters
    ----------
    out : folder to write (created if needed).
    quick : fewer walkers/steps, samples, records and a shorter rubber fit (the page says so).
    seed : seed of every stochastic step.
    progress : show tqdm progress bars on the long steps.
    settings : explicit step sizes (overrides ``quick``/``seed``).
    steps : the steps to run (default :data:`rrfrei.app.demo.steps.STEPS`).
    parallel : use a second process while this one runs the chain of steps: it first compiles the
        kernels of the propagation step ahead (:data:`~rrfrei.app.demo.steps.AHEAD`), then runs
        the steps marked ``alone``, at once (the rubber fits) or once the step they come
        ``after`` has finished here (the gap diagnosis needs the comparison's best law); the page
        is the same, in the same order.  None (default): when the machine has at least 2 cores.

    Returns
    -------
    DemoResult with ``ok`` False when a step failed or is a placeholder.
    """
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    if settings is None:
        settings = DemoSettings.quick_run(int(seed)) if quick else DemoSettings.full_run(int(seed))
    else:
        settings = replace(settings)
    steps = _steps.STEPS if steps is None else tuple(steps)

    report = Report(
        "rrfrei: from isolator tests to building response",
        intro=(
            "Every workflow of rrfrei run on the bundled data: calibration of four isolator laws on a "
            "cyclic shear test, model comparison, validation on held-out tests, sim-to-real gap "
            "diagnosis, propagation of the posterior through ground motions on an example "
            "building, and the polyurethane model fits. Every reading below is computed from the "
            "numbers of this run."
        ),
    )
    report.banner(
        f"The isolator tests are {SYNTHETIC} RR-FREI-like tests (made by an independent model with "
        "noise); no real RR-FREI test data are public.",
        "synthetic",
    )
    if settings.quick:
        report.banner(
            f"This is a QUICK run (--quick): {len(settings.laws)} of the 4 laws "
            f"({', '.join(settings.laws)}), short chains, "
            + (f"{len(settings.gap_effects)} gap effects ({', '.join(settings.gap_effects)}), "
               if settings.gap_effects is not None else "")
            + "few samples, records and stripes, a short rubber fit. Numbers are indicative only; run "
            "without --quick for the full analysis.",
            "note",
        )
    report.meta.update(
        {
            "rrfrei version": __version__,
            "run": "quick" if settings.quick else "full",
            "seed": settings.seed,
            "date": time.strftime("%Y-%m-%d %H:%M"),
        }
    )
    # inner bars (optimiser, sampler, gap, propagation, fits) only on a terminal: in a log every
    # tqdm refresh is a new line, and the step bar below says enough
    inner = progress and stderr_is_tty()
    ctx = DemoContext(settings=settings, progress=inner)
    t0 = time.perf_counter()
    if parallel is None:
        parallel = (os.cpu_count() or 1) >= 2
    aside = {s.key for s in steps if _can_run_aside(s)} if parallel else set()
    if len(aside) == len(steps):
        aside = set()  # nothing would run here: no second process
    sections = _run_steps(steps, ctx, aside, progress)
    for step in steps:
        report.add(sections[step.key])
    seconds = time.perf_counter() - t0
    report.meta["total time"] = f"{seconds:.0f} s"
    page = report.write(out)
    return DemoResult(page=page, report=report, seconds=seconds)
