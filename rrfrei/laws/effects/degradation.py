"""Effect ``degradation``: strength and stiffness fade with cumulative work (inner, scaling).

``g = 1 / (1 + deg_rate E)`` with ``E`` the largest cumulative work of the base force so far,
``E = max_t int f_b du`` [kN m] (trapezoid, lagged one step so the tangent stays ``g k_b``).
Strength and stiffness fade together, as in energy-based damage of elastomers (Park & Ang 1985
use dissipated energy as the damage index).  Neutral: ``deg_rate = 0``.

State (4): ``[u, f_b, E, E_max]`` of the last call.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 / (1 + deg_rate E_max) (contract in :mod:`rrfrei.laws.effects`)."""
    up = sc[so]
    fp = sc[so + 1]
    e_t = sc[so + 2] + 0.5 * (fp + fb) * (u - up)
    e_max = sc[so + 3]
    st[so] = u
    st[so + 1] = fb
    st[so + 2] = e_t
    st[so + 3] = max(e_max, e_t)
    gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0))
    dg = dg * gi
    g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against cumulative dissipated energy (the force fades)."""
    return partial(ctx.resid * force_sign(ctx), ctx.energy, [np.abs(ctx.disp)])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"deg_rate": 0.1 / s.energy}, {"deg_rate": 0.5 / s.energy}],
    lambda s: {"deg_rate": 1.0 / s.energy}, lambda s: {"deg_rate": (0.0, 100.0 / s.energy)}, order=1)


EFFECT = register_effect(EffectSpec(
    "degradation",
    (ParamSpec("deg_rate", "1/kN*m", 0.0, 1e9,
               "fade rate per unit cumulative work: g = 1 / (1 + deg_rate E)",
               Prior("halfnormal", 1.0)),),
    4, "strength and stiffness fade with cumulative dissipated energy", (0.0,), apply=apply, hints=HINTS))
