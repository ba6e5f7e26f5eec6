"""Effect ``pinching``: reduced force near zero displacement once the bearing has been loaded
(inner, scaling).

Slack or gap closing (the pinching of the BWBN model, Baber & Noori 1986; Foliente 1995): after
the first excursion, the force is reduced in a band of width ``u_p`` about ``u = 0``, and the
reduction vanishes at the largest |u| reached so far, ``u_max``, so the force stays continuous::

    g = 1 - p [exp(-(u / u_p)^2) - exp(-(u_max / u_p)^2)]      for |u| < u_max, else 1

(``u_max`` committed; virgin loading is unpinched).  ``g`` depends on ``u`` and ``u_max`` only, so
a cycle at a constant amplitude closes; with ``0 <= p < 1`` it is in (0, 1], so the loop area is
smaller than the base law's.  Neutral: ``pinch = 0``.

State (1): ``[u_max]`` [m].
"""

import math

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, signed_partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 - p [exp(-(u/u_p)^2) - exp(-(u_max/u_p)^2)] below u_max (contract in
    :mod:`rrfrei.laws.effects`)."""
    um = sc[so]
    a = abs(u)
    st[so] = max(um, a)
    pin = p[po]
    if pin != 0.0 and a < um:
        w = p[po + 1]
        x = u / w
        e = math.exp(-x * x)
        xm = um / w
        gi = 1.0 - pin * (e - math.exp(-xm * xm))
        dgi = 2.0 * pin * x / w * e
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against a narrow band of |u| near 0 on branches below the previous peak |u|
    (the force there is smaller: a negative association; positive scores 0)."""
    a = np.abs(ctx.disp)
    peak = float(a.max()) if a.size else 0.0
    before = np.concatenate([[0.0], np.maximum.accumulate(a)[:-1]])
    band = (a < 0.15 * peak) & (a < before)
    return max(-signed_partial(ctx.resid * force_sign(ctx), band.astype(float), [a]), 0.0)


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"pinch": 0.3, "pinch_width": 0.2 * s.disp}, {"pinch": 0.6, "pinch_width": 0.1 * s.disp}],
    lambda s: {"pinch": 0.3, "pinch_width": 0.2 * s.disp},
    lambda s: {"pinch_width": (0.02 * s.disp, s.disp)}, order=8)


EFFECT = register_effect(EffectSpec(
    "pinching",
    (ParamSpec("pinch", "-", 0.0, 0.95, "largest relative force reduction at u = 0 once loaded",
               Prior("uniform", 0.0, 0.9)),
     ParamSpec("pinch_width", "m", 1e-6, 1e3, "half-width of the pinched band about u = 0",
               Prior("halfnormal", 1.0))),
    1, "pinching: slack (gap closing) near zero displacement on later cycles", (0.0, 1.0),
    apply=apply, hints=HINTS))
