"""Validation of the diagnosis on withheld effects: the entry points (issue 7 item 4, issue 12 point 4).

The generator forms, cases, the parallel table and its report live in
:mod:`rrfrei.gap.validation`; this module keeps the short names used by the tests and the CLI:

* :func:`validate` runs the table (every effect of the catalogue by each of its three forms,
  plus the controls, for the given seeds) and returns a :class:`ValidationResult`;
* :func:`make_tests` makes protocols 1-4 of one effect by its first form in the middle of its
  size range, with 1.5 % Gaussian noise, on the ``plasticity`` base law (a fixed example for
  other tests).
"""

from __future__ import annotations

import numpy as np

from rrfrei.gap.validation import (
    BASES,
    FIXED,
    FORMS,
    FULL,
    REDUCED,
    Case,
    Settings,
    ValidationResult,
    forms_of,
    make_case_tests,
    run_table,
)
from rrfrei.gap.validation.forms import EPSlider, Signal, series_solve
from rrfrei.io import ShearTest

__all__ = ["CASES", "make_tests", "ValidationResult", "validate", "BASE_LAW", "BASE_PARAMS", "FIXED"]

BASE_LAW = "plasticity"
BASE_PARAMS = dict(BASES["plasticity"])
CASES = ("control", "degradation", "mullins", "rollover", "rate", "asymmetry", "slip")
"""The effects every catalogue has had since issue 7, and the control."""


def make_tests(
    case: str, seed: int = 0, *, reduced: bool = False, form: str | None = None, size_quantile: float = 0.7
) -> list[ShearTest]:
    """Protocols 1-4 of ``case`` (an effect of :data:`rrfrei.gap.validation.FORMS` or
    ``"control"``) on the ``plasticity`` base law (even ``seed``; odd seeds use ``bouc_wen``).

    ``form`` : the generator form (default the effect's first).  Gaussian noise of 1.5 % of the
    peak force (the controls of the table have other noises: :data:`rrfrei.gap.validation.CONTROLS`).
    ``reduced`` samples at 10 Hz instead of 20 Hz.  ``size_quantile`` : where in the form's size
    range (0 smallest, 1 largest).
    """
    if case != "control" and case not in FORMS:
        raise ValueError(f"case must be one of control, {', '.join(FORMS)}, got {case!r}")
    rate = 10.0 if reduced else 20.0
    if case == "control":
        c = Case("control", "gaussian_0.5%", seed)
        return make_case_tests(c, rate=rate, noise=("gaussian", 0.015)).tests
    name = form or forms_of(case)[0].name
    data = make_case_tests(
        Case(case, name, seed), rate=rate, size_quantile=size_quantile, noise=("gaussian", 0.015)
    )
    return data.tests


def validate(
    seeds: int | list[int] = 1,
    *,
    cases: tuple[str, ...] | None = None,
    reduced: bool = False,
    draws: int | None = None,
    combine: bool = False,
    forms: str = "all",
    workers: int = 1,
    time_budget: float | None = None,
    checkpoint=None,
    progress: bool = False,
) -> ValidationResult:
    """Run the validation table (see :mod:`rrfrei.gap.validation`).

    Parameters
    ----------
    seeds : a count n (seeds 0..n-1) or a list of seeds.
    cases : effects to include, with ``"control"`` for the controls (default: every effect of the
        catalogue that has generator forms, and the controls).
    reduced : the quick settings (:data:`rrfrei.gap.validation.REDUCED`, today the table's own:
        5 Hz, 50 draws; a quick run is one with fewer cases, ``forms``).
    draws : posterior draws per fit (overrides the settings').
    combine : let the diagnosis add further effects (the table scores the first).
    forms : ``"all"`` (three per effect), ``"rotate"`` or ``"first"`` (one per effect and seed).
    workers, time_budget, checkpoint, progress : see :func:`rrfrei.gap.validation.run_table`.
    """
    from rrfrei.gap.validation import cases as make_cases

    base = REDUCED if reduced else FULL
    settings = Settings(
        rate=base.rate, draws=draws or base.draws, combine=combine, case_budget=base.case_budget
    )
    effects = None if cases is None else [c for c in cases if c != "control"]
    controls = ("gaussian_0.5%", "gaussian_3%", "student_t3", "ar1_0.8")
    if cases is not None and "control" not in cases:
        controls = ()
    return run_table(
        make_cases(seeds, effects=effects, controls=controls, forms=forms),
        settings,
        workers=workers,
        time_budget=time_budget,
        checkpoint=checkpoint,
        progress=progress,
    )


def _slip(u, t, p, fs, ks):
    """``plasticity`` (packed ``p``) in series with an elastic-plastic slider of stiffness ``ks``
    [kN/m] and capacity ``fs`` [kN], solved by bisection per sample (an independent peer of the
    catalogue's rigid-plastic ``slip``)."""
    from rrfrei.laws import get

    spec = get("plasticity")
    u = np.asarray(u, dtype=float)
    sig = Signal(
        np.asarray(t, dtype=float),
        u,
        np.zeros_like(u),
        spec.step,
        np.asarray(p, dtype=float),
        np.array(spec.initial_state, dtype=float),
        1.0,
        1.0,
        0.02,
        0.03,
        float(p[0]),
        float(p[2] * p[0]),
        float(p[1]),
    )
    return series_solve(sig, EPSlider(ks, fs))
