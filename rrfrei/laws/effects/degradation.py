"""Effect ``degradation``: strength and stiffness fade with cumulative work and travel (inner, scaling).

A damage index that mixes the cumulative work of the base force and the cumulative travel of the
bearing fades strength and stiffness together::

    g = 1 / (1 + D),        D = deg_rate E_max + deg_travel T_m,    T_m = int |d(|u|^m)|

``E`` is the cumulative work of the base force, ``E = int f_b du`` [kN m], ``E_max`` its largest
value so far, and ``T_m`` the cumulative travel of ``|u|^m`` [m^m] (``m = deg_exp``): every
half-cycle of amplitude ``A`` adds ``2 A^m`` whatever its path, so ``m = 1`` is the travel
``int |du|`` [m], ``m < 1`` weights small cycles more and ``m -> 0`` counts cycles whatever
their amplitude.  This is Miner's rule (Miner 1945, "Cumulative damage in fatigue", J. Appl.
Mech. 12) over a Coffin-Manson life ``N_f ~ A^(-m)`` (Manson 1953, NACA TN 2933; Coffin 1954,
Trans. ASME 76): the low-cycle fatigue of a joint or an elastomer, whose damage per cycle grows
as a power of its amplitude.  Both measures are lagged one step, so the tangent stays
``g k_b``.  Park & Ang (1985, "Mechanistic seismic damage model for reinforced
concrete", J. Struct. Eng. 111(4)) combine a deformation term and a dissipated-energy term in
one damage index; the deformation term here is cumulative (Banon & Veneziano 1982's normalised
cumulative rotation, the low-cycle-fatigue measure of a joint or elastomer that wears with every
excursion whatever its force), so small cycles fade the bearing more than their work alone
would.  Energy-based damage of elastomers is the ``deg_travel = 0`` case (the default: the
one-parameter kernel bit for bit); ``deg_exp = 1`` (the default) is the travel bit for bit.
Neutral: ``deg_rate = deg_travel = 0``.

The diagnosis fits ``deg_rate`` and ``deg_travel`` with ``m = 1`` (the primary fit), and with
``m`` free in ``[0.1, 2]`` as the variant ``cycles`` (:class:`rrfrei.laws.effects.Variant`),
which stands for the effect only when it beats the primary fit on the held-out blocks.  Fitting
``m`` always was tried first and not kept: on the validation table it raised the cycle-count
form's held-out shrink (median 0.40 -> 0.77) and lowered the two energy forms' (0.82 -> 0.70,
0.79 -> 0.60), as a travel measure fits protocol 1 as well as the work and extrapolates worse;
as a variant chosen on the held-out blocks the energy forms keep the primary fit
(docs/gap/validation.md).  Refitted to the cycle-count form (noise-free, largest size) the
variant misses it by about 1 % of the peak force, under the table's 2 % noise: that form no
longer tests a shape beyond the catalogue's.

State (5): ``[u, f_b, E, E_max, T]`` of the last call.
"""

import numpy as np
from numba import njit

from rrfrei.laws.effects import DiagnosisHints, EffectSpec, Variant, register_effect
from rrfrei.laws.effects._screens import force_sign, partial
from rrfrei.laws.registry import ParamSpec, Prior


@njit(cache=True, inline="always")
def apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """Scale by 1 / (1 + deg_rate E_max + deg_travel T) (contract in :mod:`rrfrei.laws.effects`)."""
    up = sc[so]
    fp = sc[so + 1]
    e_t = sc[so + 2] + 0.5 * (fp + fb) * (u - up)
    e_max = sc[so + 3]
    trav = sc[so + 4]
    st[so] = u
    st[so + 1] = fb
    st[so + 2] = e_t
    st[so + 3] = max(e_max, e_t)
    m = p[po + 2]
    if m == 1.0:
        st[so + 4] = trav + abs(u - up)
    elif (u > 0.0) == (up > 0.0):
        st[so + 4] = trav + abs(abs(u) ** m - abs(up) ** m)
    else:  # through u = 0: down to 0 and up again
        st[so + 4] = trav + abs(u) ** m + abs(up) ** m
    ct = p[po + 1]
    if ct == 0.0:
        gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0))
    else:
        gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0) + ct * trav)
    dg = dg * gi
    g = g * gi
    return g, dg, fa, ka


def _screen(ctx) -> float:
    """r sgn(F) against cumulative dissipated energy (the force fades)."""
    return partial(ctx.resid * force_sign(ctx), ctx.energy, [np.abs(ctx.disp)])


CYCLES = Variant(
    "cycles",
    "low-cycle fatigue: the amplitude exponent m of the travel fitted (Miner over Coffin-Manson)",
    lambda s: [{"deg_rate": 0.0, "deg_travel": 0.02 / s.disp**m, "deg_exp": m} for m in (0.3, 1.0)]
    + [{"deg_rate": 0.1 / s.energy, "deg_travel": 0.01 / s.disp**0.3, "deg_exp": 0.3}],
    lambda s: {"deg_rate": 1.0 / s.energy, "deg_travel": 0.05 / s.disp**0.5, "deg_exp": 0.5},
    lambda s: {"deg_rate": (0.0, 100.0 / s.energy), "deg_travel": (0.0, 5.0 / min(s.disp, 1.0)),
               "deg_exp": (0.1, 2.0)})

HINTS = DiagnosisHints(
    _screen,
    lambda s: [{"deg_rate": 0.1 / s.energy, "deg_travel": 0.0},
               {"deg_rate": 0.5 / s.energy, "deg_travel": 0.0},
               {"deg_rate": 0.0, "deg_travel": 0.02 / s.disp}],
    lambda s: {"deg_rate": 1.0 / s.energy, "deg_travel": 0.05 / s.disp},
    lambda s: {"deg_rate": (0.0, 100.0 / s.energy), "deg_travel": (0.0, 5.0 / s.disp)}, order=1,
    variants=(CYCLES,))


EFFECT = register_effect(EffectSpec(
    "degradation",
    (ParamSpec("deg_rate", "1/kN*m", 0.0, 1e9,
               "fade rate per unit cumulative work: g = 1 / (1 + deg_rate E)",
               Prior("halfnormal", 1.0)),
     ParamSpec("deg_travel", "1/m", 0.0, 1e9,
               "fade rate per unit cumulative travel of |u|^m: D = deg_rate E + deg_travel T_m "
               "[1/m^m]", Prior("halfnormal", 1.0), default=0.0),
     ParamSpec("deg_exp", "-", 0.05, 3.0,
               "amplitude exponent m of the travel measure T_m = int |d(|u|^m)| (1: travel, "
               "-> 0: cycle count)", Prior("uniform", 0.1, 2.0), default=1.0)),
    5, "strength and stiffness fade with cumulative dissipated energy and travel", (0.0, 0.0, 1.0),
    apply=apply, hints=HINTS, memory=True))
