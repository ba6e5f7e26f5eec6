"""Effect ``scragging``: permanent softening with the largest |u| ever reached (inner, scaling).

A virgin elastomer softens for good once it has been deformed (scragging, Thompson et al. 2000;
the ASCE 7-22 17.2.8.4 property modification for scragging)::

    g = 1 - s (1 - exp(-u_max / u_c))

with ``u_max`` the largest |u| so far including the current one.  Unlike ``mullins`` (softer only
below u_max, recovering on virgin loading beyond it) and ``degradation`` (fading on with work at
a constant amplitude), the softening applies to all later loading, including virgin loading, and
only grows with a new peak.  Its state is what a bearing carries from one test to the next
(:attr:`rrfrei.io.ShearTest.preceding`).  Neutral: ``scrag = 0``.

How the softening sets in with the peak: a Weibull shape ``k`` (``scrag_shape``)::

    g = 1 - s (1 - exp(-(u_max / u_c)^k))
    dg/du_max = -s k (u_max / u_c)^(k - 1) exp(-(u_max / u_c)^k) / u_c

``k = 1`` (the default): the exponential above, bit for bit; ``k > 1``: little softening until
the peak nears ``u_c``, then most of it over a narrow band of peaks (the scragging of a filled
rubber is concentrated in the first cycles at a new, large strain: Thompson, Whittaker, Fenves
& Mahin 2000, "Property modification factors for elastomeric seismic isolation bearings", 12th
WCEE; the breakdown of filler structure grows as a sigmoid of the strain amplitude, Payne 1962);
``k < 1``: most of it at small peaks.  The diagnosis fits the exponential, and ``k`` in
[0.5, 6] as the variant ``onset``, which stands for the effect only when it beats it on the
held-out blocks (:class:`rrfrei.laws.effects.Variant`).

State (1): ``[u_max]`` [m].
"""

import math

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, Variant, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 - s (1 - exp(-(u_max / u_c)^k)) (contract in :mod:`rrfrei.laws.effects`)."""
    a = abs(u)
    um = max(sc[so], a)
    st[so] = um
    s = p[po]
    if s != 0.0:
        uc = p[po + 1]
        k = p[po + 2]
        if k == 1.0:
            e = math.exp(-um / uc)
            de = e / uc
        else:
            x = um / uc
            xk = x**k
            e = math.exp(-xk)
            de = k * xk / x * e / uc if x > 0.0 else 0.0
        gi = 1.0 - s * (1.0 - e)
        dgi = 0.0
        if a > sc[so]:  # on a new peak u_max moves with u
            dgi = -s * de * (1.0 if u > 0.0 else -1.0)
        dg = dg * gi + g * dgi
        g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against the running peak |u| beyond |u| (the force fades with it; unsigned, as
    the baseline's own fit may absorb part of the fade either way)."""
    a = np.abs(ctx.disp)
    return partial(ctx.resid * force_sign(ctx), np.maximum.accumulate(a), [a])


HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"scrag": 0.2, "scrag_disp": 0.5 * s.disp}, {"scrag": 0.4, "scrag_disp": 0.2 * s.disp}],
    lambda s: {"scrag": 0.2, "scrag_disp": s.disp},
    lambda s: {"scrag_disp": (0.02 * s.disp, 5.0 * s.disp)}, order=9,
    variants=(Variant(
        "onset",
        "scragging that sets in near a peak displacement: a Weibull shape k of the peak fitted",
        lambda s: [{"scrag": 0.2, "scrag_disp": f * s.disp, "scrag_shape": k}
                   for f, k in ((0.5, 3.0), (0.3, 2.0), (0.8, 5.0))],
        lambda s: {"scrag": 0.2, "scrag_disp": s.disp, "scrag_shape": 1.0},
        lambda s: {"scrag_disp": (0.02 * s.disp, 5.0 * s.disp), "scrag_shape": (0.5, 6.0)}),))


EFFECT = register_effect(EffectSpec(
    "scragging",
    (ParamSpec("scrag", "-", 0.0, 0.95, "softening reached after a very large displacement",
               Prior("uniform", 0.0, 0.9)),
     ParamSpec("scrag_disp", "m", 1e-6, 1e3, "displacement scale of the softening u_c",
               Prior("halfnormal", 1.0)),
     ParamSpec("scrag_shape", "-", 0.2, 20.0,
               "Weibull shape k of the softening in the peak (1: exponential; > 1: sets in near u_c)",
               Prior("uniform", 0.5, 6.0), default=1.0)),
    1, "scragging: permanent softening with the largest displacement ever reached", (0.0, 1.0, 1.0),
    apply=apply, hints=HINTS, memory=True))
