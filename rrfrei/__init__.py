"""rrfrei: performance-based seismic analysis of buildings on low-cost isolators.

This package is the core layer: isolator laws (``rrfrei.laws``), their simulation, test I/O,
energy, protocols, Bayesian calibration and the sim-to-real gap engine (``rrfrei.gap``).  The
application on top of everything (CLI, commands, demo, HTML report) is ``rrfrei.app``; the
layer order, bottom to top, is ``rrfrei._jit_cache`` -> ``ground_motions`` -> rrfrei core ->
``structures`` | ``rubber`` -> ``rrfrei.app`` (see :mod:`rrfrei.app`, checked by
``tests/test_layers.py``).  Within the core: workflows (``calibrate``, ``compare``,
``diagnose_gap``) -> models (frozen dataclasses: ``LawSpec``, ``ShearTest``, ...) -> Numba
kernels (``rrfrei.laws``; kernels that call a law
are instantiated per law by ``rrfrei.laws.specialise``).

Units: kN, m, s, tonnes throughout.

The public names below are imported lazily (the table ``_LAZY``, all of them core modules), so
``import rrfrei`` stays cheap: every package imports ``rrfrei._jit_cache`` first, which runs this
file, and must not pay for the calibration stack (arviz, emcee) it may not use.  Importing only
defines things: ``rrfrei._jit_cache`` registers the kernel cache locator with Numba, and writes
nothing and sets no environment variable (the cache folder is made at the first compile).
"""

from __future__ import annotations

import importlib

from rrfrei import _jit_cache  # noqa: F401  (first: the kernel cache locator, before any @njit)

__version__ = "0.1.0"

_LAZY = {
    "laws": ("rrfrei.laws", None),
    "simulate_force": ("rrfrei.simulate", "simulate_force"),
    "LocalSolverDeviation": ("rrfrei.simulate", "LocalSolverDeviation"),
    "protocols": ("rrfrei.protocols", None),
    "energy": ("rrfrei.energy", None),
    "read_test": ("rrfrei.io", "read_test"),
    "ShearTest": ("rrfrei.io", "ShearTest"),
    "load_test": ("rrfrei.io", "load_test"),
    "calibrate": ("rrfrei.calibration", "calibrate"),
    "Calibration": ("rrfrei.calibration", "Calibration"),
    "compare": ("rrfrei.calibration", "compare"),
    "diagnose_gap": ("rrfrei.gap", "diagnose_gap"),
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        module, attr = _LAZY[name]
        mod = importlib.import_module(module)
        value = mod if attr is None else getattr(mod, attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rrfrei' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
