"""Effect ``rate``: a force that depends on velocity (inner, additive).

A viscous force ``f_a = c sgn(v) |v|^a`` (a = 1 linear viscous; a < 1 as in rubber and fluid
dampers, Constantinou & Symans 1993).  Dissipative for c >= 0.  Neutral: ``c = 0``.  No state.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add c sgn(v) |v|^a, tangent c a |v|^(a-1) / dt (contract in :mod:`rrfrei.laws.effects`)."""
    c = p[po]
    a = p[po + 1]
    av = abs(v)
    if av > 0.0:
        fa += c * (av**a) * (1.0 if v > 0.0 else -1.0)
        ka += c * a * av ** (a - 1.0) / dt
    elif a == 1.0:
        ka += c / dt
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r against velocity beyond the sign of velocity (needs real time)."""
    if not ctx.has_time or not np.any(ctx.vel):
        return float("nan")
    return partial(ctx.resid, ctx.vel, [np.sign(ctx.vel), ctx.disp])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"rate_c": 0.05 * s.force / s.vel}, {"rate_c": 0.2 * s.force / s.vel}],
    lambda s: {"rate_c": s.force / s.vel}, lambda s: {"rate_c": (0.0, 20 * s.force / s.vel)},
    needs_time=True, order=4)


EFFECT = register_effect(EffectSpec(
    "rate",
    (ParamSpec("rate_c", "kN*s/m", 0.0, 1e9, "viscous coefficient of c sgn(v)|v|^a",
               Prior("halfnormal", 1e3)),
     ParamSpec("rate_exp", "-", 0.1, 2.0, "velocity exponent a", Prior("uniform", 0.2, 1.5),
               default=1.0)),
    0, "a force that depends on velocity", (0.0, 1.0), apply=apply, hints=HINTS))
