"""The named inputs and outputs of the Newmark kernel (:mod:`structures.dynamics.newmark`).

Plain named tuples of arrays and scalars, which Numba passes to and returns from compiled code
(and caches) like any tuple: a field is read by name at no cost.  They live in a module of their
own, not in the kernel template, so that every per-law instance of the template shares one class
for each (see :mod:`rrfrei.laws.specialise`).  Units: kN, m, s, tonnes.

The degrees of freedom are ``[base slab, floor 1, ..., roof]`` (``ndof`` of them, relative to
the ground); story ``i`` (1-based) joins DOF ``i - 1`` and DOF ``i``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from structures.dynamics.energy import TERMS as ENERGY_TERMS

N_ENERGY = len(ENERGY_TERMS)
"""Columns of :attr:`Histories.energy`: the terms of :data:`structures.dynamics.energy.TERMS`."""


class Chain(NamedTuple):
    """The superstructure: a chain of masses joined by story springs and dashpots."""

    mass: np.ndarray
    """(ndof,) lumped masses, base slab first [t]."""
    story_stiffness: np.ndarray
    """(ndof - 1,) story shear stiffness [kN/m]."""
    story_damping: np.ndarray
    """(ndof - 1,) story dashpots [kN s/m]."""
    ground_damping: np.ndarray
    """(ndof,) dashpots from each DOF to the ground [kN s/m] (the mass part of Rayleigh damping;
    zeros for stiffness-proportional damping)."""
    story_height: np.ndarray
    """(ndof - 1,) story heights [m] (drift ratios)."""


class Layer(NamedTuple):
    """The isolation layer: ``count`` bearings of one law, scaled by similitude.

    The layer force is ``count scale^2 F_law(u / scale, v / scale)`` and its tangent
    ``count scale k_law(u / scale)`` (equal stress, see :mod:`structures.building.shear_building`).
    """

    params: np.ndarray
    """The law's parameters at the scale it was calibrated on (its ``param_names`` order)."""
    count: float
    """Number of bearings [-]."""
    scale: float
    """Similitude length scale from the law's specimen to the prototype bearing [-]."""
    state0: np.ndarray
    """The law's initial (virgin) state."""


class Solver(NamedTuple):
    """Newmark, Newton and subdivision settings."""

    gamma: float
    """Newmark gamma [-] (1/2: no numerical damping)."""
    beta: float
    """Newmark beta [-] (1/4: average acceleration)."""
    tol: float
    """Newton convergence on the 2-norm of the displacement correction [m] (NormDispIncr)."""
    max_iter: int
    """Newton iterations per (sub)step before the step is subdivided."""
    max_levels: int
    """A failing step is retried in 2, 4, ..., 2^max_levels substeps."""
    robust: bool
    """At the last subdivision level only, call the law's robust local solve."""


class Histories(NamedTuple):
    """Output histories, one row per output step (nt of them), or zero rows: peaks only.

    The shapes are those of the unidirectional kernel; the plan kernel's
    (:class:`structures.dynamics.plan_newmark_records.PlanHistories`) put a leading direction axis
    (2: x, y) on every field but ``iterations``, ``levels`` and ``robust``, so that
    :meth:`direction` is a unidirectional record.
    """

    disp: np.ndarray
    """(nt, ndof) displacement relative to the ground [m]."""
    accel: np.ndarray
    """(nt, ndof) absolute acceleration [m/s^2]."""
    drift: np.ndarray
    """(nt, ndof - 1) story drift, DOF i minus DOF i-1 [m]."""
    drift_ratio: np.ndarray
    """(nt, ndof - 1) drift / story height [-]."""
    isolator_force: np.ndarray
    """(nt,) isolator layer force [kN]."""
    base_shear: np.ndarray
    """(nt,) shear of story 1, spring and dashpot [kN]."""
    energy: np.ndarray
    """(5, nt) energy terms [kN m], one row per term of :data:`ENERGY_TERMS`."""
    iterations: np.ndarray
    """(nt,) int64 Newton iterations per output step (summed over its substeps)."""
    levels: np.ndarray
    """(nt,) int64 subdivision level of the output step (0: one step, l: 2^l substeps)."""
    robust: np.ndarray
    """(nt,) bool: the robust local solve acted in the output step (a deviation from OpenSees)."""

    @staticmethod
    def allocate(nt: int, ndof: int, directions: tuple[int, ...] = ()) -> Histories:
        """Uninitialised histories for ``nt`` output steps (``nt = 0``: none), with the leading
        axes ``directions`` (``(2,)`` in plan) on the per-direction fields."""
        def e(*shape):
            return np.empty(directions + shape)

        return Histories(e(nt, ndof), e(nt, ndof), e(nt, ndof - 1), e(nt, ndof - 1), e(nt), e(nt),
                         e(N_ENERGY, nt), np.zeros(nt, dtype=np.int64), np.zeros(nt, dtype=np.int64),
                         np.zeros(nt, dtype=np.bool_))

    def direction(self, d: int) -> Histories:
        """The unidirectional histories of direction ``d`` of plan histories (views)."""
        return Histories(*(x[d] for x in self[:7]), self.iterations, self.levels, self.robust)


class Summary(NamedTuple):
    """What one analysis returns (peaks are absolute values over the output steps)."""

    status: int
    """0 converged; a law status < 0; -3 non-finite force; -4 Newton did not converge."""
    failed_step: int
    """Index of the output step that failed, or -1."""
    iso_disp_peak: float
    """Peak isolator displacement [m] (for a failed run: the largest before it failed)."""
    iso_disp_residual: float
    """Isolator displacement at the end [m]."""
    base_shear_peak: float
    """Peak story-1 shear [kN]."""
    iso_work: float
    """Work done on the isolator layer at the end [kN m]."""
    energy_error: float
    """max |energy imbalance| / max |input energy| [-]."""
    subdivided_steps: int
    """Number of output steps that needed substeps."""
    robust_steps: int
    """Number of output steps where the robust local solve acted."""
    drift_peak: np.ndarray
    """(ndof - 1,) peak drift ratio per story [-]."""
    accel_peak: np.ndarray
    """(ndof - 1,) peak absolute floor acceleration [m/s^2]."""


def batch_record(summary: type, name: str, per_run) -> type:
    """The record of a batch's results for the summary record ``summary``: its fields, each an
    array with one entry (or row) per run.  ``allocate(runs, stories)`` gives zeroed results,
    ``per_run(stories)`` mapping a field to the shape of one run's value (default scalar); int64
    for ``status`` and the ``*_steps`` counts.  The class lives in ``summary``'s module."""
    cls = NamedTuple(name, [(f, np.ndarray) for f in summary._fields])
    cls.__module__ = summary.__module__
    cls.__doc__ = f"Per-run results of a batch, one entry (or row) per run: :class:`{summary.__name__}`."

    def allocate(runs: int, stories: int) -> cls:
        """Zeroed results for ``runs`` analyses of a building with ``stories`` stories."""
        shapes = per_run(stories)
        return cls(*(np.zeros((runs, *shapes.get(f, ())),
                              dtype=np.int64 if f == "status" or f.endswith("_steps") else float)
                     for f in summary._fields))

    cls.allocate = staticmethod(allocate)
    return cls


Batch = batch_record(Summary, "Batch", lambda stories: {"drift_peak": (stories,), "accel_peak": (stories,)})
