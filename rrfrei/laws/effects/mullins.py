"""Effect ``mullins``: Mullins softening, softer reloading below the largest past |u| (inner, scaling).

Below the largest |u| reached so far, ``u_max``, the response is softer by a damage that grows
with the deficit of the deformation measure ``r^c`` below its past maximum (``r = |u| / u_max``)::

    g = 1 - m (1 - r^c)      for |u| < u_max, else 1
    dg/du = m c r^c / |u| sgn(u)

virgin loading beyond ``u_max`` is unsoftened (Mullins 1969).  ``c = 1``: linear in the
displacement deficit (the simplest pseudo-elasticity); ``c = 2``: linear in the deficit of an
elastic strain energy ``W ~ u^2`` below ``W_max``, the argument of Ogden & Roxburgh's damage
function (1999, Proc. R. Soc. A 455; Dorfmann & Ogden 2004); ``c > 2`` recovers the virgin
curve only close to ``u_max``, ``c < 1`` softens mostly near ``u = 0``.  ``g`` lies in
``[1 - m, 1]`` and reaches 1 at ``u_max`` for every ``c``, so the force stays continuous.  At
``c = 1`` the kernel evaluates the linear form itself (bit for bit the former one-parameter
kernel).  Neutral: ``m = 0``.  The diagnosis fits ``0.25 <= c <= 2`` (its box): beyond the
strain-energy exponent the shape has no physical reading here, and the refitted kernel then
reproduced a validation generator form (``erf`` of the energy deficit) to better than its noise
(docs/gap/validation.md).

State (1): ``[u_max]`` [m].
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 - m (1 - (|u| / u_max)^c) below u_max (contract in :mod:`rrfrei.laws.effects`)."""
    um = sc[so]
    a = abs(u)
    st[so] = max(um, a)
    if um > 0.0 and a < um:
        m = p[po]
        c = p[po + 1]
        if c == 1.0:
            gi = 1.0 - m * (1.0 - a / um)
            d = m / um
        else:
            rc = (a / um) ** c
            gi = 1.0 - m * (1.0 - rc)
            d = m * c * rc / a if a > 0.0 else 0.0
        dgi = d if u > 0.0 else (-d if u < 0.0 else 0.0)
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) on first vs repeated cycles of an amplitude (the first is stiffer)."""
    return partial(ctx.resid * force_sign(ctx), ctx.first_cycle.astype(float), [np.abs(ctx.disp)])


HINTS = DiagnosisHints(_screen,
                       lambda s: [{"mullins": 0.1, "mullins_shape": 1.0},
                                  {"mullins": 0.3, "mullins_shape": 2.0}],
                       lambda s: {"mullins": 0.1, "mullins_shape": 1.0},
                       lambda s: {"mullins_shape": (0.25, 2.0)}, order=2)


EFFECT = register_effect(EffectSpec(
    "mullins",
    (ParamSpec("mullins", "-", 0.0, 0.95,
               "softening at zero displacement of reloading below the largest past |u|",
               Prior("uniform", 0.0, 0.9)),
     ParamSpec("mullins_shape", "-", 0.1, 20.0,
               "exponent c of the deformation measure r^c whose deficit softens (1: linear in |u|)",
               Prior("lognormal", 1.0, 1.0))),
    1, "Mullins softening: softer reloading below the previous maximum deformation (recovers beyond it)",
    (0.0, 1.0), apply=apply,
    hints=HINTS, memory=True))
