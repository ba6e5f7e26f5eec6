"""The named outputs of the plan-building Newmark kernel (:mod:`structures.dynamics.plan_newmark`).

The inputs are the records of the unidirectional kernel (:mod:`structures.dynamics.newmark_records`): one
:class:`~structures.dynamics.newmark_records.Chain` per horizontal direction (x, y), one
:class:`~structures.dynamics.newmark_records.Layer` for the coupled isolator layer and one
:class:`~structures.dynamics.newmark_records.Solver`.  The histories are the unidirectional
:class:`~structures.dynamics.newmark_records.Histories` with a leading axis of length 2 for the direction
(0: x, 1: y).  They live in a module of their own so that every per-law instance of the template
shares one class for each (see :mod:`rrfrei.laws.specialise`).  Units: kN, m, s, tonnes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from structures.dynamics.newmark_records import Histories, batch_record


class PlanHistories(Histories):
    """:class:`~structures.dynamics.newmark_records.Histories` per direction: ``disp`` (2, nt, ndof),
    ``energy`` (2, 5, nt), ...; ``iterations``, ``levels`` and ``robust`` (nt,) are shared
    (``robust`` stays False: the plan laws have no robust local solve)."""

    __slots__ = ()

    @staticmethod
    def allocate(nt: int, ndof: int) -> PlanHistories:
        """Uninitialised histories for ``nt`` output steps (``nt = 0``: none)."""
        return PlanHistories(*Histories.allocate(nt, ndof, (2,)))


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


PlanBatch = batch_record(PlanSummary, "PlanBatch", lambda stories: {
    "iso_disp_peak": (2,), "base_shear_peak": (2,), "drift_peak": (2, stories), "accel_peak": (2, stories)})
