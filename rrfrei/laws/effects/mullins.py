"""Effect ``mullins``: Mullins softening, softer reloading below the largest past |u| (inner, scaling).

Below the largest |u| reached so far, ``u_max``, the response is softer,
``g = 1 - m (1 - |u| / u_max)``; virgin loading beyond ``u_max`` is unsoftened (Mullins 1969;
Dorfmann & Ogden 2004 pseudo-elasticity in its simplest form).  Neutral: ``m = 0``.

State (1): ``[u_max]`` [m].
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 - m (1 - |u| / u_max) below u_max (contract in :mod:`rrfrei.laws.effects`)."""
    um = sc[so]
    a = abs(u)
    st[so] = max(um, a)
    if um > 0.0 and a < um:
        m = p[po]
        gi = 1.0 - m * (1.0 - a / um)
        dgi = m / um if u > 0.0 else (-m / um if u < 0.0 else 0.0)
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) on first vs repeated cycles of an amplitude (the first is stiffer)."""
    return partial(ctx.resid * force_sign(ctx), ctx.first_cycle.astype(float), [np.abs(ctx.disp)])


HINTS = DiagnosisHints(_screen, lambda s: [{"mullins": 0.1}, {"mullins": 0.3}],
                       lambda s: {"mullins": 0.1}, order=2)


EFFECT = register_effect(EffectSpec(
    "mullins",
    (ParamSpec("mullins", "-", 0.0, 0.95,
               "softening at zero displacement of reloading below the largest past |u|",
               Prior("uniform", 0.0, 0.9)),),
    1, "Mullins softening: softer reloading below the previous maximum deformation (recovers beyond it)",
    (0.0,), apply=apply,
    hints=HINTS))
