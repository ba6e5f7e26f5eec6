"""Effect ``rollover``: amplitude-dependent tangent at large displacement (inner, additive).

``f_a = k_r sgn(u) (|u| - u_r)_+`` with ``k_r <= 0``: the rollover softening of unbonded FREIs
(Toopchi-Nezhad et al. 2008), a kinked loss of tangent stiffness beyond the onset.  Stiffening at
large displacement is the separate effect ``stiffening`` (smooth onset): the two names keep the
two physical signs apart, so a diagnosis that names one says which way the bearing departs.

A smooth rollover: with a power ``n > 1`` of the excess ``e = (|u| - u_r)_+`` (``roll_exp``),
as ``stiffening``'s shape with the other sign::

    f_a = k_r u_r sgn(u) (e / u_r)^n / n,        df_a/du = k_r (e / u_r)^(n - 1)

the tangent loss grows from zero at the onset and is ``k_r`` at twice the onset: an unbonded
FREI's ends roll off its supports progressively, so its backbone is fitted by an odd polynomial
whose cubic term softens it (Toopchi-Nezhad, Tait & Drysdale 2008, "Testing and modeling of
square carbon fiber-reinforced elastomeric seismic isolators", Struct. Control Health Monit.
15; Kelly & Konstantinidis 2011, *Mechanics of Rubber Bearings for Seismic and Vibration
Isolation*, ch. 9).  ``n = 1`` (the default): the kinked hinge, bit for bit; ``n`` acts only
with an onset ``u_r > 0`` (at ``u_r = 0`` the hinge is linear whatever ``n``).  The diagnosis
fits the kinked hinge, and the smooth shape (``n`` in [1.5, 4], ``u_r >= 0.05`` of the peak
displacement) as the variant ``smooth`` that stands for the effect only when it beats the hinge
on the held-out blocks (:class:`rrfrei.laws.effects.Variant`).

Elastic (path independent).  Neutral: ``k_r = 0``.  No state.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import power_excess
from rrfrei.laws.effects import DiagnosisHints, EffectSpec, Variant, register_effect
from rrfrei.laws.effects._screens import partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add k_r sgn(u) (|u| - u_r)_+, or k_r u_r sgn(u) ((|u| - u_r)_+ / u_r)^n / n for n != 1
    and u_r > 0 (contract in :mod:`rrfrei.laws.effects`)."""
    ur = p[po + 1]
    ex = abs(u) - ur
    if ex > 0.0:
        n = p[po + 2]
        if n == 1.0 or ur <= 0.0:
            fa += p[po] * ex * (1.0 if u > 0.0 else -1.0)
            ka += p[po]
        else:
            fe, ke = power_excess(p[po], ur, n, ex)
            fa += fe * (1.0 if u > 0.0 else -1.0)
            ka += ke
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
    order=3,
    variants=(Variant(
        "smooth",
        "smooth rollover: the tangent loss grows as a power n of the excess over the onset",
        lambda s: [{"roll_k": -0.3 * s.force / s.disp, "roll_onset": f * s.disp, "roll_exp": n}
                   for f, n in ((0.1, 3.0), (0.3, 2.0), (0.5, 2.0))],
        lambda s: {"roll_k": s.force / s.disp, "roll_onset": s.disp, "roll_exp": 1.0},
        lambda s: {"roll_k": (-10 * s.force / s.disp, 0.0), "roll_onset": (0.05 * s.disp, s.disp),
                   "roll_exp": (1.5, 4.0)}),))


EFFECT = register_effect(EffectSpec(
    "rollover",
    (ParamSpec("roll_k", "kN/m", -1e9, 0.0,
               "tangent stiffness lost beyond the onset (<= 0: rollover softening)",
               Prior("normal", 0.0, 1.0)),
     ParamSpec("roll_onset", "m", 0.0, 1e3, "displacement at which the tangent changes",
               Prior("halfnormal", 1.0)),
     ParamSpec("roll_exp", "-", 1.0, 20.0,
               "power n of the excess over the onset (1: kinked hinge; > 1 smooth, needs onset > 0)",
               Prior("uniform", 1.0, 4.0), default=1.0)),
    0, "amplitude-dependent tangent stiffness at large displacement", (0.0, 0.0, 1.0), apply=apply,
    hints=HINTS))
