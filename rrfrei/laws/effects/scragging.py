"""Effect ``scragging``: permanent softening with the largest |u| ever reached (inner, scaling).

A virgin elastomer softens for good once it has been deformed (scragging, Thompson et al. 2000;
the ASCE 7-22 17.2.8.4 property modification for scragging)::

    g = 1 - s (1 - exp(-u_max / u_c))

with ``u_max`` the largest |u| so far including the current one.  Unlike ``mullins`` (softer only
below u_max, recovering on virgin loading beyond it) and ``degradation`` (fading on with work at
a constant amplitude), the softening applies to all later loading, including virgin loading, and
only grows with a new peak.  Its state is what a bearing carries from one test to the next
(:attr:`rrfrei.io.ShearTest.preceding`).  Neutral: ``scrag = 0``.

State (1): ``[u_max]`` [m].
"""

import math

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 - s (1 - exp(-u_max / u_c)) (contract in :mod:`rrfrei.laws.effects`)."""
    a = abs(u)
    um = max(sc[so], a)
    st[so] = um
    s = p[po]
    if s != 0.0:
        uc = p[po + 1]
        e = math.exp(-um / uc)
        gi = 1.0 - s * (1.0 - e)
        dgi = 0.0
        if a > sc[so]:  # on a new peak u_max moves with u
            dgi = -s * e / uc * (1.0 if u > 0.0 else -1.0)
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against the running peak |u| beyond |u| (the force fades with it; unsigned, as
    the baseline's own fit may absorb part of the fade either way)."""
    a = np.abs(ctx.disp)
    return partial(ctx.resid * force_sign(ctx), np.maximum.accumulate(a), [a])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"scrag": 0.2, "scrag_disp": 0.5 * s.disp}, {"scrag": 0.4, "scrag_disp": 0.2 * s.disp}],
    lambda s: {"scrag": 0.2, "scrag_disp": s.disp},
    lambda s: {"scrag_disp": (0.02 * s.disp, 5.0 * s.disp)}, order=9)


EFFECT = register_effect(EffectSpec(
    "scragging",
    (ParamSpec("scrag", "-", 0.0, 0.95, "softening reached after a very large displacement",
               Prior("uniform", 0.0, 0.9)),
     ParamSpec("scrag_disp", "m", 1e-6, 1e3, "displacement scale of the softening u_c",
               Prior("halfnormal", 1.0))),
    1, "scragging: permanent softening with the largest displacement ever reached", (0.0, 1.0),
    apply=apply, hints=HINTS))
