"""Shear buildings on isolators: models, time histories, energy balance, propagation.

Sub-packages, one idea each:

* :mod:`structures.building`: the frozen models (:class:`ShearBuilding`, :class:`Isolator`) with
  modal analysis and TOML loading, and the checks of a posterior against a building;
* :mod:`structures.dynamics`: time histories.  :mod:`structures.dynamics.newmark` is the Numba
  kernel template (Newmark + Newton over a chain condensed onto the isolator, instantiated per
  isolator law), :mod:`structures.dynamics.history` the public verbs :func:`time_history` /
  :func:`time_history_batch`; :mod:`structures.dynamics.plan_newmark` /
  :mod:`structures.dynamics.plan_history` the same in plan (two horizontal directions on a coupled
  isolator law, no torsion); both on the chain core :mod:`structures.dynamics.newmark_chain`;
  energy balance in :mod:`structures.dynamics.energy`;
* :mod:`structures.propagation`: posterior propagation through records (inputs, executors, the
  Parquet store, response sets and plots, fragility, stripes, design answers for pairs);
* :mod:`structures.shake_table`: shake-table runs (reading, checks, the isolation system),
  superstructure identification, and the building as a gap-engine model.

Layer: on top of ``ground_motions`` and the ``rrfrei`` core (laws, simulation, calibration); below
``rrfrei.app``.  Nothing here imports ``rubber`` or ``rrfrei.app`` (``tests/test_layers.py``).

>>> import structures
>>> structures.available_buildings()
('five_story', 'three_story')
"""

import rrfrei._jit_cache  # noqa: F401  (first: the kernel cache locator, before any @njit)
from structures.building.shear_building import Isolator, ShearBuilding, available_buildings, load_building
from structures.building.specimen import SpecimenWarning, specimen_checks  # noqa: F401  (posterior vs building)
from structures.dynamics.history import ConvergenceError, Response, time_history, time_history_batch
from structures.dynamics.plan_history import (  # noqa: F401  (plan building, issue 14)
    PlanResponse,
    plan_time_history,
    plan_time_history_batch,
)
from structures.propagation.propagate import ResponseSet, SpectrumScaling, propagate  # noqa: F401  (propagation API)
from structures.shake_table import (  # noqa: F401  (shake-table runs)
    ShakeTableRun,
    available_runs,
    isolation_metrics,
    isolation_test,
    load_run,
    read_run,
)
from structures.shake_table.identify import SuperstructureIdentification, identify_superstructure  # noqa: F401
from structures.shake_table.predict import RunPrediction, predict_run  # noqa: F401

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
