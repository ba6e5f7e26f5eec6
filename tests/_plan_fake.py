"""Stand-ins for the plan building and record pairs, for tests of the code's answers.

:func:`decoupled` is the plan building of a *linear* isolator (or of any isolator under a pair
whose y component is zero) computed as two independent 1-D time histories
(:func:`structures.time_history`), one per direction: with a linear superstructure and an
isotropic linear isolator (``rrfrei.laws.plan`` "linear": F = k u + c v per axis, no coupling)
the two directions do not interact, so this is the plan response exactly, not an approximation.
It returns what :func:`structures.propagation.plan_design.plan_arrays` reads: (n, 2) histories.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

import ground_motions
import structures


@dataclass(frozen=True, eq=False)
class FakePair:
    """A record pair: ``accel`` (n, 2) [m/s^2] at step ``dt`` [s]."""

    name: str
    dt: float
    accel: np.ndarray

    def scaled(self, f: float) -> FakePair:
        return FakePair(self.name, self.dt, np.asarray(self.accel) * float(f))

    def component(self, j: int) -> ground_motions.Record:
        return ground_motions.Record(f"{self.name}-{'xy'[j]}", self.dt, np.asarray(self.accel)[:, j])


def pair_from(record: ground_motions.Record, seconds: float, *, y_factor: float = 0.7, delay: float = 0.5,
              name: str | None = None) -> FakePair:
    """The first ``seconds`` of ``record`` as x, and ``y_factor`` x the same record delayed by
    ``delay`` s as y (0 for a pair along x only)."""
    n = int(seconds / record.dt) + 1
    x = np.asarray(record.accel[:n], dtype=float)
    k = int(round(delay / record.dt))
    y = y_factor * np.concatenate([np.zeros(k), x[: n - k]])
    return FakePair(name or record.name, record.dt, np.column_stack([x, y]))


def decoupled(building, law, params, ground):
    """The plan response of a decoupled (linear, or y = 0) system from two 1-D time histories."""
    bld = building.with_isolator_params(params)
    acc = np.asarray(ground.accel, dtype=float)
    runs = []
    for j in range(2):
        if not np.any(acc[:, j]):
            runs.append(None)
            continue
        runs.append(structures.time_history(bld, ground_motions.Record(f"c{j}", ground.dt, acc[:, j])))
    n, s = acc.shape[0], building.n_stories
    zero1, zero2 = np.zeros(n), np.zeros((n, s))

    def both(attr, zero):
        return np.stack([zero if r is None else getattr(r, attr) for r in runs], axis=-1)

    return SimpleNamespace(
        isolator_disp=both("isolator_disp", zero1),
        base_shear=both("base_shear", zero1),
        drift_ratio=both("drift_ratio", zero2),
        floor_accel_abs=both("floor_accel_abs", zero2),
        energy={"isolator": sum(r.energy["isolator"] for r in runs if r is not None)},
        energy_error=max(r.energy_error for r in runs if r is not None),
    )
