"""Effect ``degradation``: strength and stiffness fade with cumulative work and travel (inner, scaling).

A damage index that mixes the cumulative work of the base force and the cumulative travel of the
bearing fades strength and stiffness together::

    g = 1 / (1 + D),        D = deg_rate E_max + deg_travel T

``E`` is the cumulative work of the base force, ``E = int f_b du`` [kN m], ``E_max`` its largest
value so far, and ``T = int |du|`` [m] the cumulative travel; both are lagged one step, so the
tangent stays ``g k_b``.  Park & Ang (1985, "Mechanistic seismic damage model for reinforced
concrete", J. Struct. Eng. 111(4)) combine a deformation term and a dissipated-energy term in
one damage index; the deformation term here is cumulative (Banon & Veneziano 1982's normalised
cumulative rotation, the low-cycle-fatigue measure of a joint or elastomer that wears with every
excursion whatever its force), so small cycles fade the bearing more than their work alone
would.  Energy-based damage of elastomers is the ``deg_travel = 0`` case (the default: the
one-parameter kernel bit for bit).  Neutral: ``deg_rate = deg_travel = 0``.

State (5): ``[u, f_b, E, E_max, T]`` of the last call.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 / (1 + deg_rate E_max + deg_travel T) (contract in :mod:`rrfrei.laws.effects`)."""
    up = sc[so]
    fp = sc[so + 1]
    e_t = sc[so + 2] + 0.5 * (fp + fb) * (u - up)
    e_max = sc[so + 3]
    trav = sc[so + 4]
    st[so] = u
    st[so + 1] = fb
    st[so + 2] = e_t
    st[so + 3] = max(e_max, e_t)
    st[so + 4] = trav + abs(u - up)
    ct = p[po + 1]
    if ct == 0.0:
        gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0))
    else:
        gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0) + ct * trav)
    dg = dg * gi
    g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against cumulative dissipated energy (the force fades)."""
    return partial(ctx.resid * force_sign(ctx), ctx.energy, [np.abs(ctx.disp)])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"deg_rate": 0.1 / s.energy, "deg_travel": 0.0},
               {"deg_rate": 0.5 / s.energy, "deg_travel": 0.0},
               {"deg_rate": 0.0, "deg_travel": 0.02 / s.disp}],
    lambda s: {"deg_rate": 1.0 / s.energy, "deg_travel": 0.05 / s.disp},
    lambda s: {"deg_rate": (0.0, 100.0 / s.energy), "deg_travel": (0.0, 5.0 / s.disp)}, order=1)


EFFECT = register_effect(EffectSpec(
    "degradation",
    (ParamSpec("deg_rate", "1/kN*m", 0.0, 1e9,
               "fade rate per unit cumulative work: g = 1 / (1 + deg_rate E)",
               Prior("halfnormal", 1.0)),
     ParamSpec("deg_travel", "1/m", 0.0, 1e9,
               "fade rate per unit cumulative travel: D = deg_rate E + deg_travel T",
               Prior("halfnormal", 1.0), default=0.0)),
    5, "strength and stiffness fade with cumulative dissipated energy and travel", (0.0, 0.0), apply=apply,
    hints=HINTS))
