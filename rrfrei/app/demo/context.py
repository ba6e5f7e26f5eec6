"""What the demo's steps share: the step sizes, the running context and the failure rules."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rrfrei.app.report import Section

LAWS = ("plasticity", "bouc_wen", "elastomeric_x", "hdr")
TESTS = ("protocol1", "protocol2", "protocol3", "protocol4")
SYNTHETIC = "SYNTHETIC"


#: Failures a demo step may meet on valid input (bad data, numerical failure, a structural
#: analysis that did not converge, a file problem); they are written into the page.  Anything
#: else is a bug and propagates.
EXPECTED_FAILURES: tuple[type[BaseException], ...] = (
    ValueError, RuntimeError, ArithmeticError, OSError, np.linalg.LinAlgError)


class Placeholder(Exception):
    """A step's workflow is not available yet: its section is a placeholder, not a result."""


@dataclass(frozen=True)
class DemoSettings:
    """Sizes of every step (the defaults are the full run; :meth:`quick_run` the quick one)."""

    quick: bool = False
    seed: int = 0
    laws: tuple[str, ...] = LAWS
    walkers: int = 32
    steps: int | None = None  # None: until converged (>= 50 tau, stable), up to max_steps
    max_steps: int = 2000
    gap_draws: int = 200
    gap_effects: tuple[str, ...] | None = None  # None: every catalogue effect
    n_samples: int = 100
    records: tuple[str, ...] | None = None  # None: every bundled record (as recorded)
    # fragility: multiple stripe analysis at Sa(T_iso, 5 %) (structures.propagation.stripes)
    stripe_records: tuple[str, ...] | None = None  # None: every bundled record
    stripes: int = 7
    stripe_samples: int = 20
    building: str = "five_story"
    rubber_evals: int = 800
    rubber_restarts: int = 1
    rubber_polish_evals: int | None = None  # None: the polish stops by its tolerances
    predict_draws: int = 200
    # the real base-isolated building (BNCS shake-table runs): calibrate -> hold out
    shake_calibrate: tuple[str, ...] = ("CNP100", "LAC100", "ICA50")
    shake_holdout: tuple[str, ...] = ("ICA100",)
    shake_law: str = "auto"
    shake_rate_hz: float = 25.0
    shake_draws: int = 30  # posterior draws per building fit (each one a simulation)
    # a cap, not a target: the whole default split takes about 160 s warm on 2 cores alone
    # (benchmarks/RESULTS.md, bench_shake_table); the demo's other steps may share the cores
    shake_budget_s: float = 300.0
    shake_effects: tuple[str, ...] | None = None  # None: every catalogue effect

    @classmethod
    def full_run(cls, seed: int = 0) -> DemoSettings:
        return cls(seed=seed)

    @classmethod
    def quick_run(cls, seed: int = 0) -> DemoSettings:
        return cls(
            quick=True,
            seed=seed,
            laws=("plasticity", "bouc_wen"),  # two of the four: each law compiles its own kernels
            gap_effects=("rollover", "stiffening", "degradation", "mullins"),
            walkers=24,
            steps=200,
            gap_draws=60,
            n_samples=16,
            records=("elcentro", "kocaeli"),
            stripe_records=("rinaldi", "tabas", "santamonica", "elcentro"),
            stripes=6,
            stripe_samples=6,
            rubber_evals=300,
            rubber_restarts=1,
            rubber_polish_evals=150,
            predict_draws=100,
            shake_calibrate=("ICA50",),
            shake_law="plasticity",
            shake_draws=20,
            shake_budget_s=120.0,  # a cap, not a target: ~25 s of CPU; a slow machine still gets a diagnosis
            shake_effects=("rate", "mullins", "scragging", "stiffening"),
        )


@dataclass
class DemoContext:
    """What the steps share: settings, the loaded tests and the results of earlier steps."""

    settings: DemoSettings
    progress: bool = True
    tests: dict[str, Any] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    best_law: str | None = None
    results: dict[str, Any] = field(default_factory=dict)

    def need(self, what: str, step: str) -> Any:
        """The result ``what`` of an earlier step, or an error saying that step did not give it."""
        value = getattr(self, what, None) if what != "results" else self.results
        if not value:
            raise RuntimeError(f"this step needs the result of the '{step}' step, which did not finish")
        return value


@dataclass(frozen=True)
class Step:
    """One section of the page: ``func(ctx, section)`` fills it.

    ``alone``: the step gives no result to a later step and needs none from an earlier one but
    the tests and the best law, which it reads once the step ``after`` (a key; None: none) has
    finished; it may then run in a second process beside the others
    (:func:`rrfrei.app.demo.run_demo`, ``parallel``).
    """

    key: str
    title: str
    func: Callable[[DemoContext, Section], None]
    alone: bool = False
    after: str | None = None
