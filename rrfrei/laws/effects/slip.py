"""Effect ``slip``: sliding of an unbonded bearing on its supports (series slider).

A rigid-plastic slider of capacity ``F_s = mu N`` [kN] in series with the (augmented) law; while
``|F| < F_s`` it sticks, else ``u_s`` moves so that ``|F| = F_s`` (solved by safeguarded Newton on
the inner law, then bisection: :mod:`rrfrei.laws.effects._augment`).  Dissipative.  Neutral:
``slip_force`` at its upper bound (never reached).

State (1): ``[u_s]`` the slider displacement [m].
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior

SLIP_NEVER = 1e12
"""``slip_force`` [kN] at which the slider never slides (its neutral value and upper bound)."""


@njit(cache=True, inline="always")
def capacity(p, po):
    """The friction capacity mu N [kN] (contract in :mod:`rrfrei.laws.effects`)."""
    return p[po]


def _screen(ctx) -> float:
    """r sgn(F) against the excess of |F| over its 80th percentile (a capped force)."""
    a = np.abs(ctx.force_pred)
    return partial(ctx.resid * force_sign(ctx), np.maximum(a - np.quantile(a, 0.8), 0.0), [a])


HINTS = DiagnosisHints(
    _screen, lambda s: [{"slip_force": 0.9 * s.force}, {"slip_force": 0.75 * s.force}],
    lambda s: {"slip_force": s.force}, lambda s: {"slip_force": (0.2 * s.force, 2.0 * s.force)}, order=6)


EFFECT = register_effect(EffectSpec(
    "slip",
    (ParamSpec("slip_force", "kN", 0.0, SLIP_NEVER, "friction capacity of the supports mu N",
               Prior("loguniform", 1e-2, 1e3)),),
    1, "sliding of an unbonded bearing once shear exceeds the friction capacity",
    (SLIP_NEVER,), capacity=capacity, hints=HINTS))
