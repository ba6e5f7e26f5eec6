"""Effect ``rate``: a force that depends on velocity (inner, additive and scaling).

A viscous force that may saturate at high velocity, and a strength that grows with velocity to a
plateau::

    F = g_v f_b + f_a,    f_a = c sgn(v) |v|^a / (1 + (lam |v|)^a),
                          g_v = 1 + r (1 - exp(-|v| / v_s))

``lam = 0`` (the default, ``rate_sat``): the power-law viscous force ``c sgn(v) |v|^a`` of fluid
dampers and rubber (``a = 1`` linear viscous, ``a < 1`` as in Constantinou & Symans 1993,
"Experimental study of seismic response of buildings with supplemental fluid dampers", Struct.
Des. Tall Build. 2).  ``lam > 0``: the Cross model of a shear-thinning material (Cross 1965,
"Rheology of non-Newtonian fluids: a new flow equation for pseudoplastic systems", J. Colloid
Sci. 20), whose apparent viscosity ``c |v|^(a-1) / (1 + (lam |v|)^a)`` falls with the rate, so
the force rises as ``c |v|^a`` at low velocity and levels off at ``c / lam^a`` beyond
``|v| ~ 1 / lam``: the velocity dependence of sliding friction, which grows from its static to its
high-velocity value and then stays (Constantinou, Mokha & Reinhorn 1990, "Teflon bearings in
base isolation II: modeling", J. Struct. Eng. 116(2)), and of rubber whose rate effect saturates.
``f_a`` is odd in ``v`` and increasing in ``|v|``, so it dissipates for ``c >= 0``.  At
``lam = 0`` the kernel evaluates the power law itself (bit for bit the two-parameter kernel).

``g_v`` is the velocity-dependent strength of a sliding interface: its coefficient of friction
rises from its low-velocity value ``f_min`` to ``f_max`` as ``f_max - (f_max - f_min)
exp(-|v| / v_s)`` (Constantinou, Mokha & Reinhorn 1990, eq. 4, there with ``a = 1 / v_s``;
Mokha, Constantinou & Reinhorn 1990, "Teflon bearings in base isolation I: testing", J. Struct.
Eng. 116(2)), and the force of a rubber bearing whose stiffness and damping both grow with the
loading rate up to a plateau: it scales the base force, so the bearing's whole loop, not a
force added beside it, is stronger the faster it moves (``r = f_max / f_min - 1 >= 0``, the
rise; ``v_s`` [m/s] the velocity over which it saturates).  ``r = 0`` (the default): no
scaling, the viscous kernel bit for bit.  Neutral: ``c = 0``, ``r = 0``.  No state (``v`` is
the step's own velocity).

The diagnosis fits ``c`` and the strength's ``r`` and ``v_s`` (the viscous force linear,
``a = 1``, ``lam = 0``: the primary fit), and with ``a`` free in ``[0.2, 1]`` as the variant
``power`` (the power-law viscous force of fluid dampers; :class:`rrfrei.laws.effects.Variant`),
which stands for the effect only when it beats the primary fit on the held-out blocks.  Refitted
to the validation's saturating form (``rate/tanh_friction``, noise-free, largest size) the
primary fit misses it by 3.1 % of the peak force, the power variant by about 1.2 %, under the
table's 2 % noise: with the variant that form, like ``rate/friction_velocity`` (the law of
Constantinou et al. on the hysteretic part of the force alone, missed by 1.2 % by the primary
fit), no longer tests a shape beyond the catalogue's (docs/gap/validation.md).  The Cross
saturation (``lam``) stays for calibration.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, Variant, register_effect
from rrfrei.laws.effects._screens import partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add c sgn(v) |v|^a / (1 + (lam |v|)^a), tangent c a |v|^(a-1) / (1 + (lam |v|)^a)^2 / dt,
    and scale by 1 + r (1 - exp(-|v| / v_s)), dg/du = r exp(-|v| / v_s) sgn(v) / (v_s dt)
    (contract in :mod:`rrfrei.laws.effects`)."""
    c = p[po]
    a = p[po + 1]
    lam = p[po + 2]
    r = p[po + 3]
    av = abs(v)
    if r != 0.0 and av > 0.0:
        vs = p[po + 4]
        ex = np.exp(-av / vs)
        gv = 1.0 + r * (1.0 - ex)
        dgv = r * ex / vs / dt * (1.0 if v > 0.0 else -1.0)
        dg = dg * gv + g * dgv
        g = g * gv
    if lam == 0.0:
        if av > 0.0:
            fa += c * (av**a) * (1.0 if v > 0.0 else -1.0)
            ka += c * a * av ** (a - 1.0) / dt
        elif a == 1.0:
            ka += c / dt
    else:
        if av > 0.0:
            h = av**a
            d = 1.0 + lam**a * h
            fa += c * h / d * (1.0 if v > 0.0 else -1.0)
            ka += c * a * av ** (a - 1.0) / (d * d) / dt
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
    lambda s: [{"rate_c": 0.05 * s.force / s.vel, "rate_rise": 0.0, "rate_vsat": 0.3 * s.vel},
               {"rate_c": 0.2 * s.force / s.vel, "rate_rise": 0.0, "rate_vsat": 0.3 * s.vel},
               {"rate_c": 0.0, "rate_rise": 0.2, "rate_vsat": 0.3 * s.vel}],
    lambda s: {"rate_c": s.force / s.vel, "rate_rise": 0.3, "rate_vsat": s.vel},
    lambda s: {"rate_c": (0.0, 20 * s.force / s.vel), "rate_rise": (0.0, 2.0),
               "rate_vsat": (0.02 * s.vel, 5.0 * s.vel)},
    needs_time=True, order=4,
    variants=(Variant(
        "power",
        "power-law viscous force c sgn(v) |v|^a, a fitted (fluid dampers, Constantinou & Symans 1993)",
        lambda s: [{"rate_c": 0.1 * s.force / s.vel**a, "rate_exp": a, "rate_rise": 0.0,
                    "rate_vsat": 0.3 * s.vel} for a in (0.3, 0.6)]
        + [{"rate_c": 0.05 * s.force / s.vel**0.5, "rate_exp": 0.5, "rate_rise": 0.2,
            "rate_vsat": 0.3 * s.vel}],
        lambda s: {"rate_c": s.force / s.vel**0.5, "rate_exp": 0.3, "rate_rise": 0.3, "rate_vsat": s.vel},
        lambda s: {"rate_c": (0.0, 20 * s.force / min(s.vel, 1.0)), "rate_exp": (0.2, 1.0),
                   "rate_rise": (0.0, 2.0), "rate_vsat": (0.02 * s.vel, 5.0 * s.vel)}),))


EFFECT = register_effect(EffectSpec(
    "rate",
    (ParamSpec("rate_c", "kN*s/m", 0.0, 1e9, "viscous coefficient of c sgn(v)|v|^a",
               Prior("halfnormal", 1e3)),
     ParamSpec("rate_exp", "-", 0.1, 2.0, "velocity exponent a", Prior("uniform", 0.2, 1.5),
               default=1.0),
     ParamSpec("rate_sat", "s/m", 0.0, 1e6,
               "inverse saturation velocity lam of the Cross form (0: no saturation)",
               Prior("halfnormal", 10.0), default=0.0),
     ParamSpec("rate_rise", "-", 0.0, 100.0,
               "rise r of the strength with velocity, g_v = 1 + r (1 - exp(-|v| / v_s)) (0: none)",
               Prior("halfnormal", 0.5), default=0.0),
     ParamSpec("rate_vsat", "m/s", 1e-9, 1e6, "velocity v_s over which the strength rise saturates",
               Prior("loguniform", 1e-3, 10.0), default=0.1)),
    0, "a force that depends on velocity", (0.0, 1.0, 0.0, 0.0, 0.1), apply=apply, hints=HINTS))
