"""rubber: uniaxial PRF (Yeoh + Bergstrom-Boyce) model of rubber-like solids for the SDRSI (MPa, s).

Layers: Numba kernels (``integrate``) -> frozen model dataclasses and ``simulate`` (``prf``) ->
protocols, test I/O, CMA-ES ``fit``, the cross-protocol study and material cards -> ``python -m rubber``.
The gap diagnosis (``rubber.gap``: ``RubberModel``, ``rank_effects``) is exported lazily, for
start-up speed only: it imports the ``rrfrei.gap`` engine and with it the calibration stack (arviz,
emcee, about a second), which ``python -m rubber fit`` does not need.

Layer: on the ``rrfrei`` core (errors, budgets, the gap engine), beside ``structures``, below
``rrfrei.app`` (``tests/test_layers.py``).
"""

import rrfrei._jit_cache  # noqa: F401  (first: the kernel cache locator, before any @njit)

from .fit import FitResult, fit, objective
from .io import Test, read_test
from .prf import (
    PARAM_NAMES,
    BBChain,
    NeoHookean,
    PRFModel,
    PRFParams,
    SimResult,
    Yeoh,
    equilibrium_stress,
    instantaneous_stress,
    simulate,
)
from .protocols import protocol1, protocol2
from .study import BOX, PRESETS, cases

__all__ = [
    "PARAM_NAMES", "BBChain", "NeoHookean", "PRFModel", "PRFParams", "SimResult", "Yeoh",
    "equilibrium_stress", "instantaneous_stress", "simulate", "protocol1", "protocol2",
    "BOX", "PRESETS", "cases", "Test", "read_test", "FitResult", "fit", "objective",
    "EFFECTS", "RubberModel", "RubberFit", "RubberGapReport", "augmented_stress", "rank_effects",
]
_GAP = ("EFFECTS", "RubberModel", "RubberFit", "RubberGapReport", "augmented_stress", "rank_effects")


def __getattr__(name: str):
    if name in _GAP:
        from . import gap  # deferred for start-up speed (module docstring); same layer, no cycle

        return getattr(gap, name)
    raise AttributeError(f"module 'rubber' has no attribute {name!r}")
