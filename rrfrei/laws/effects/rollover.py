"""Effect ``rollover``: amplitude-dependent tangent at large displacement (inner, additive).

``f_a = k_r sgn(u) (|u| - u_r)_+`` (``k_r < 0``: rollover softening of unbonded FREIs;
``k_r > 0``: stiffening at full rollover or large strain; Toopchi-Nezhad et al. 2008).  Elastic
(path independent).  Neutral: ``k_r = 0``.  No state.
"""

from numba import njit

from rrfrei.laws.effects import EffectSpec, register_effect
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, g, dg, fa, ka):
    """Add k_r sgn(u) (|u| - u_r)_+ (contract in :mod:`rrfrei.laws.effects`)."""
    ex = abs(u) - p[po + 1]
    if ex > 0.0:
        fa += p[po] * ex * (1.0 if u > 0.0 else -1.0)
        ka += p[po]
    return g, dg, fa, ka


EFFECT = register_effect(EffectSpec(
    "rollover",
    (ParamSpec("roll_k", "kN/m", -1e9, 1e9,
               "tangent stiffness change beyond the onset (< 0 rollover softening)",
               Prior("normal", 0.0, 1.0)),
     ParamSpec("roll_onset", "m", 0.0, 1e3, "displacement at which the tangent changes",
               Prior("halfnormal", 1.0))),
    0, "amplitude-dependent tangent stiffness at large displacement", (0.0, 0.0), apply=apply))
