"""Effect ``stiffening``: smooth stiffening at large displacement (inner, additive).

High-damping rubber stiffens at large shear strain as its chains reach their extensibility
(Kikuchi & Aiken 1997; Grant et al. 2004).  Beyond the onset ``u_s`` an elastic force grows with
a power ``n > 1`` of the excess ``e = (|u| - u_s)_+``::

    f_a = k_s u_s sgn(u) (e / u_s)^n / n,        df_a/du = k_s (e / u_s)^(n - 1)

so the added tangent is zero at the onset (continuous, unlike ``rollover``'s kinked linear hinge)
and equals ``k_s`` at twice the onset.  ``n = 2`` (the default, ``stiff_exp``): a tangent growing
linearly with the excess, ``f_a = k_s sgn(u) e^2 / (2 u_s)`` (evaluated as such, bit for bit the
two-parameter kernel); a larger ``n`` makes the upturn later and steeper, as the higher-order
terms of the polynomial strain energies of filled rubber do (Yeoh 1993, "Some forms of the strain
energy function for rubber", Rubber Chem. Technol. 66: the cubic term, whose shear force grows as
the fifth power of the strain, is the one that makes the upturn; Gent 1996's limiting
extensibility steeper still).  ``k_s >= 0`` only (stiffening).  Elastic (path independent): it adds
no loop area.  Neutral: ``stiff_k = 0``.  No state.

The diagnosis fits ``1.5 <= n <= 6`` (its box) besides ``k_s`` and ``u_s``.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import power_excess
from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import signed_partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add k_s u_s sgn(u) ((|u| - u_s)_+ / u_s)^n / n (contract in :mod:`rrfrei.laws.effects`)."""
    k = p[po]
    us = p[po + 1]
    n = p[po + 2]
    ex = abs(u) - us
    if k != 0.0 and ex > 0.0:
        if n == 2.0:
            fa += 0.5 * k * ex * ex / us * (1.0 if u > 0.0 else -1.0)
            ka += k * ex / us
        else:
            fe, ke = power_excess(k, us, n, ex)
            fa += fe * (1.0 if u > 0.0 else -1.0)
            ka += ke
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(u) against the squared excess of |u| over half its peak (stiffening only: a
    negative association scores 0)."""
    a = np.abs(ctx.disp)
    onset = 0.5 * float(a.max()) if a.size else 0.0
    ex = np.maximum(a - onset, 0.0)
    return max(signed_partial(ctx.resid * np.sign(ctx.disp), ex**2, [a, ex]), 0.0)


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"stiff_k": 0.3 * s.force / s.disp, "stiff_onset": 0.5 * s.disp, "stiff_exp": 2.0},
               {"stiff_k": 1.0 * s.force / s.disp, "stiff_onset": 0.5 * s.disp, "stiff_exp": 2.0},
               {"stiff_k": 0.3 * s.force / s.disp, "stiff_onset": 0.25 * s.disp, "stiff_exp": 3.0}],
    lambda s: {"stiff_k": s.force / s.disp, "stiff_onset": s.disp, "stiff_exp": 1.0},
    lambda s: {"stiff_k": (0.0, 20 * s.force / s.disp), "stiff_onset": (0.05 * s.disp, s.disp),
               "stiff_exp": (1.5, 6.0)},
    order=7)


EFFECT = register_effect(EffectSpec(
    "stiffening",
    (ParamSpec("stiff_k", "kN/m", 0.0, 1e9,
               "added tangent stiffness at twice the onset (grows linearly with the excess)",
               Prior("halfnormal", 1.0)),
     ParamSpec("stiff_onset", "m", 1e-6, 1e3, "displacement at which stiffening starts",
               Prior("halfnormal", 1.0)),
     ParamSpec("stiff_exp", "-", 1.01, 20.0,
               "power n of the excess over the onset (2: tangent linear in the excess)",
               Prior("uniform", 1.5, 6.0), default=2.0)),
    0, "smooth stiffening at large displacement (high-damping rubber at large strain)", (0.0, 1.0, 2.0),
    apply=apply, hints=HINTS))
