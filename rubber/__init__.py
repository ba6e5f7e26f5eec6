"""rubber: uniaxial PRF (Yeoh + Bergstrom-Boyce) model of rubber-like solids for the SDRSI (MPa, s).

Layers: Numba kernels (``integrate``) -> frozen model dataclasses and ``simulate`` (``prf``) ->
protocols, test I/O, CMA-ES ``fit``, the cross-protocol study and material cards -> ``python -m rubber``.
"""

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
]
