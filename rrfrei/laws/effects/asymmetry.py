"""Effect ``asymmetry``: different response in the + and - directions (inner, scaling).

``g = 1 + a sgn(f_b)``: the response in the + direction is ``(1 + a) / (1 - a)`` times the one
in the - direction (e.g. an eccentric vertical load or a rotated specimen).  Neutral: ``a = 0``.
No state.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 + a sgn(f_b) (contract in :mod:`rrfrei.laws.effects`)."""
    s = 1.0 if fb > 0.0 else (-1.0 if fb < 0.0 else 0.0)
    gi = 1.0 + p[po] * s
    dg = dg * gi
    g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r against |F| (a scaling that is even in the force, not odd)."""
    return partial(ctx.resid, np.abs(ctx.force_pred), [ctx.force_pred])


HINTS = DiagnosisHints(_screen, lambda s: [{"asym": 0.05}, {"asym": -0.05}], lambda s: {"asym": 0.1},
                       order=5)


EFFECT = register_effect(EffectSpec(
    "asymmetry",
    (ParamSpec("asym", "-", -0.9, 0.9, "relative excess of the + over the - response",
               Prior("uniform", -0.5, 0.5)),),
    0, "different response in the + and - directions", (0.0,), apply=apply, hints=HINTS))
