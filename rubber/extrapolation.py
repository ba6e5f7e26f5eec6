"""Where a fitted PRF model stops being evidence: the fitted stretch range and the chains' locks.

A fit is evidence inside the stretch range of its tests.  Beyond it, and near a chain's locking
stretch, the prediction is the model's form only: the eight-chain spring stiffens towards its lock
(chain stretch lambda_ch -> sqrt(N)), which no fitted test reached.  :func:`check` flags a test
that goes beyond the fitted range, or within :data:`rrfrei.extrapolation.MARGIN` (10 %) of a
chain's locking stretch, with the project's one mechanism (:mod:`rrfrei.extrapolation`).

Locking stretch (uniaxial, incompressible)
------------------------------------------
The eight-chain stretch of a uniaxial stretch lambda is lambda_ch = sqrt((lambda^2 + 2/lambda) / 3)
(Arruda and Boyce 1993; ``docs/reference/prf_model.md`` section 2).  The chain locks at
lambda_ch = sqrt(N), so the applied stretch at the lock solves lambda^3 - 3 N lambda + 2 = 0; the
root above 1 is (trigonometric form of the cubic)::

    lambda_lock = 2 sqrt(N) cos(arccos(-N^(-3/2)) / 3)      (N >= 1; lambda_lock = 1 for N <= 1)

(about sqrt(3 N) for large N).  This is the instantaneous lock (viscous stretch lambda_v = 1): a
chain that has flowed locks later, so the check is conservative for the viscous chains.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rrfrei.extrapolation import MARGIN, Extrapolation, approaching, beyond

from .io import Test
from .prf import BBChain, PRFModel, PRFParams, _as_model

__all__ = ["check", "locking_stretch", "stretch_range"]


def locking_stretch(chain: BBChain | float) -> float:
    """Uniaxial stretch at which an eight-chain spring of ``N`` (a :class:`BBChain` or N) locks.

    lambda_lock = 2 sqrt(N) cos(arccos(-N^(-3/2)) / 3), the root above 1 of
    lambda^3 - 3 N lambda + 2 = 0 (module docstring); 1 when N <= 1 (locked at rest).
    """
    n = float(chain.N if isinstance(chain, BBChain) else chain)
    if not math.isfinite(n) or n <= 0:
        raise ValueError(f"N = {n!r}: expected a finite positive number")
    if n <= 1.0:
        return 1.0
    return 2.0 * math.sqrt(n) * math.cos(math.acos(-(n ** -1.5)) / 3.0)


def stretch_range(tests: Sequence[Test]) -> tuple[float, float]:
    """(min, max) stretch over every sample of ``tests``: the range a fit to them covers."""
    if not tests:
        raise ValueError("stretch_range: expected at least one test")
    return (float(min(np.min(t.stretch) for t in tests)), float(max(np.max(t.stretch) for t in tests)))


def _labels(model: PRFModel) -> list[str]:
    return [chr(ord("B") + i) for i in range(len(model.chains))]


def check(params: PRFParams | PRFModel, tests: Sequence[Test], *, sources: Sequence[str] | None = None,
          fitted_range: Sequence[float] | None = None, margin: float = MARGIN) -> list[Extrapolation]:
    """Extrapolation records of ``tests`` for the fitted ``params`` (empty: all inside the evidence).

    Parameters
    ----------
    params : the fitted model.
    tests : the tests predicted (or fitted).
    sources : a name per test for the messages (the file it came from; default the test names).
    fitted_range : (min, max) stretch of the fitted tests (``params.json``'s ``stretch_range``); None
        skips the range check (only the locking stretches are checked).
    margin : relative distance to a locking stretch that is flagged (default 10 %).

    Returns
    -------
    One record per test and bound: beyond the fitted range (either side), and near the locking
    stretch of each chain (B, C, ... in the model's order; the equilibrium Yeoh chain has no lock).
    """
    model = _as_model(params)
    names = list(sources) if sources is not None else [t.name for t in tests]
    if len(names) != len(tests):
        raise ValueError(f"sources: {len(names)} names for {len(tests)} tests")
    out: list[Extrapolation] = []
    locks = [(f"the locking stretch of chain {lab} (N = {c.N:.4g})", locking_stretch(c))
             for lab, c in zip(_labels(model), model.chains)]
    for name, test in zip(names, tests):
        if fitted_range is not None:
            out += beyond(name, "stretch", test.stretch, fitted_range, what="the fitted stretch range")
        for reason, lock in locks:
            near = approaching(name, "stretch", test.stretch, lock, margin=margin, reason=reason)
            if near is not None:
                out.append(near)
    return out
