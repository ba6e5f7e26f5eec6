"""Effect ``pinching``: slack near zero force, the loop pinched where it crosses a line through
the origin (inner, scaling by a function of the base force and displacement).

Slack or gap closing, the pinching of the BWBN model (Baber & Noori 1986, "Modeling general
hysteresis behavior and random vibration application", J. Vib. Acoust. 108; Foliente 1995,
"Hysteresis modeling of wood joints and structural systems", J. Struct. Eng. 121(6)): there the
hysteretic variable z grows slowly, ``dz/du`` scaled by ``h(z) = 1 - zeta_1 exp(-(z sgn(du) -
q)^2 / zeta_2^2)``, while |z| is small, so the stiffness is reduced near *zero force*, away from
u = 0 in a loop with hysteresis.  As an effect that wraps any law the reduction acts on the base
force ``f_b`` at the pinching coordinate

    xi = cos(phi) f_b / F_max - sin(phi) u / u_max

(``F_max``, ``u_max`` the largest |f_b| and |u| committed so far): ``xi = 0`` is a line through
the origin of the loop, normalised by its previous peaks.  ``phi = 0`` pinches where the base
force is zero (BWBN, slip-lock), ``phi = atan(k2 u_max / F_max)`` where its hysteretic part is
zero, ``phi = +-pi/2`` at zero displacement (the earlier displacement-space kernel's place).  The
slack has a finite extent (the gap closes, Baber & Noori's slip-lock element), so the reduction is
a compact C1 bump, half-width ``w`` in ``xi``::

    F = g f_b,   g = 1 - p b(xi / w),   b(x) = (1 - x^2)^2 for |x| < 1, else 0
    dg/du = -p b'(xi / w) / w (cos(phi) k_b / F_max - sin(phi) / u_max),  b'(x) = -4 x (1 - x^2)

so the tangent needs the base law's ``k_b`` (effect contract, :mod:`rrfrei.laws.effects`).  At
``phi = 0``, ``dF/df_b = 1 - p (1 - x^2)(1 - 5 x^2) >= 1 - p > 0``: the force stays monotonic
in the base force and the stiffness at zero force is ``(1 - p) k_b``.  ``g`` depends on the state
only through the committed peaks, so a cycle at a constant amplitude closes; with
``0 <= p < 1``, ``0 < g <= 1`` and the force is never larger in magnitude than the base force
(the loop dissipates less).  Before the first step (``F_max = 0`` or ``u_max = 0``) ``g = 1``.
Neutral: ``pinch = 0`` (any width and angle).

Squeezed toward the line, not toward zero force (BWBN)
------------------------------------------------------
In BWBN the pinching slows the hysteretic variable z near ``z = 0`` only, so the force there
follows the non-hysteretic part of the law, ``alpha k u``: the loop is squeezed toward the line
of its elastic part, not toward zero force, in a band of z of a fixed width (Foliente 1995, eqs.
4-6).  Two more things make the kernel that:

* ``lam`` (``pinch_line``, in [0, 1]) blends the band toward the pinching line's own force
  ``kappa u``::

      F = g f_b + (1 - g) lam kappa u,
      dF/du = g k_b + f_b dg/du + lam kappa ((1 - g) - u dg/du)

  ``lam = 1``: ``F - kappa u = g (f_b - kappa u)``, the distance from the line is scaled and the
  line's force kept; ``lam = 0`` (the default): the band kernel above bit for bit.  The line term
  is an additive force (other scaling effects do not scale it).
* a line of a fixed slope in a band of a fixed force width: with ``w_F > 0`` (``pinch_force``
  [kN]) the band coordinate is ``x = (f_b - kappa u) / w_F`` with ``kappa`` = ``pinch_slope``
  [kN/m] (``phi``, ``w`` and the peaks are then not used; ``dx/du = (k_b - kappa) / w_F``).  On a
  law whose elastic part is ``alpha k u``, ``kappa = alpha k`` puts the band on ``z = 0`` exactly,
  with ``w_F`` its width in force, ``q_d`` times BWBN's width in z.  ``w_F = 0`` (the default):
  the peaks-normalised coordinate ``xi`` above, whose line ``kappa = tan(phi) F_max / u_max``
  (used by ``lam`` there, for ``cos(phi) > 1e-6``) turns as the peaks grow.

The diagnosis fits the fixed line with ``lam`` as the variant ``bwbn`` (``p``, ``kappa``,
``w_F``, ``lam`` free), which stands for the effect only when it beats the primary fit on the
held-out blocks (:class:`rrfrei.laws.effects.Variant`).  A variant on the peaks-normalised line
(``lam``, ``w <= 1``, ``|phi| <= 1.2``) was tried and not kept: on the validation's
``pinching/bwbn_like`` form it stood for the effect in 5 of 10 cases with held-out shrinks of
0.43-0.52, where the fixed line gives 1.00 in all ten (docs/gap/validation.md).

Slack is local: the diagnosis fits the half-width in ``w <= 0.5`` (its box, the physical bound is
wider), so a band never spans more than half of the previous peaks either side of the line.  A
softening below the previous peak that reaches out to ``u_max`` is Mullins' (:mod:`.mullins`);
at ``phi = pi/2`` both are functions of ``|u| / u_max`` alone and the band's width is what tells
them apart (docs/gap/validation.md, "Why the misses").

Slack in series (slip-lock)
--------------------------
The band above squeezes the force at the same displacement; the slack of a joint or a gap that
opens and closes also *stretches* the loop: after every zero crossing the base law lags behind by
the slack's travel.  Baber & Noori's pinching comes from exactly such a slip-lock element in
series with the hysteretic one, whose compliance is a Gaussian of the force it carries (Baber &
Noori 1986, eqs. for the slip-lock element; Foliente 1995, eq. 9, ``h(z)``).  Its deformation is
then an error function of the force, soft near zero force and locked (rigid) at its travel ``a``
beyond a few force widths ``sigma``::

    x_s = a erf(F / sigma),        dx_s/dF = 2 a / (sqrt(pi) sigma) exp(-(F / sigma)^2)

and the whole law (base, the other effects, a slider) acts on ``u - x_s`` (a series solve,
:func:`rrfrei.laws.effects._augment._slack`); the slack centre is zero force, so the element is
elastic and adds no loop area of its own.  ``slack_gap = a = 0`` (the default): no element, the
band kernel bit for bit.  The diagnosis fits ``a <= 0.5`` of the test's peak displacement and
``0.005 <= sigma / F_peak <= 0.5`` (its box) besides the band.

State (5): ``[F_max [kN], u_max [m], x_s [m], u_c [m], dx_s/du [-]]`` (the last two: the total
displacement at which ``x_s`` was committed and its rate there, the predictor of the series
solve).
"""

