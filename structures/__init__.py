"""Shear buildings on isolators: models, time histories, energy balance, propagation.

Layers: :mod:`structures.newmark` is the Numba kernel template (Newmark + Newton over a chain
condensed onto the isolator, instantiated per isolator law), :mod:`structures.newmark_records`
its named inputs and outputs, :mod:`structures.history` the public verbs :func:`time_history` /
:func:`time_history_batch`; :mod:`structures.plan_newmark` / :mod:`structures.plan_history` the
same in plan (two horizontal directions on a coupled isolator law, no torsion:
:func:`plan_time_history`, :func:`plan_time_history_batch`, :class:`PlanResponse`, energy in
:mod:`structures.plan_energy`); :mod:`structures.building` the frozen models
(:class:`ShearBuilding`, :class:`Isolator`) with modal analysis and TOML loading;
:mod:`structures.energy` the energy balance; :mod:`structures.propagate` posterior propagation
(its inputs, executors, store, response set and plots in modules of those names).

Layer: on top of ``ground_motions`` and the ``rrfrei`` core (laws, simulation, calibration); below
``rrfrei.app``.  Nothing here imports ``rubber`` or ``rrfrei.app`` (``tests/test_layers.py``).

>>> import structures
>>> structures.available_buildings()
('five_story', 'three_story')
"""

import rrfrei._jit_cache  # noqa: F401  (first: the kernel cache locator, before any @njit)
from structures.building import Isolator, ShearBuilding, available_buildings, load_building
from structures.history import ConvergenceError, Response, time_history, time_history_batch
from structures.identify import SuperstructureIdentification, identify_superstructure  # noqa: F401
from structures.plan_history import (  # noqa: F401  (plan building, issue 14)
    PlanResponse,
    plan_time_history,
    plan_time_history_batch,
)
from structures.predict import RunPrediction, predict_run  # noqa: F401
from structures.propagate import ResponseSet, SpectrumScaling, propagate  # noqa: F401  (propagation API)
from structures.shake_table import (  # noqa: F401  (shake-table runs)
    ShakeTableRun,
    available_runs,
    isolation_metrics,
    isolation_test,
    load_run,
    read_run,
)
from structures.specimen import SpecimenWarning, specimen_checks  # noqa: F401  (posterior vs building)

__all__ = [
    "ConvergenceError",
    "Isolator",
    "Response",
    "PlanResponse",
    "ShearBuilding",
    "available_buildings",
    "load_building",
    "plan_time_history",
    "plan_time_history_batch",
    "time_history",
    "time_history_batch",
]
