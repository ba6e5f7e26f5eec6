"""Robust local solve of the Bouc-Wen backward-Euler equation: the root of
f(z) = z - z_C - r [1 - |z|^eta (gamma + beta sgn(z r))] on a bracket, used by the robust
steps of :mod:`rrfrei.laws.bouc_wen` and :mod:`rrfrei.laws.elastomeric_x`
(``local_solver="robust"``).

Why (opt-in: a deviation from OpenSees).  OpenSees'
Newton fails (status -2) typically when an iterate lands near z = 0 with eta < 1, where
f' ~ |z|^(eta-1) is unbounded and the steps stall, or when large steps make it cycle.
A subtler failure: with eta < 1 an iterate near z = 0 has |f'| so large that the Newton step
falls below 1e-12 while f is O(1), and OpenSees reports convergence at a point that is no root
(e.g. z_C = 1e-308, du/u_y = -1, eta = 0.5, beta = 1, gamma = 0: OpenSees returns z ~ 3e-154,
the root is -0.382).  ``bouc_wen.step_robust`` runs ``bouc_wen.step`` unchanged and, only where it fails
(status -1 or -2) or its result is no root (f keeps its sign on z +- 1e-10 max(1, |z|),
:func:`near_root`), solves the same equation f(z) = 0 from the committed state by
:func:`solve_bracketed` (returning status :data:`STATUS_ROBUST` = 1), so wherever OpenSees'
iteration converges to a root the result is OpenSees' own, bit for bit.  The fast solver's
steps are certified roots and are kept as they are.  Bracket: f is odd under (z, z_C, r) -> (-z, -z_C, -r),
so with s = sgn(du), y = s z, y_C = s z_C and rho = |r| > 0::

    f(y) = y - y_C - rho [1 - |y|^eta (gamma + beta sgn(y))],   z_max = (beta + gamma)^(-1/eta)

(beta >= 0 and beta + gamma > 0 are enforced by the parameter bounds).  (a) y_C >= -rho:
f(0) = -y_C - rho <= 0, f is strictly increasing on y >= 0 (both terms are), and
f(y_C + rho) = rho (beta + gamma) (y_C + rho)^eta >= 0, f(z_max) = z_max - y_C >= 0 when
y_C <= z_max: the root is the unique one in [0, min(z_max, y_C + rho)].  (b) y_C < -rho:
f(0) = -y_C - rho > 0 and f(y_C) = rho [(gamma - beta) |y_C|^eta - 1] <= 0 whenever
|y_C| <= z_max (gamma - beta <= gamma + beta): a root lies in [y_C, 0).  So from any committed
|z_C| <= z_max (the virgin z_C = 0 included) a root exists, it is found, and |z| <= z_max again;
the bound is invariant.  A committed state beyond the bound ((gamma - beta) |y_C|^eta > 1, only
reachable through a spurious root that OpenSees' own iteration converged to) has f(y_C) > 0
and f > 0 on y >= 0; on y < 0, f has one turning point at |y| = (rho (gamma - beta) eta)^(-1/(eta-1)),
a minimum for eta > 1 (a root exists iff f <= 0 there, bracketed by it and y_C) and a maximum
for eta < 1 (f -> -oo: the bracket is found by doubling downward from y_C); otherwise status
-2 (no root).  There the Bouc-Wen flow itself diverges (beyond |y| = (gamma - beta)^(-1/eta)
on y < 0, dy/drho < 0), so ``bouc_wen.step_robust`` restarts the step from z_C projected onto the
bound, |z_C| = z_max (:func:`solve_robust`, the return mapping to the saturation surface), where
case (b) always has a root: the robust path completes every history with finite input.  On the bracket
[a, b] with f(a) <= 0 <= f(b), safeguarded Newton (Numerical Recipes' ``rtsafe``): the
Newton step is taken only if it stays strictly inside the bracket and at least halves the step
before last, otherwise bisection; every evaluation shrinks the bracket.  At y = 0 (eta < 1: f'
infinite; eta >= 1: one-sided) the step is always bisection.  It stops when the step is below
2 DBL_EPSILON |y| or the bracket is two adjacent doubles, so the root is at rounding level
(OpenSees stops at |dz| < 1e-12: the two agree to ~1e-12 or better where both find the root
of the bracket).  f can have further, spurious roots on the side opposite to du when
gamma > beta (|du|/u_y >> 1), and OpenSees' iteration sometimes converges to one (|z| > z_max);
``bouc_wen.step_robust`` keeps OpenSees' result wherever it converges, by design.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import DBL_EPSILON, powabs, sgn

A = 1.0

STATUS_ROBUST = 1
"""Status of ``bouc_wen.step_robust`` when OpenSees' iteration failed and :func:`solve_bracketed`
found the root instead (converged, but a deviation from OpenSees)."""

ROBUST_MAX_ITER = 5000
"""Cap on safeguarded-Newton iterations (bisection alone reaches adjacent doubles in < 2100)."""


@njit(cache=True, inline="always")
def _residual(y, yc, rho, eta, beta, gamma):
    """(f(y), f'(y)) in the frame y = sgn(du) z (module docstring, "Robust local solve");
    f' = NaN at y = 0 (infinite for eta < 1, one-sided otherwise)."""
    a = abs(y)
    if y > 0.0:
        t = gamma + beta
    elif y < 0.0:
        t = gamma - beta
    else:
        return -yc - rho, np.nan
    pe = a**eta
    f = (y - yc) - rho * (1.0 - pe * t)
    df = 1.0 + rho * eta * (pe / a) * t * (1.0 if y > 0.0 else -1.0)
    return f, df


@njit(cache=True, error_model="numpy")
def solve_bracketed(zc, r, eta, beta, gamma):
    """Root z of the backward-Euler equation f(z) = z - z_C - r [1 - |z|^eta (gamma + beta
    sgn(z r))] on a bracket that contains it (module docstring, "Robust local solve").

    Parameters
    ----------
    zc : committed hysteretic variable z_C [-].
    r : du / u_y [-], nonzero.
    eta, beta, gamma : Bouc-Wen exponent and coefficients (beta >= 0, beta + gamma > 0).

    Returns
    -------
    (z, status, iterations) : status 0 (root found to rounding) or -2 (f has no root, which
    needs a committed state beyond the bound, or the iteration cap).
    """
    s = 1.0 if r > 0.0 else -1.0
    yc = s * zc
    rho = abs(r)
    if not (rho > 0.0 and np.isfinite(rho) and np.isfinite(yc)):
        return zc, -2, 0
    # a: an end with f(a) <= 0, b: an end with f(b) >= 0 (either order)
    if yc >= -rho:  # case (a): root in [0, min(z_max, y_C + rho)], f increasing there
        zmax = (beta + gamma) ** (-1.0 / eta)
        a = 0.0
        b = yc + rho
        if yc <= zmax and zmax < b:
            b = zmax
    else:
        c = gamma - beta
        if rho * (c * abs(yc) ** eta - 1.0) <= 0.0:  # case (b): root in [y_C, 0)
            a = yc
            b = 0.0
        else:
            # committed state beyond the bound (c > 0, c |y_C|^eta > 1): f > 0 on y >= 0; on
            # y < 0, f = y - y_C - rho + rho c |y|^eta has one turning point at |y| = a*,
            # a* = (rho c eta)^(-1/(eta-1)): a minimum for eta > 1, a maximum for eta < 1
            b = yc
            ystar = -np.inf  # the turning point -a* if a minimum (eta > 1)
            found = False
            if eta > 1.0:
                ystar = -((rho * c * eta) ** (-1.0 / (eta - 1.0)))
                if ystar > yc:  # f decreases from y_C to its minimum at y*
                    if (ystar - yc) - rho + rho * c * abs(ystar) ** eta > 0.0:
                        return zc, -2, 0  # f > 0 everywhere: no root
                    a = ystar
                    found = True
            if not found:  # f increasing on [y*, y_C]: a root below y_C, search downward
                t = max(rho, abs(yc))
                while True:
                    a = yc - t
                    floor = a <= ystar
                    if floor:
                        a = ystar
                    fa = (a - yc) - rho + rho * c * abs(a) ** eta
                    if not (np.isfinite(a) and np.isfinite(fa)):
                        return zc, -2, 0
                    if fa <= 0.0:
                        break
                    if floor:
                        return zc, -2, 0  # f > 0 everywhere: no root
                    b = a
                    t *= 2.0
    if a == b:
        return s * a, 0, 0
    y = yc if min(a, b) < yc < max(a, b) else a + 0.5 * (b - a)
    dx_old = abs(b - a)
    dx = dx_old
    for it in range(1, ROBUST_MAX_ITER + 1):
        f, df = _residual(y, yc, rho, eta, beta, gamma)
        if f == 0.0:
            return s * y, 0, it
        if f < 0.0:
            a = y
        else:
            b = y
        lo = min(a, b)
        hi = max(a, b)
        newton = False
        yn = y
        if np.isfinite(df) and df != 0.0:
            yn = y - f / df
            newton = lo < yn < hi and abs(2.0 * f) <= abs(dx_old * df)
        dx_old = dx
        if not newton:
            yn = lo + 0.5 * (hi - lo)
            if yn == lo or yn == hi:  # adjacent doubles: the bracket cannot shrink further
                return s * y, 0, it  # y, just evaluated, is one of the two
        dx = abs(yn - y)
        y = yn
        if dx <= 2.0 * DBL_EPSILON * abs(y) or hi - lo <= 2.0 * DBL_EPSILON * max(abs(lo), abs(hi)):
            return s * y, 0, it
    return s * y, -2, ROBUST_MAX_ITER


@njit(cache=True, error_model="numpy")
def solve_robust(zc, r, eta, beta, gamma):
    """:func:`solve_bracketed`, and where f has no root from a committed state beyond the bound
    |z_C| > z_max = (beta + gamma)^(-1/eta), the root from z_C projected onto the bound.

    Such a state is reachable only through a spurious root that OpenSees' own iteration
    converged to (module docstring, "Robust local solve"); from it the step equation can have
    no root at all (the Bouc-Wen flow beyond |z| = (gamma - beta)^(-1/eta) on the side opposite
    to du diverges), so no solver can continue it.  Projecting z_C onto the bound, the return
    mapping to the saturation surface, restores an admissible state, from which a root always
    exists (case (b) of the bracket).  Returns ``(z, status)``: status 0, or -2 if even that
    fails (non-finite input).
    """
    z, status, _ = solve_bracketed(zc, r, eta, beta, gamma)
    if status == 0:
        return z, 0
    zmax = (beta + gamma) ** (-1.0 / eta)
    if abs(zc) > zmax:
        z, status, _ = solve_bracketed(zmax if zc > 0.0 else -zmax, r, eta, beta, gamma)
    return z, status


NEAR_ROOT = 1e-10
"""Certificate of an OpenSees result in ``bouc_wen.step_robust``: f changes sign within
NEAR_ROOT max(1, |z|) of it (a converged Newton iterate is within ~1e-12 of its root)."""


@njit(cache=True, inline="always")
def near_root(zc, r, z, eta, beta, gamma):
    """True if f (module docstring) changes sign on [z - d, z + d], d = NEAR_ROOT max(1, |z|).

    Catches OpenSees' false convergence: with eta < 1 an iterate near 0 has |f'| ~ |z|^(eta-1)
    so large that the step |f / f'| falls below 1e-12 while f itself is O(1).
    """
    d = NEAR_ROOT * max(1.0, abs(z))
    w = z - d
    f1 = w - zc - r * (A - powabs(w, eta) * (gamma + beta * sgn(w * r)))
    w = z + d
    f2 = w - zc - r * (A - powabs(w, eta) * (gamma + beta * sgn(w * r)))
    return f1 * f2 <= 0.0
