"""Effect ``rollover``: amplitude-dependent tangent at large displacement (inner, additive).

``f_a = k_r sgn(u) (|u| - u_r)_+`` with ``k_r <= 0``: the rollover softening of unbonded FREIs
(Toopchi-Nezhad et al. 2008), a kinked loss of tangent stiffness beyond the onset.  Stiffening at
large displacement is the separate effect ``stiffening`` (smooth onset): the two names keep the
two physical signs apart, so a diagnosis that names one says which way the bearing departs.
Elastic (path independent).  Neutral: ``k_r = 0``.  No state.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add k_r sgn(u) (|u| - u_r)_+ (contract in :mod:`rrfrei.laws.effects`)."""
    ex = abs(u) - p[po + 1]
    if ex > 0.0:
        fa += p[po] * ex * (1.0 if u > 0.0 else -1.0)
        ka += p[po]
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(u) against |u|^2 (the shape changes with |u|)."""
    return partial(ctx.resid * np.sign(ctx.disp), ctx.disp**2, [np.abs(ctx.disp)])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"roll_k": -0.3 * s.force / s.disp, "roll_onset": 0.5 * s.disp},
               {"roll_k": -0.3 * s.force / s.disp, "roll_onset": 0.25 * s.disp}],
    lambda s: {"roll_k": s.force / s.disp, "roll_onset": s.disp},
    lambda s: {"roll_k": (-10 * s.force / s.disp, 0.0), "roll_onset": (0.0, s.disp)},
    order=3)


EFFECT = register_effect(EffectSpec(
    "rollover",
    (ParamSpec("roll_k", "kN/m", -1e9, 0.0,
               "tangent stiffness lost beyond the onset (<= 0: rollover softening)",
               Prior("normal", 0.0, 1.0)),
     ParamSpec("roll_onset", "m", 0.0, 1e3, "displacement at which the tangent changes",
               Prior("halfnormal", 1.0))),
    0, "amplitude-dependent tangent stiffness at large displacement", (0.0, 0.0), apply=apply, hints=HINTS))
