"""Effect ``slip``: sliding of an unbonded bearing on its supports (series slider).

A slider of capacity ``F_s = mu N`` [kN] in series with the (augmented) law; while ``|F| < F_s``
it sticks, else ``u_s`` moves so that ``|F| = F_s`` (solved by safeguarded Newton on the inner
law, then bisection: :mod:`rrfrei.laws.effects._augment`).  While it sticks, the interface
deforms elastically by ``x_e = y_s F / F_s`` (``|x_e| <= y_s``, the stick displacement
``slip_stick`` [m]): an elastic-plastic slider of stick stiffness ``k_s = F_s / y_s``, the
pre-sliding displacement of a frictional contact, proportional to the force up to gross sliding
(Mindlin 1949, "Compliance of elastic bodies in contact", J. Appl. Mech. 16; the yield
displacement ``Y`` of the sliding interface in Constantinou, Mokha & Reinhorn 1990, "Teflon
bearings in base isolation II: modeling", J. Struct. Eng. 116(2), of which this is the sharp,
``n -> infinity`` limit).  It rounds the transition from stick to slip and lowers the stiffness
the bearing shows while it sticks.  ``y_s = 0`` (the default): the rigid-plastic slider bit for
bit.

Static and kinetic friction: the capacity to break away from rest exceeds the capacity while
sliding, and falls to it over a slip distance (the breakaway friction of sliding bearings, Mokha,
Constantinou & Reinhorn 1990, "Teflon bearings in base isolation I: testing", J. Struct. Eng.
116(2)).  The linear slip-weakening law (Ida 1972, "Cohesive force across the tip of a
longitudinal shear crack and Griffith's specific surface energy", J. Geophys. Res. 77(20); Palmer
& Rice 1973, Proc. R. Soc. Lond. A 332)::

    F_s = F_k (1 + (r - 1) max(1 - s / d_c, 0))

with ``F_k`` = ``slip_force`` the kinetic capacity, ``r`` = ``slip_static`` >= 1 the ratio of
static to kinetic capacity, ``d_c`` = ``slip_dc`` [m] the slip distance over which it weakens and
``s`` the slip travel since the slider last stuck (committed, so the capacity of a step is that
of the state it starts from); every stick restores the static capacity.  ``r = 1`` (the
default): a constant capacity, bit for bit.  Dissipative.  Neutral: ``slip_force`` at its upper
bound (never reached).

State (2): ``[u_s, s]`` the slider's plastic slip [m] and its slip travel since it last stuck [m].

The diagnosis fits ``slip_force``, ``slip_static`` and ``slip_dc`` (a rigid-plastic slider,
``y_s = 0``).  With the stick displacement fitted as well, the 30 slip cases of the validation
table lost verdicts rather than gaining shrink (27 and 25 of 30 named, against 28 before): the
stick solve drives the ``bouc_wen`` base law through trial steps at which its own iteration
fails on held-out tests, and the held-out shrink of the smooth slider form did not move
(0.45-0.46).  ``y_s`` stays for calibration.  Refitted to the validation's stick-slip form
(``slip/stick_slip``, noise-free, largest size) the slip-weakening kernel misses it by 0.13 % of
the peak force: that form weakens over 1 mm of slip, within one sample of the table (5 Hz), so
no weakening law differs from it there and it no longer tests a shape beyond the kernel's
(docs/gap/validation.md).
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior

SLIP_NEVER = 1e12
"""``slip_force`` [kN] at which the slider never slides (its neutral value and upper bound)."""


@njit(cache=True, inline="always")
def capacity(p, po, sc, so):
    """The friction capacity F_k (1 + (r - 1) max(1 - s / d_c, 0)) [kN] (contract in
    :mod:`rrfrei.laws.effects`)."""
    r = p[po + 2]
    if r == 1.0:
        return p[po]
    return p[po] * (1.0 + (r - 1.0) * max(1.0 - sc[so + 1] / p[po + 3], 0.0))


@njit(cache=True, inline="always")
def stick(p, po):
    """The stick displacement y_s [m] (contract in :mod:`rrfrei.laws.effects`)."""
    return p[po + 1]


def _screen(ctx) -> float:
    """r sgn(F) against the excess of |F| over its 80th percentile (a capped force)."""
    a = np.abs(ctx.force_pred)
    return partial(ctx.resid * force_sign(ctx), np.maximum(a - np.quantile(a, 0.8), 0.0), [a])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"slip_force": 0.9 * s.force, "slip_static": 1.0},
               {"slip_force": 0.75 * s.force, "slip_static": 1.0},
               {"slip_force": 0.75 * s.force, "slip_static": 1.2, "slip_dc": 0.1 * s.disp}],
    lambda s: {"slip_force": s.force, "slip_static": 0.2, "slip_dc": 0.1 * s.disp},
    lambda s: {"slip_force": (0.2 * s.force, 2.0 * s.force), "slip_static": (1.0, 2.0),
               "slip_dc": (0.005 * s.disp, s.disp)},
    order=6)


EFFECT = register_effect(EffectSpec(
    "slip",
    (ParamSpec("slip_force", "kN", 0.0, SLIP_NEVER, "friction capacity of the supports mu N",
               Prior("loguniform", 1e-2, 1e3)),
     ParamSpec("slip_stick", "m", 0.0, 1e3,
               "stick displacement y_s: elastic deformation of the interface at the capacity "
               "(stick stiffness F_s / y_s; 0: rigid-plastic)",
               Prior("halfnormal", 1e-3), default=0.0),
     ParamSpec("slip_static", "-", 1.0, 10.0,
               "ratio r of the static (breakaway) to the kinetic capacity (1: one capacity)",
               Prior("uniform", 1.0, 2.0), default=1.0),
     ParamSpec("slip_dc", "m", 1e-9, 1e3, "slip distance d_c over which the static capacity "
               "weakens linearly to the kinetic one", Prior("halfnormal", 1e-2), default=1e-3)),
    2, "sliding of an unbonded bearing once shear exceeds the friction capacity",
    (SLIP_NEVER, 0.0, 1.0, 1e-3), capacity=capacity, hints=HINTS, stick=stick))
