"""The main job: every workflow of the package on the bundled data, as one HTML page.

:func:`run_demo` runs the steps below in order and writes ``DIR/index.html`` (one self-contained
page, figures embedded), ``DIR/tables/*.csv`` and ``DIR/manifest.json`` (see
:mod:`rrfrei.app.report`).  Each step is a function ``step(ctx, section)`` that fills its section with
tables, figures and a short reading computed from the numbers; a step that raises does not stop
the page: its section shows the error, later steps that need its result say so, and
:attr:`DemoResult.ok` is False (the ``rrfrei demo`` command then exits non-zero).

Steps (the isolator tests are SYNTHETIC RR-FREI-like tests, labelled so everywhere):

1. ``tests``        the four bundled tests: loops, per-cycle energy, k_eff and beta_eff;
2. ``calibration``  Bayesian calibration of plasticity, bouc_wen, elastomeric_x and hdr on
                    protocol 1;
3. ``comparison``   PSIS-LOO, WAIC and leave-one-cycle-out of the laws; the best law is the
                    one with the highest LOO elpd;
4. ``validation``   the best law's predictions of the held-out protocols 2-4 (NRMSE, coverage,
                    energy per cycle);
5. ``gap``          sim-to-real gap diagnosis of the best law (where the residuals sit, which
                    unmodelled effect explains them, how far the gap shrinks);
6. ``propagation``  the best posterior through the bundled records on the 5-story example building
                    (as recorded), and its fragility by multiple stripe analysis at Sa(T_iso, 5 %);
7. ``rubber``       the polyurethane PRF model fitted to its protocols and to the real VHB 4910 data.

A step whose workflow is not available raises :class:`Placeholder`: its section is marked as a
placeholder, which the tests and :attr:`DemoResult.ok` do not accept.

Quick runs (``quick=True``) calibrate two of the four laws (plasticity, bouc_wen: every law compiles
kernels of its own, which dominates a first run), try four gap effects, and use fewer walkers and
steps, samples, records and stripes and a shorter rubber fit; the page says so.

Modules: :mod:`~rrfrei.app.demo.context` (settings, the shared context, what a step is),
:mod:`~rrfrei.app.demo.steps` (the computations and tables, :data:`STEPS`),
:mod:`~rrfrei.app.demo.figures` (the figures), :mod:`~rrfrei.app.demo.prose` (the readings) and
:mod:`~rrfrei.app.demo.pipeline` (running the steps and writing the page).
"""

from __future__ import annotations

from rrfrei.app.demo.context import (
    EXPECTED_FAILURES,
    LAWS,
    SYNTHETIC,
    TESTS,
    DemoContext,
    DemoSettings,
    Placeholder,
    Step,
)
from rrfrei.app.demo.pipeline import DemoResult, run_demo, run_step
from rrfrei.app.demo.steps import STEPS

__all__ = ["EXPECTED_FAILURES", "LAWS", "SYNTHETIC", "TESTS", "DemoContext", "DemoResult", "DemoSettings",
           "Placeholder", "STEPS", "Step", "run_demo", "run_step"]