import math

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, Variant, register_effect
from rrfrei.laws.effects._screens import force_sign, signed_partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by g = 1 - p b(xi / w), xi = cos(phi) f_b / F_max - sin(phi) u / u_max, and add
    (1 - g) lam kappa u (contract in :mod:`rrfrei.laws.effects`)."""
    fm = sc[so]
    um = sc[so + 1]
    st[so] = max(fm, abs(fb))
    st[so + 1] = max(um, abs(u))
    pin = p[po]
    if pin == 0.0:
        return g, dg, fa, ka
    lam = p[po + 5]
    wf = p[po + 7]
    x = 2.0  # outside the band
    dxdu = 0.0
    kap = 0.0
    if wf > 0.0:  # the line of a fixed slope, a band of a fixed force width (BWBN)
        k0 = p[po + 6]
        x = (fb - k0 * u) / wf
        dxdu = (kb - k0) / wf
        kap = lam * k0
    elif fm > 0.0 and um > 0.0:  # the line through the previous peaks' corner at angle phi
        w = p[po + 1]
        phi = p[po + 2]
        c = math.cos(phi)
        s = math.sin(phi)
        x = (c * fb / fm - s * u / um) / w
        dxdu = (c * kb / fm - s / um) / w
        if lam != 0.0 and c > 1e-6:
            kap = lam * s / c * fm / um
    if abs(x) < 1.0:
        q = 1.0 - x * x
        gi = 1.0 - pin * q * q
        dgi = 4.0 * pin * x * q * dxdu
        if kap != 0.0:
            fa += (1.0 - gi) * kap * u
            ka += kap * ((1.0 - gi) - u * dgi)
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


@njit(cache=True, inline="always")
def compliance(p, pc, f):
    """Slack element's deformation a erf(F / sigma) and its derivative in F (``p[pc]`` = a,
    ``p[pc + 1]`` = sigma; contract in :mod:`rrfrei.laws.effects`)."""
    a = p[pc]
    sg = p[pc + 1]
    x = f / sg
    return a * math.erf(x), 2.0 * a / (math.sqrt(math.pi) * sg) * math.exp(-x * x)


def _screen(ctx) -> float:
    """r sgn(F) against a band of small predicted |F| (below a fifth of its peak) on branches
    below the previous peak |u| (the force there is smaller: a negative association; positive
    scores 0)."""
    a = np.abs(ctx.disp)
    fp = np.abs(ctx.force_pred)
    peak = float(fp.max()) if fp.size else 0.0
    before = np.concatenate([[0.0], np.maximum.accumulate(a)[:-1]])
    band = (fp < 0.2 * peak) & (a < before)
    return max(-signed_partial(ctx.resid * force_sign(ctx), band.astype(float), [a, fp]), 0.0)


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"pinch": 0.6, "pinch_width": 0.4, "pinch_angle": 0.5, "slack_gap": 0.0,
                "slack_force": 0.1 * s.force},
               {"pinch": 0.5, "pinch_width": 0.4, "pinch_angle": 1.4, "slack_gap": 0.0,
                "slack_force": 0.1 * s.force},
               {"pinch": 0.0, "pinch_width": 0.3, "pinch_angle": 0.0, "slack_gap": 0.1 * s.disp,
                "slack_force": 0.05 * s.force}],
    lambda s: {"pinch": 0.3, "pinch_width": 0.3, "pinch_angle": 0.5, "slack_gap": 0.1 * s.disp,
               "slack_force": 0.1 * s.force},
    lambda s: {"pinch_width": (0.05, 0.5), "slack_gap": (0.0, 0.5 * s.disp),
               "slack_force": (0.005 * s.force, 0.5 * s.force)}, order=8,
    variants=(Variant(
        "bwbn",
        "BWBN pinching about a line of fixed slope, in a band of fixed force width",
        lambda s: [{"pinch": 0.6, "pinch_slope": f * s.force / s.disp, "pinch_force": w * s.force,
                    "pinch_line": 1.0} for f, w in ((0.2, 0.3), (0.5, 0.3), (0.1, 0.6))],
        lambda s: {"pinch": 0.3, "pinch_slope": s.force / s.disp, "pinch_force": s.force,
                   "pinch_line": 0.5},
        lambda s: {"pinch_slope": (-0.5 * s.force / s.disp, 1.5 * s.force / s.disp),
                   "pinch_force": (0.02 * s.force, 1.0 * s.force), "pinch_line": (0.0, 1.0)}),))


EFFECT = register_effect(EffectSpec(
    "pinching",
    (ParamSpec("pinch", "-", 0.0, 0.95, "largest relative force reduction, on the pinching line",
               Prior("uniform", 0.0, 0.9)),
     ParamSpec("pinch_width", "-", 1e-3, 10.0,
               "half-width of the pinched band in the normalised coordinate xi",
               Prior("halfnormal", 1.0)),
     ParamSpec("pinch_angle", "rad", -math.pi / 2, math.pi / 2,
               "angle of the pinching line: 0 at zero force, +-pi/2 at zero displacement",
               Prior("uniform", -math.pi / 2, math.pi / 2)),
     ParamSpec("slack_gap", "m", 0.0, 1e3,
               "travel a of the series slack element, x_s = a erf(F / sigma) (0: none)",
               Prior("halfnormal", 0.01), default=0.0),
     ParamSpec("slack_force", "kN", 1e-9, 1e9,
               "force width sigma over which the series slack is taken up",
               Prior("halfnormal", 1.0), default=1.0),
     ParamSpec("pinch_line", "-", 0.0, 1.0,
               "blend lam of the band toward the pinching line's force (0: toward zero force, "
               "1: BWBN, the line's force kept)", Prior("uniform", 0.0, 1.0), default=0.0),
     ParamSpec("pinch_slope", "kN/m", -1e9, 1e9,
               "slope kappa of a fixed pinching line f = kappa u (used with pinch_force > 0)",
               Prior("normal", 0.0, 1e3), default=0.0),
     ParamSpec("pinch_force", "kN", 0.0, 1e9,
               "half-width w_F of a band of fixed force width about that line (0: the band in "
               "the peaks-normalised coordinate xi)", Prior("halfnormal", 1.0), default=0.0)),
    5, "pinching: slack near zero force (BWBN), where the loop crosses a line through the origin",
    (0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0), apply=apply, hints=HINTS, compliance=compliance,
    compliance_param=3))
