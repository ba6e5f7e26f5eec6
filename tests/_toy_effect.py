"""A toy effect defined in one module with one table entry (issue 13: "new effects are then one
module each"): a force offset that grows with the largest |u| seen, a crude permanent set.

    F = F_base + c * u_max * sgn(F_base)

``c`` [kN/m]; state ``[u_max]`` [m].  Neutral: c = 0.  Nothing else in the repository names it:
``tests/test_toy_effect.py`` composes it with a law and finds it among the gap diagnosis's
candidates.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior

NAME = "toy_offset"


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Add c u_max sgn(F_base) (contract in :mod:`rrfrei.laws.effects`); no tangent (u_max is
    history)."""
    um = max(sc[so], abs(u))
    st[so] = um
    s = 1.0 if fb > 0.0 else (-1.0 if fb < 0.0 else 0.0)
    fa += p[po] * um * s
    return g, dg, fa, ka


def _screen(ctx) -> float:
    return partial(ctx.resid * force_sign(ctx), np.maximum.accumulate(np.abs(ctx.disp)),
                   [np.abs(ctx.disp)])


EFFECT = register_effect(EffectSpec(
    NAME,
    (ParamSpec("offset_c", "kN/m", 0.0, 1e9, "offset per metre of the largest |u|",
               Prior("halfnormal", 1e3)),),
    1, "a force offset that grows with the largest displacement", (0.0,), apply=apply,
    hints=DiagnosisHints(_screen, lambda s: [{"offset_c": 0.1 * s.force / s.disp}],
                         lambda s: {"offset_c": s.force / s.disp}, order=50)))
