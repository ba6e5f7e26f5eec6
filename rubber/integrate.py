"""Numba kernels of the uniaxial PRF model: springs, flow rate, and the TR-BDF2 chain integrator.

Units: stress MPa, time s.  Kinematics and flow rule as in ``docs/reference/prf_model.md``
(Bergstrom & Boyce 1998, JMPS 46:931; MSC Marc notation gamma_dot = C1 (lam_ch - 1 + xi)^C2 tau^C3).

Each viscous chain k has one scalar state u_k = ln(lambda_v,k) obeying (Mises form, to which the
Frobenius form reduces exactly by C1_mises = C1_frob (2/3)^((C3+1)/2))::

    du/dt = A (lam_ch(u) - 1 + xi)^C2 |Delta(lam e^-u)|^C3 sign(Delta),
    lam_ch(u) = sqrt((e^{2u} + 2 e^{-u}) / 3),   Delta(le) = 2 W1(I1(le)) (le^2 - 1/le).

Chains decouple given lambda(t); each is integrated by TR-BDF2 (Bank et al. 1985; gamma = 2 - sqrt 2,
L-stable, second order) with a local error estimate from the divided difference of the stage rates,
a safeguarded scalar Newton solve per stage (bisection inside the bracket [b, ln lam], rejection and
halving when 1 - c h df/du <= 0 or Newton fails) and steps that land on every sample of lambda(t)
(lambda is piecewise linear between samples, so every kink is a step boundary).

Robustness (issue 16.3): a stage whose root would leave |u| <= U_MAX (lambda_v = e^50, far beyond
any physical viscous stretch) is rejected like a failed Newton solve; when the bracket collapses on a
very stiff chain (|d(du/dt)/du| ~ 1e15 and more) the stage rate is taken from the implicit relation
f = (v - b) / (c h) rather than re-evaluated, so round-off in v is not amplified into the error
estimate; and a chain stops with "too many steps" after MAX_STEPS_BASE + MAX_STEPS_PER_SAMPLE m
attempted steps (m samples), so a runaway parameter set costs a fraction of a second, not minutes.

Status codes: 0 ok, 1 step size underflow, 2 too many steps, 3 non-finite state.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

GAMMA = 2.0 - math.sqrt(2.0)
# local truncation error constant of TR-BDF2: (-3 g^2 + 4 g - 2) / (12 (2 - g)) h^3 u'''
LTE = abs((-3.0 * GAMMA**2 + 4.0 * GAMMA - 2.0) / (12.0 * (2.0 - GAMMA)))
# Eight-Chain five-term series, W1 = nkT sum_i b_i (I1/N)^(i-1), b_i = i a_i
A_EC = (0.5, 1.0 / 20.0, 11.0 / 1050.0, 19.0 / 7000.0, 519.0 / 673750.0)
B1, B2, B3, B4, B5 = 0.5, 2.0 / 20.0, 33.0 / 1050.0, 76.0 / 7000.0, 2595.0 / 673750.0
LOG_CAP = 600.0  # cap of ln|rate| (guards tau^C3 overflow during trial iterates)
U_MAX = 50.0  # |ln lambda_v| beyond which a stage is rejected (exp(2 U_MAX) stays finite)
MAX_STEPS_BASE = 20_000  # attempted steps per chain: MAX_STEPS_BASE + MAX_STEPS_PER_SAMPLE * m
MAX_STEPS_PER_SAMPLE = 200

OK, UNDERFLOW, TOO_MANY, NONFINITE = 0, 1, 2, 3
STATUS_TEXT = {
    OK: "ok",
    UNDERFLOW: "step size underflow",
    TOO_MANY: "too many steps",
    NONFINITE: "non-finite state",
}


@njit(cache=True)
def ec_delta(le, nkt, n):
    """Eight-Chain spring: Delta = sigma11 - sigma22 (MPa) and dDelta/dle at elastic stretch le."""
    i1 = le * le + 2.0 / le
    x = i1 / n
    w1 = nkt * (B1 + x * (B2 + x * (B3 + x * (B4 + x * B5))))
    dw1 = nkt / n * (B2 + x * (2.0 * B3 + x * (3.0 * B4 + x * 4.0 * B5)))
    q = le * le - 1.0 / le
    d = 2.0 * w1 * q
    dd = 2.0 * dw1 * (2.0 * le - 2.0 / (le * le)) * q + 2.0 * w1 * (2.0 * le + 1.0 / (le * le))
    return d, dd


@njit(cache=True)
def ec_energy(le, nkt, n):
    """Eight-Chain stored energy density (MJ/m^3 = MPa) at elastic stretch le."""
    i1 = le * le + 2.0 / le
    w = 0.0
    p_i = 1.0
    p_3 = 1.0
    for i in range(5):
        p_i *= i1
        p_3 *= 3.0
        w += A_EC[i] / n**i * (p_i - p_3)
    return nkt * w


@njit(cache=True)
def yeoh_delta(lam, c10, c20, c30):
    """Yeoh spring: Delta = 2 W1 (lam^2 - 1/lam), W1 = C10 + 2 C20 x + 3 C30 x^2, x = I1 - 3."""
    x = lam * lam + 2.0 / lam - 3.0
    return 2.0 * (c10 + 2.0 * c20 * x + 3.0 * c30 * x * x) * (lam * lam - 1.0 / lam)


@njit(cache=True)
def yeoh_energy(lam, c10, c20, c30):
    x = lam * lam + 2.0 / lam - 3.0
    return c10 * x + c20 * x * x + c30 * x * x * x


@njit(cache=True)
def flow_rate(u, lam, nkt, n, a, c2, c3, xi):
    """Rate du/dt (1/s), its derivative d(du/dt)/du (1/s) and Delta (MPa) of one viscous chain."""
    lv = math.exp(u)
    le = lam / lv
    d, dd = ec_delta(le, nkt, n)
    if a == 0.0 or d == 0.0:
        return 0.0, 0.0, d
    lch2 = (lv * lv + 2.0 / lv) / 3.0
    if lch2 < 1.0:
        lch2 = 1.0
    lch = math.sqrt(lch2)
    base = lch - 1.0 + xi
    ad = abs(d)
    lg = math.log(a) + c2 * math.log(base) + c3 * math.log(ad)
    if lg > LOG_CAP:
        lg = LOG_CAP
    mag = math.exp(lg)
    f = mag if d > 0.0 else -mag
    dlch = (lv * lv - 1.0 / lv) / (3.0 * lch)
    dd_du = -le * dd
    dfdu = f * c2 * dlch / base + mag * c3 / ad * dd_du
    return f, dfdu, d


@njit(cache=True)
def _stage(b, c, h, lam, v0, nkt, n, a, c2, c3, xi):
    """Solve g(v) = v - b - c h f(v, lam) = 0 by Newton safeguarded with bisection.

    The root lies in [min(b, ln lam), max(b, ln lam)] (f has the sign of lam e^-v - 1), with
    g <= 0 at the lower end.  Returns (v, f, Delta, ok); ok is False when the iteration fails or
    when 1 - c h df/du <= 0 at the root (then the caller halves the step).
    """
    ueq = math.log(lam)
    if not (math.isfinite(b) and math.isfinite(ueq)):
        return b, 0.0, 0.0, False
    lo = max(min(b, ueq), -U_MAX)
    hi = min(max(b, ueq), U_MAX)
    if lo > hi:
        return b, 0.0, 0.0, False
    v = v0
    if v < lo or v > hi:
        v = 0.5 * (lo + hi)
    tol = 1e-13 * (1.0 + abs(b))
    for _ in range(100):
        f, df, d = flow_rate(v, lam, nkt, n, a, c2, c3, xi)
        g = v - b - c * h * f
        dg = 1.0 - c * h * df
        if abs(g) <= tol:
            return v, f, d, dg > 0.0
        if hi - lo <= tol:
            # collapsed bracket on a very stiff chain: the rate consistent with the stage equation;
            # a root pinned at the U_MAX clamp is no root (reject the step)
            pinned = (hi >= U_MAX and g < 0.0) or (lo <= -U_MAX and g > 0.0)
            return v, (v - b) / (c * h), d, dg > 0.0 and not pinned
        if g > 0.0:
            hi = v
        else:
            lo = v
        if dg > 0.0:
            vn = v - g / dg
            if vn <= lo or vn >= hi:
                vn = 0.5 * (lo + hi)
        else:
            vn = 0.5 * (lo + hi)
        v = vn
    return v, 0.0, 0.0, False


@njit(cache=True)
def integrate_chain(time, lam, nkt, n, a, c2, c3, xi, rtol, u_out, d_out, diss_out):
    """Integrate one viscous chain over the piecewise-linear stretch history.

    Parameters
    ----------
    time, lam : (m,) sample times (s, strictly increasing) and stretches; lam(t) is linear between.
    nkt, n : Eight-Chain modulus (MPa) and N = lambda_lock^2.
    a, c2, c3, xi : flow law in Mises form (A = C1 for Mises tau, C1 (2/3)^((C3+1)/2) for Frobenius).
    rtol : local error tolerance on u = ln lambda_v (dimensionless).
    u_out, d_out, diss_out : (m,) outputs: u, Delta (MPa) and cumulative dissipation (MJ/m^3).

    Returns (status, accepted steps, rejected steps).
    """
    m = time.shape[0]
    u = 0.0
    f0, _, d0 = flow_rate(u, lam[0], nkt, n, a, c2, c3, xi)
    u_out[0] = u
    d_out[0] = d0
    diss_out[0] = 0.0
    diss = 0.0
    h = 1e-3
    nacc = 0
    nrej = 0
    g = GAMMA
    cg = 0.5 * g
    cb = (1.0 - g) / (2.0 - g)
    w1 = 1.0 / (g * (2.0 - g))
    w0 = (1.0 - g) ** 2 / (g * (2.0 - g))
    max_steps = MAX_STEPS_BASE + MAX_STEPS_PER_SAMPLE * m
    for i in range(m - 1):
        t0 = time[i]
        t1 = time[i + 1]
        slope = (lam[i + 1] - lam[i]) / (t1 - t0)
        t = t0
        while t < t1:
            if nacc + nrej > max_steps:
                return TOO_MANY, nacc, nrej
            last = False
            hs = h
            if t + hs >= t1 - 1e-12 * (1.0 + abs(t1)):
                hs = t1 - t
                last = True
            lg = lam[i] + slope * (t + g * hs - t0)
            l1 = lam[i + 1] if last else lam[i] + slope * (t + hs - t0)
            b = u + cg * hs * f0
            ug, fg, dg_, okg = _stage(b, cg, hs, lg, u + g * hs * f0, nkt, n, a, c2, c3, xi)
            ok = okg
            if ok:
                b2 = w1 * ug - w0 * u
                u1, f1, d1, ok = _stage(b2, cb, hs, l1, ug + (1.0 - g) * hs * fg,
                                        nkt, n, a, c2, c3, xi)
            if not ok:
                h = 0.5 * hs
                nrej += 1
                if h < 1e-14:
                    return UNDERFLOW, nacc, nrej
                continue
            est = 2.0 * LTE * hs * abs((f1 - fg) / (1.0 - g) - (fg - f0) / g)
            err = est / rtol
            if err > 1.0:
                h = hs * max(0.2, 0.9 * err ** (-1.0 / 3.0))
                nrej += 1
                if h < 1e-14:
                    return UNDERFLOW, nacc, nrej
                continue
            if not math.isfinite(u1):
                return NONFINITE, nacc, nrej
            diss += 0.5 * (d0 + dg_) * (ug - u) + 0.5 * (dg_ + d1) * (u1 - ug)
            u = u1
            f0 = f1
            d0 = d1
            t = t1 if last else t + hs
            nacc += 1
            fac = 5.0 if err == 0.0 else min(5.0, 0.9 * err ** (-1.0 / 3.0))
            hn = hs * max(0.2, fac)
            if not last or hn > h:
                h = hn
        u_out[i + 1] = u
        d_out[i + 1] = d0
        diss_out[i + 1] = diss
    return OK, nacc, nrej


@njit(cache=True)
def simulate_kernel(time, lam, eq, chains, rtol, u, dch, diss):
    """All chains of a PRF model over one stretch history.

    eq : (3,) Yeoh C10, C20, C30 (MPa).  chains : (k, 6) rows nkt, N, A (Mises), C2, C3, xi.
    u, diss : (k, m) outputs; dch : (k + 1, m) Delta of the equilibrium chain (row 0) and chains.
    Returns (status, accepted steps, rejected steps).
    """
    m = time.shape[0]
    for j in range(m):
        dch[0, j] = yeoh_delta(lam[j], eq[0], eq[1], eq[2])
    tot_a = 0
    tot_r = 0
    for k in range(chains.shape[0]):
        st, na, nr = integrate_chain(time, lam, chains[k, 0], chains[k, 1], chains[k, 2], chains[k, 3],
                                     chains[k, 4], chains[k, 5], rtol, u[k], dch[k + 1], diss[k])
        tot_a += na
        tot_r += nr
        if st != OK:
            return st, tot_a, tot_r
    return OK, tot_a, tot_r


@njit(cache=True)
def nominal_stress(time, lam, eq, chains, rtol, out):
    """Nominal stress P = sum(Delta)/lam (MPa) into ``out``; the fast path of the fit objective."""
    m = time.shape[0]
    k = chains.shape[0]
    u = np.empty((k, m))
    dch = np.empty((k + 1, m))
    diss = np.empty((k, m))
    st, na, nr = simulate_kernel(time, lam, eq, chains, rtol, u, dch, diss)
    for j in range(m):
        s = 0.0
        for r in range(k + 1):
            s += dch[r, j]
        out[j] = s / lam[j]
    return st
