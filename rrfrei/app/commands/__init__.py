"""CLI commands, one module each (see :mod:`rrfrei.app.cli`).

:data:`HELPS` names the commands' modules in the order ``rrfrei --help`` lists them, with each
command's one-line help (the module's ``HELP``).  The CLI imports a command's module only when
that command runs, so ``rrfrei --help`` and each command start without importing the others'
dependencies (the demo, the building stack, Dask).  A module ``name`` is the command ``name``
with ``_`` typed as ``-`` (``gap_validate`` is ``rrfrei gap-validate``).
"""

HELPS = {
    "calibrate": "calibrate a law's parameters on a shear test (posterior, checks, figures)",
    "compare": "compare laws on one test by PSIS-LOO, WAIC and leave-one-cycle-out",
    "gap": "diagnose the sim-to-real gap of a calibrated law (which unmodelled effect)",
    "gap_validate": "validate the gap diagnosis on synthetic tests with withheld effects",
    "propagate": "run posterior draws of an isolator law through a building under ground motions",
    "shake_table": "predict a base-isolated building on shake-table runs and diagnose the gap",
    "demo": "run the whole pipeline on the bundled data and write an HTML report",
    "kernels": "list the generated kernel files of a law (the code a command compiles)",
}
"""Command module -> one-line help, in the order of ``rrfrei --help``."""
