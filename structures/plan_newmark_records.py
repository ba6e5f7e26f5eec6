"""The named outputs of the plan-building Newmark kernel (:mod:`structures.plan_newmark`).

The inputs are the records of the unidirectional kernel (:mod:`structures.newmark_records`): one
:class:`~structures.newmark_records.Chain` per horizontal direction (x, y), one
:class:`~structures.newmark_records.Layer` for the coupled isolator layer and one
:class:`~structures.newmark_records.Solver`.  The outputs carry a leading axis of length 2 for
the direction (0: x, 1: y).  They live in a module of their own so that every per-law instance of
the template shares one class for each (see :mod:`rrfrei.laws.specialise`).  Units: kN, m, s,
tonnes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from structures.newmark_records import N_ENERGY


class PlanHistories(NamedTuple):
    """Output histories, one entry per output step (nt of them), or nt = 0: peaks only."""

    disp: np.ndarray
    """(2, nt, ndof) displacement relative to the ground [m], per direction."""
    accel: np.ndarray
    """(2, nt, ndof) absolute acceleration [m/s^2]."""
    drift: np.ndarray
    """(2, nt, ndof - 1) story drift, DOF i minus DOF i-1 [m]."""
    drift_ratio: np.ndarray
    """(2, nt, ndof - 1) drift / story height [-]."""
    isolator_force: np.ndarray
    """(2, nt) isolator layer force components [kN]."""
    base_shear: np.ndarray
    """(2, nt) shear of story 1, spring and dashpot [kN]."""
    energy: np.ndarray
    """(2, 5, nt) energy terms per direction [kN m] (rows of :data:`structures.energy.TERMS`)."""
    iterations: np.ndarray
    """(nt,) int64 Newton iterations per output step (summed over its substeps)."""
    levels: np.ndarray
    """(nt,) int64 subdivision level of the output step (0: one step, l: 2^l substeps)."""

    @staticmethod
    def allocate(nt: int, ndof: int) -> PlanHistories:
        """Uninitialised histories for ``nt`` output steps (``nt = 0``: none)."""
        e = np.empty
        return PlanHistories(e((2, nt, ndof)), e((2, nt, ndof)), e((2, nt, ndof - 1)),
                             e((2, nt, ndof - 1)), e((2, nt)), e((2, nt)), e((2, N_ENERGY, nt)),
                             np.zeros(nt, dtype=np.int64), np.zeros(nt, dtype=np.int64))


class PlanSummary(NamedTuple):
    """What one analysis returns (peaks are absolute values over the output steps)."""

    status: int
    """0 converged; a law status < 0; -3 non-finite force; -4 Newton did not converge."""
    failed_step: int
    """Index of the output step that failed, or -1."""
    iso_plan_disp_peak: float
    """Peak isolator displacement in plan, max_t sqrt(u_x^2 + u_y^2) [m] (for a failed run: the
    largest before it failed)."""
    iso_disp_peak: np.ndarray
    """(2,) peak |isolator displacement| per direction [m]."""
    iso_plan_disp_residual: float
    """Isolator displacement in plan at the end [m]."""
    base_shear_peak: np.ndarray
    """(2,) peak |story-1 shear| per direction [kN]."""
    iso_work: float
    """Work done on the isolator layer at the end, int F . du in plan [kN m]."""
    energy_error: float
    """max |energy imbalance| / max |input energy|, both directions together [-]."""
    subdivided_steps: int
    """Number of output steps that needed substeps."""
    drift_peak: np.ndarray
    """(2, ndof - 1) peak |drift ratio| per direction and story [-]."""
    accel_peak: np.ndarray
    """(2, ndof - 1) peak |absolute floor acceleration| per direction and floor [m/s^2]."""


class PlanBatch(NamedTuple):
    """Per-run results of a batch: one entry (or row) per parameter set, fields of
    :class:`PlanSummary`."""

    status: np.ndarray
    iso_plan_disp_peak: np.ndarray
    iso_disp_peak: np.ndarray
    """(runs, 2)."""
    iso_plan_disp_residual: np.ndarray
    base_shear_peak: np.ndarray
    """(runs, 2)."""
    iso_work: np.ndarray
    energy_error: np.ndarray
    subdivided_steps: np.ndarray
    drift_peak: np.ndarray
    """(runs, 2, stories)."""
    accel_peak: np.ndarray
    """(runs, 2, stories)."""

    @staticmethod
    def allocate(runs: int, stories: int) -> PlanBatch:
        """Zeroed results for ``runs`` analyses of a building with ``stories`` stories."""
        z = np.zeros
        i8 = np.int64
        return PlanBatch(z(runs, dtype=i8), z(runs), z((runs, 2)), z(runs), z((runs, 2)), z(runs),
                         z(runs), z(runs, dtype=i8), z((runs, 2, stories)), z((runs, 2, stories)))
