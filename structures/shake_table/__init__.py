"""Shake-table runs of base-isolated buildings: reading, consistency checks, the isolation system.

A run (:class:`ShakeTableRun`) holds, at a constant sampling step,

* the table acceleration ``table_accel`` [m/s^2] (and its displacement ``table_disp`` [m] if
  measured),
* per level, bottom-up (column 0 = the base slab just above the isolators, last = the roof), the
  absolute acceleration ``accel`` [m/s^2] and the displacement relative to the table ``disp``
  [m]; ``disp[:, 0]`` is therefore the isolator displacement,
* the level masses ``masses`` [t] in the same order.

Two layouts are read by :func:`read_run`:

1. **Folder layout** (the BNCS data of Orozco et al. 2025): files ``a1 ... aN`` (absolute
   accelerations [m/s^2], ``a1`` the roof, ``aN`` the base slab), ``d1 ... dN`` (displacements
   relative to the table [m]), ``u`` (table acceleration [m/s^2]) and optionally ``du`` (table
   displacement [m]), whitespace-separated values (one per line, or all on one line as in some
   BNCS ``d`` files), ``.txt`` or ``.txt.gz``; the sampling rate and the
   level masses come from a TOML sidecar (``run.toml`` inside the folder or ``<folder>.toml``
   next to it) or the arguments ``rate_hz=`` and ``masses=`` / ``weights=``; ``a1=`` (sidecar
   ``[levels] a1``) says whether ``a1`` is the roof (default) or the base slab.
2. **CSV layout**: ``time_s``, ``table_accel_<unit>``, optional ``table_disp_<unit>``, and per
   level ``<LEVEL>_accel_abs_<unit>`` and ``<LEVEL>_disp_rel_<unit>`` (accelerations ``mps2``,
   ``cmps2``, ``g``; displacements ``m``, ``cm``, ``mm``), plain or gzip-compressed, with a TOML
   sidecar (``<stem>.toml`` next to it, else ``shake_table.toml`` in the same folder)::

       [levels]
       names = ["base", "floor2", "floor3", "floor4", "floor5", "roof"]   # bottom-up
       weights = [2275.1, 674.0, 703.0, 1036.3, 1078.1, 593.3]           # or masses = [...]
       weight_unit = "kN"                                                 # or mass_unit = "t"
       g = 9.81                                                           # to convert weights
       [units]                   # optional: units of columns written without a suffix
       accel = "mps2"
       disp = "m"

Every list of levels (names, masses, weights) runs base slab first unless ``level_order =
"roof-first"`` (``[levels] level_order`` or the argument ``level_order=``).  **The sidecar
format, its keys and units, an example for a raw folder and what the reader checks:
``docs/shake_table_data.md``** (command line: ``rrfrei shake-table --rate-hz --weights
--weight-unit --masses --level-order --a1``).

Consistency (:func:`check_consistency`, run by :func:`read_run`): for every level the absolute
acceleration must equal the second derivative of the relative displacement plus the table
acceleration, a_i = d''_i + a_g, and the table displacement must satisfy du'' = a_g; both sides
are low-passed identically (zero-phase Butterworth, 5 Hz by default) since double differentiation
amplifies noise.  A failing check gives a :class:`ConsistencyWarning` and is kept in
``run.consistency``; malformed input (missing file or column, bad value, unknown unit) is a
``ValueError`` naming the file, column and value.  A missing rate or masses, and channels whose
failure is that of a wrong sampling rate (one common scale (f/f')^2 between d'' and the
accelerations), raise :class:`MetadataError`.  :func:`check_level_order` warns
(:class:`LevelOrderWarning`) when the levels look upside down or the masses reversed.

The isolation system (:func:`isolation_test`): with every level above the isolators in the free
body, horizontal equilibrium gives the force the isolators apply to the building

    F_iso(t) = -sum_i m_i a_i(t)      [kN = t m/s^2]

(a_i absolute), exact for any superstructure (the story forces are internal), to be plotted
against the isolator displacement d_0 = ``disp[:, 0]``.

Modules: :mod:`.run` (:class:`ShakeTableRun`), :mod:`.io` (reading, writing, the bundled runs),
:mod:`.checks` (consistency and level order; the report in :mod:`.consistency`),
:mod:`.filters` (low-pass and derivatives), :mod:`.isolation` (the isolation system).  Every
public name of these data modules is importable from this package; the identification, the
building as a gap model and the ``rrfrei shake-table`` pipeline are in their own modules
(:mod:`.identify`, :mod:`.building_model`, :mod:`.gap`).
"""

from structures.shake_table.checks import (  # noqa: F401  (importable from here, as before the split)
    MASS_ORDER_GAIN,
    UPSIDE_DOWN_RATIO,
    ConsistencyWarning,
    LevelOrderWarning,
    check_consistency,
    check_level_order,
    story_fit_r2,
)
from structures.shake_table.consistency import ConsistencyReport  # noqa: F401
from structures.shake_table.filters import derivative, lowpass, second_derivative  # noqa: F401
from structures.shake_table.io import (  # noqa: F401  (importable from here, as before the split)
    A1_LEVELS,
    ACCEL_UNITS,
    BNCS_WEIGHTS_KN,
    DISP_UNITS,
    LEVEL_ORDERS,
    MASS_UNITS,
    WEIGHT_UNITS,
    G,
    MetadataError,
    available_runs,
    load_run,
    open_run,
    read_run,
    write_run,
)
from structures.shake_table.isolation import isolation_metrics, isolation_test
from structures.shake_table.run import ShakeTableRun

__all__ = [
    "BNCS_WEIGHTS_KN",
    "ConsistencyReport",
    "ConsistencyWarning",
    "LevelOrderWarning",
    "MetadataError",
    "ShakeTableRun",
    "available_runs",
    "check_consistency",
    "check_level_order",
    "isolation_metrics",
    "isolation_test",
    "load_run",
    "open_run",
    "read_run",
    "write_run",
]
