"""Augmentations ("effects") that wrap any base law's step kernel.

An augmented law ``base+effect[+effect...]`` has the base law's parameters followed by each
effect's parameters, and the base state followed by each effect's state.  Its dispatch code
(:data:`rrfrei.laws.registry.CODE_LEN`) lists the effect ids with their parameter and state
offsets.  The effects are the catalogue of unmodelled phenomena of the gap diagnosis (issue 7);
their metadata for screening and fitting lives in :mod:`rrfrei.gap.catalogue`.

Composition (independent of the order in which effects are named)
-----------------------------------------------------------------
With ``f_b, k_b`` the base law's force and tangent at the displacement it sees::

    F = g(u, history) f_b + f_a(u, v)          (scaling effects g, additive effects f_a)
    K = g k_b + f_b dg/du + df_a/du

``g`` is the product of the scaling effects (degradation, mullins, asymmetry) and ``f_a`` the sum
of the additive ones (rollover, rate).  ``slip`` puts a rigid-plastic slider in series with the
whole of that: the inner law sees ``u - u_s``.

Catalogue (units kN, m, s; each effect is the base law exactly at its neutral parameters)
-----------------------------------------------------------------------------------------
``degradation``  ``g = 1 / (1 + deg_rate E)`` with ``E`` the largest cumulative work of the base
    force so far, ``E = max_t int f_b du`` [kN m] (trapezoid, lagged one step so the tangent stays
    ``g k_b``).  Strength and stiffness fade together, as in energy-based damage of elastomers
    (Park & Ang 1985 use dissipated energy as the damage index).  Neutral: ``deg_rate = 0``.
``mullins``  scragging: below the largest |u| reached so far, ``u_max``, the response is softer,
    ``g = 1 - m (1 - |u| / u_max)``; virgin loading beyond ``u_max`` is unsoftened (Mullins 1969;
    Dorfmann & Ogden 2004 pseudo-elasticity in its simplest form).  Neutral: ``m = 0``.
``rollover``  amplitude-dependent tangent at large displacement: ``f_a = k_r sgn(u) (|u| - u_r)_+``
    (``k_r < 0``: rollover softening of unbonded FREIs; ``k_r > 0``: stiffening at full rollover or
    large strain; Toopchi-Nezhad et al. 2008).  Elastic (path independent).  Neutral: ``k_r = 0``.
``rate``  a viscous force ``f_a = c sgn(v) |v|^a`` (a = 1 linear viscous; a < 1 as in rubber and
    fluid dampers, Constantinou & Symans 1993).  Dissipative for c >= 0.  Neutral: ``c = 0``.
``asymmetry``  ``g = 1 + a sgn(f_b)``: the response in the + direction is ``(1 + a) / (1 - a)``
    times the one in the - direction (e.g. an eccentric vertical load or a rotated specimen).
    Neutral: ``a = 0``.
``slip``  sliding of an unbonded bearing on its supports: a rigid-plastic slider of capacity
    ``F_s = mu N`` [kN] in series; while ``|F| < F_s`` it sticks, else ``u_s`` moves so that
    ``|F| = F_s`` (solved by safeguarded Newton on the inner law, then bisection).  Dissipative.
    Neutral: ``slip_force`` at its upper bound (never reached).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from rrfrei.laws.dispatch import base_step
from rrfrei.laws.registry import CODE_LEN, MAX_EFFECTS, LawSpec, ParamSpec, Prior

__all__ = ["EffectSpec", "EFFECTS", "compose", "augmented_step", "SLIP_NEVER"]


@dataclass(frozen=True)
class EffectSpec:
    """An effect: its kernel id, parameters, state size and a one-line physical meaning.

    ``neutral`` holds the parameter values at which the augmented law is the base law exactly.
    """

    name: str
    effect_id: int
    params: tuple[ParamSpec, ...]
    state_size: int
    description: str
    neutral: tuple[float, ...] = ()


DEGRADATION, MULLINS, ROLLOVER, RATE, ASYMMETRY, SLIP = 1, 2, 3, 4, 5, 6
SLIP_NEVER = 1e12
"""``slip_force`` [kN] at which the slider never slides (its neutral value and upper bound)."""

EFFECTS: dict[str, EffectSpec] = {
    "degradation": EffectSpec(
        "degradation", DEGRADATION,
        (ParamSpec("deg_rate", "1/kN*m", 0.0, 1e9,
                   "fade rate per unit cumulative work: g = 1 / (1 + deg_rate E)",
                   Prior("halfnormal", 1.0)),),
        4, "strength and stiffness fade with cumulative dissipated energy", (0.0,)),
    "mullins": EffectSpec(
        "mullins", MULLINS,
        (ParamSpec("mullins", "-", 0.0, 0.95,
                   "softening at zero displacement of reloading below the largest past |u|",
                   Prior("uniform", 0.0, 0.9)),),
        1, "scragging: softer reloading below the previous maximum deformation", (0.0,)),
    "rollover": EffectSpec(
        "rollover", ROLLOVER,
        (ParamSpec("roll_k", "kN/m", -1e9, 1e9,
                   "tangent stiffness change beyond the onset (< 0 rollover softening)",
                   Prior("normal", 0.0, 1.0)),
         ParamSpec("roll_onset", "m", 0.0, 1e3, "displacement at which the tangent changes",
                   Prior("halfnormal", 1.0))),
        0, "amplitude-dependent tangent stiffness at large displacement", (0.0, 0.0)),
    "rate": EffectSpec(
        "rate", RATE,
        (ParamSpec("rate_c", "kN*s/m", 0.0, 1e9, "viscous coefficient of c sgn(v)|v|^a",
                   Prior("halfnormal", 1e3)),
         ParamSpec("rate_exp", "-", 0.1, 2.0, "velocity exponent a", Prior("uniform", 0.2, 1.5),
                   default=1.0)),
        0, "a force that depends on velocity", (0.0, 1.0)),
    "asymmetry": EffectSpec(
        "asymmetry", ASYMMETRY,
        (ParamSpec("asym", "-", -0.9, 0.9, "relative excess of the + over the - response",
                   Prior("uniform", -0.5, 0.5)),),
        0, "different response in the + and - directions", (0.0,)),
    "slip": EffectSpec(
        "slip", SLIP,
        (ParamSpec("slip_force", "kN", 0.0, SLIP_NEVER, "friction capacity of the supports mu N",
                   Prior("loguniform", 1e-2, 1e3)),),
        1, "sliding of an unbonded bearing once shear exceeds the friction capacity",
        (SLIP_NEVER,)),
}


def compose(base: LawSpec, effect_names: list[str]) -> LawSpec:
    """Compose ``base`` with the named effects into a new :class:`LawSpec`."""
    if base.effects:
        raise ValueError(f"law {base.name!r} is already augmented")
    if len(effect_names) > MAX_EFFECTS:
        raise ValueError(f"at most {MAX_EFFECTS} effects can be combined, got {len(effect_names)}")
    if len(set(effect_names)) != len(effect_names):
        raise ValueError(f"effects repeat in {effect_names}")
    params = list(base.params)
    state = base.state_size
    code = np.zeros(CODE_LEN, dtype=np.int64)
    code[0] = base.kernel_id
    code[1] = len(base.params)
    code[2] = base.state_size
    code[3] = len(effect_names)
    init = [np.asarray(base.initial_state)]
    for i, name in enumerate(effect_names):
        if name not in EFFECTS:
            raise ValueError(
                f"unknown effect {name!r}; available effects: {', '.join(EFFECTS) or '(none)'}"
            )
        eff = EFFECTS[name]
        code[4 + 3 * i] = eff.effect_id
        code[5 + 3 * i] = len(params)
        code[6 + 3 * i] = state
        params.extend(eff.params)
        state += eff.state_size
        init.append(np.zeros(eff.state_size))
    base_check = base.check
    nb = len(base.params)

    def _check(p: np.ndarray, _c=base_check, _nb=nb) -> None:
        if _c is not None:
            _c(p[:_nb])

    return LawSpec(
        name=base.name + "".join("+" + n for n in effect_names),
        kernel_id=base.kernel_id,
        params=tuple(params),
        state_size=state,
        description=base.description + " Augmented with " + ", ".join(effect_names) + ".",
        opensees_element="",
        uses_velocity=True,
        check=_check,
        effects=tuple(effect_names),
        code=code,
        initial_state=np.concatenate(init),
    )


@njit(cache=True)
def _inner(code, p, sc, u, v, dt, st):
    """Base law with every effect except ``slip`` (see the module docstring)."""
    nb = code[1]
    ns = code[2]
    ne = code[3]
    fb, kb, status = base_step(code[0], p[:nb], sc[:ns], u, v, dt, st[:ns])
    if status != 0:
        return fb, kb, status
    g = 1.0
    dg = 0.0
    fa = 0.0
    ka = 0.0
    for i in range(ne):
        eid = code[4 + 3 * i]
        po = code[5 + 3 * i]
        so = code[6 + 3 * i]
        if eid == DEGRADATION:
            up = sc[so]
            fp = sc[so + 1]
            e_t = sc[so + 2] + 0.5 * (fp + fb) * (u - up)
            e_max = sc[so + 3]
            st[so] = u
            st[so + 1] = fb
            st[so + 2] = e_t
            st[so + 3] = max(e_max, e_t)
            gi = 1.0 / (1.0 + p[po] * max(e_max, 0.0))
            dg = dg * gi
            g = g * gi
        elif eid == MULLINS:
            um = sc[so]
            a = abs(u)
            st[so] = max(um, a)
            if um > 0.0 and a < um:
                m = p[po]
                gi = 1.0 - m * (1.0 - a / um)
                dgi = m / um if u > 0.0 else (-m / um if u < 0.0 else 0.0)
                dg = dg * gi + g * dgi
                g = g * gi
        elif eid == ASYMMETRY:
            s = 1.0 if fb > 0.0 else (-1.0 if fb < 0.0 else 0.0)
            gi = 1.0 + p[po] * s
            dg = dg * gi
            g = g * gi
        elif eid == ROLLOVER:
            ex = abs(u) - p[po + 1]
            if ex > 0.0:
                fa += p[po] * ex * (1.0 if u > 0.0 else -1.0)
                ka += p[po]
        elif eid == RATE:
            c = p[po]
            a = p[po + 1]
            av = abs(v)
            if av > 0.0:
                fa += c * (av**a) * (1.0 if v > 0.0 else -1.0)
                ka += c * a * av ** (a - 1.0) / dt
            elif a == 1.0:
                ka += c / dt
    return g * fb + fa, g * kb + fb * dg + ka, 0


@njit(cache=True)
def _inner_fresh(code, p, sc, x, v, dt, st, so):
    """``_inner`` from the committed state: the slider search evaluates the inner law at several
    trial points, and a base law that keeps a "sticky" trial variable (OpenSees plasticity keeps
    the trial u_p in the elastic branch) must not carry one trial into the next."""
    us = st[so]
    st[:] = sc
    st[so] = us
    return _inner(code, p, sc, x, v, dt, st)


@njit(cache=True)
def augmented_step(code, p, sc, u, v, dt, st):
    """Step of an augmented law: (force [kN], tangent [kN/m], status); contract of the registry."""
    ne = code[3]
    k = -1
    for i in range(ne):
        if code[4 + 3 * i] == SLIP:
            k = i
    if k < 0:
        return _inner(code, p, sc, u, v, dt, st)
    fs = p[code[5 + 3 * k]]
    so = code[6 + 3 * k]
    us = sc[so]
    st[so] = us
    x = u - us
    f, kt, status = _inner(code, p, sc, x, v, dt, st)
    if status != 0 or abs(f) <= fs:
        return f, kt, status
    # sliding: find the inner displacement x with |F(x)| = fs between x (|F| > fs) and a point
    # back towards the committed inner displacement where |F| <= fs
    s = 1.0 if f > 0.0 else -1.0
    target = s * fs
    tol = 1e-12 * max(fs, 1.0) + 1e-9 * fs
    hi = x  # s * (F - target) > 0 here
    lo = x
    step = max(abs(u - us), 1e-9)
    found = False
    # safeguarded Newton first (one inner call per iteration)
    xn = x
    fn = f
    kn = kt
    for _ in range(30):
        if abs(fn - target) <= tol:
            found = True
            break
        if s * (fn - target) > 0.0:
            hi = xn
        if kn > 0.0:
            xt = xn - (fn - target) / kn
        else:
            break
        if not np.isfinite(xt):
            break
        xn = xt
        fn, kn, status = _inner_fresh(code, p, sc, xn, v, dt, st, so)
        if status != 0:
            return fn, kn, status
    if not found:
        # bracket then bisect
        lo = hi - s * step
        for _ in range(80):
            fl, kl, status = _inner_fresh(code, p, sc, lo, v, dt, st, so)
            if status != 0:
                return fl, kl, status
            if s * (fl - target) <= 0.0:
                break
            step *= 2.0
            lo = hi - s * step
        else:
            return fl, kl, -2
        for _ in range(200):
            xn = 0.5 * (lo + hi)
            fn, kn, status = _inner_fresh(code, p, sc, xn, v, dt, st, so)
            if status != 0:
                return fn, kn, status
            if s * (fn - target) > 0.0:
                hi = xn
            else:
                lo = xn
            if abs(fn - target) <= tol or abs(hi - lo) <= 1e-15 * max(abs(hi), 1e-3):
                break
    st[so] = u - xn
    return target, 0.0, 0
