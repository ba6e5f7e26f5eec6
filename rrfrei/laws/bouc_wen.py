"""ElastomericBearingBoucWen (OpenSees v3.7.1, ``ElastomericBearingBoucWen2d.cpp``).

Smooth Bouc-Wen hysteresis (Wen's form, A = 1) plus linear and nonlinear hardening::

    k0 = (1 - alpha1) k_init,  k2 = alpha1 k_init,  k3 = alpha2 k_init,  u_y = qd / k0
    dz/du = (1/u_y) [A - |z|^eta (gamma + beta sgn(z du))]
    F     = qd z + k2 u + k3 sgn(u) |u|^mu

Integration (update, l.455-504), one backward-Euler step over the whole increment
du = u - u_C, solved for z by scalar Newton from the current *trial* z (not z_C)::

    f(z)  = z - z_C - (du/u_y) [A - |z|^eta (gamma + beta sgn(z du))]
    f'(z) = 1 + (du/u_y) eta |z|^(eta-1) sgn(z) (gamma + beta sgn(z du))

with |z| replaced by DBL_EPSILON when z == 0, iterating while |f/f'| >= 1e-12 and
iter < 25.  Status -2 if the loop ends with iter >= 25 (so a solve that converges exactly on the
25th iteration also fails, as in OpenSees), -1 if |f'| <= DBL_EPSILON.  The tangent is the
continuous-model one, k_t = k0 [A - |z|^eta (gamma + beta sgn(z du))] + k2 + k3 mu |u|^(mu-1).
When du == 0 exactly nothing is recomputed: force and tangent are those of the previous call.

The result depends on the step size (implicit integration over each increment); see
``rrfrei.simulate_force(substeps=...)``.

Identifiability: the force is exactly invariant under (qd, beta, gamma) -> (c qd, c^eta beta,
c^eta gamma) for any c > 0 (z scales by 1/c, u_y by c, and the backward-Euler step with them), so
one cyclic test can never fix all three.  Calibration therefore holds ``beta`` at 0.5 (``hold``
in its ParamSpec) and samples gamma, which spans the loop shapes gamma/beta in (-1, 2]; give a
prior for ``beta`` to sample it anyway (and expect a ridge).

State (float64[5])::

    [0] u      trial (committed, in sc) shear displacement [m]
    [1] z      hysteretic variable [-]
    [2] q      shear force of the last update() call [kN]
    [3] dk     tangent of the last call minus the initial tangent k_init [kN/m]
               (stored as an offset so the virgin state, all zeros, is parameter-free)
    [4] |z|^(eta-1) at z = [1] (a cache; 0 = not cached)

Speed (same iterates as OpenSees, fewer ``pow`` calls): integer ``eta`` (1, 2, 3) is
specialised; otherwise |z|^(eta-1) is carried from call to call in the state and, once Newton
has nearly converged (relative change of |z| below 1e-6), updated by a second-order Taylor step
instead of a ``pow`` call; |z|^eta = |z| |z|^(eta-1).  The iterates agree with a plain port to
about 1e-16.

Fast solver (whole histories, :func:`drive`, non-integer eta).  Per sub-step, with the trial
z equal to z_C (always so in a history), the root of f is found by Halley's method in the frame
of an anchor z_A: f(w) = w + (z_A - z_C) - r + G (1 + x)^eta, x = sgn(z_A) w / |z_A|,
G = r (gamma + beta sgn(z_A du)) |z_A|^eta, where (1 + x)^(eta-1) is a 32-term Taylor polynomial
(Estrin's scheme, truncation below 2^-55 relative for |x| <= x32, from the tail bound
|C(eta-1, 32)| |x|^32 / (1 - |x|)), |z_A|^eta and 1/|z_A| are carried from step to step by
second-order Taylor updates (restarted from ``pow`` every ``REFRESH`` steps), and the start is
one Halley step from the previous step's last evaluation point.  No ``pow`` is on the critical
path.  z_A = z_C; where the guard fails there, z_A = OpenSees' first Newton iterate (one
``pow``).

Guard (why the fast root is OpenSees' root).  With eta0 = |f(z_A) / f'(z_A)|, the ball
B = [z_A - 2 eta0, z_A + 2 eta0] and L >= max |f''| over B, the fast result is used only if::

    2 eta0 <= |z_A| / 2                      (0 not in B: f is C^2 on B, the sign terms constant)
    h = L eta0 / |f'(z_A)| <= 1/4,   L = |G eta (eta-1)| |z_A|^-2 max_{|y|<=1/2} (1+y)^(eta-2)
    (|z_A - z_C| + 2 eta0 + |r| + 1.5^eta |G|) <= 32 |f'(z_A)|,  |z_A| + 2 eta0 <= 64,
    |f'(z_A)| >= 1e-8

(the max bounded by (1 - 2 eta0/|z_A|)^-2 for eta < 2 and 1.5^(eta-2) otherwise).  By
Kantorovich's theorem (Ortega & Rheinboldt, *Iterative Solution of Nonlinear Equations*,
12.6.2), h <= 1/2 makes Newton's iteration from z_A stay in the ball of radius
(1 - sqrt(1 - 2h)) eta0 / h <= 1.17 eta0 and converge to the root z* there with
|z_k - z*| <= 2^(1-k) (2h)^(2^k - 1) eta0; with h <= 1/4 and eta0 <= 16 the step falls
below 1e-12 by k = 7, far inside OpenSees' 25 iterations, and |f'| >= |f'(z_A)| / 2 on B, so
the |f'| <= DBL_EPSILON failure cannot occur.  The third line keeps rounding noise of the
computed Newton step below 1.2e-13 (16 DBL_EPSILON x the magnitude sum / (|f'(z_A)| / 2)) and
the ulp of z below 1.5e-14, both under the 1e-12 tolerance.  f' varies by at most half of
f'(z_A) on B, so f has exactly one root in B.  The fast result z_n is accepted only if it lies
in B and in the Taylor range, with a residual |f(z_n)| at rounding level (16 DBL_EPSILON x the
sum of the magnitudes of its terms): it is then that root, and OpenSees' iterate agrees with it
to rounding.  For the anchor at OpenSees' first iterate the same argument applies from
iteration 1 (our iterate differs from OpenSees' by rounding, absorbed by the margins).
Otherwise :func:`step` (the OpenSees iteration) runs from the original trial state, so status
and failure sample are OpenSees' own.  Forces agree with :func:`drive_exact` to ~1e-15.

Robust local solve (opt-in, ``local_solver="robust"``; a deviation from OpenSees).  OpenSees'
Newton fails (status -2) typically when an iterate lands near z = 0 with eta < 1, where
f' ~ |z|^(eta-1) is unbounded and the steps stall, or when large steps make it cycle.
A subtler failure: with eta < 1 an iterate near z = 0 has |f'| so large that the Newton step
falls below 1e-12 while f is O(1), and OpenSees reports convergence at a point that is no root
(e.g. z_C = 1e-308, du/u_y = -1, eta = 0.5, beta = 1, gamma = 0: OpenSees returns z ~ 3e-154,
the root is -0.382).  :func:`step_robust` runs :func:`step` unchanged and, only where it fails
(status -1 or -2) or its result is no root (f keeps its sign on z +- 1e-10 max(1, |z|),
:func:`_near_root`), solves the same equation f(z) = 0 from the committed state by
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
on y < 0, dy/drho < 0), so :func:`step_robust` restarts the step from z_C projected onto the
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
:func:`step_robust` keeps OpenSees' result wherever it converges, by design.
"""

from dataclasses import replace

import numpy as np
from numba import njit

from rrfrei.laws._util import commit, increment, powabs, sgn
from rrfrei.laws.plasticity import PARAMS as _PLASTICITY_PARAMS
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, elastomeric_bearing, register

A = 1.0
MAX_ITER = 25
TOL = 1e-12
DBL_EPSILON = 2.220446049250313e-16


TAYLOR_MAX = 1e-6
"""Largest relative change of |z| for which |z|^(eta-1) is updated by a 2nd-order Taylor step
instead of ``pow`` (relative error <= C(eta-1, 3) 1e-18, below 1e-15 for eta <= 10)."""


@njit(cache=True, inline="always")
def _pm1(za, eta):
    """|z|^(eta-1) for |z| = za > 0, with eta = 1, 2, 3 specialised."""
    if eta == 1.0:
        return 1.0
    if eta == 2.0:
        return za
    if eta == 3.0:
        return za * za
    return za ** (eta - 1.0)


@njit(cache=True, inline="always")
def _constants(p):
    """(k_init, qd, k0, k2, k3, mu, eta, beta, gamma) of a parameter row (module docstring)."""
    k_init = p[0]
    return (k_init, p[1], (1.0 - p[2]) * k_init, p[2] * k_init, p[3] * k_init, p[4], p[5], p[6],
            p[7])


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    """Bouc-Wen bearing shear force [kN], tangent [kN/m] and status (see the module docstring)."""
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    du = u - sc[0]
    st[0] = u
    if du == 0.0:  # OpenSees keeps q and k_t of the previous update() call
        return st[2], st[3] + k_init, 0
    uy = qd / k0
    r = du / uy
    zc = sc[1]
    z = st[1]
    special = eta == 1.0 or eta == 2.0 or eta == 3.0
    e1 = eta - 1.0
    e2 = 0.5 * (eta - 2.0)
    za = abs(z)
    if za == 0.0:
        za = DBL_EPSILON
    pm1 = st[4]  # |z|^(eta-1) cached by the previous call for this same z (0: not cached)
    if special or not pm1 > 0.0:
        pm1 = _pm1(za, eta)
    it = 0
    while True:
        tmp1 = gamma + beta * sgn(z * du)
        f = z - zc - r * (A - pm1 * za * tmp1)
        df = 1.0 + r * eta * pm1 * sgn(z) * tmp1
        if abs(df) <= DBL_EPSILON:
            st[1] = z
            st[4] = 0.0
            return st[2], st[3] + k_init, -1
        dz = f / df
        z -= dz
        it += 1
        za_new = abs(z)
        if za_new == 0.0:
            za_new = DBL_EPSILON
        if special:
            pm1 = _pm1(za_new, eta)
        else:
            rel = (za_new - za) / za
            if abs(rel) < TAYLOR_MAX:
                pm1 = pm1 * (1.0 + e1 * rel * (1.0 + e2 * rel))
            else:
                pm1 = za_new ** e1
        za = za_new
        if not (abs(dz) >= TOL and it < MAX_ITER):
            break
    st[1] = z
    st[4] = pm1
    if it >= MAX_ITER:
        return st[2], st[3] + k_init, -2
    pe = pm1 * abs(z)  # |z|^eta (0 at z == 0)
    dzdu = A - pe * (gamma + beta * sgn(z * du))
    q = qd * z + k2 * u
    kt = k0 * dzdu + k2
    if k3 != 0.0:
        q += k3 * sgn(u) * powabs(u, mu)
        kt += k3 * mu * powabs(u, mu - 1.0)
    st[2] = q
    st[3] = kt - k_init
    return q, kt, 0


def _check(p: np.ndarray) -> None:
    if p[2] >= 1.0:
        raise ValueError(f"law 'bouc_wen': alpha1 = {p[2]:g} must be < 1")
    if p[6] + p[7] <= 0.0:
        raise ValueError(
            f"law 'bouc_wen': beta + gamma = {p[6] + p[7]:g} must be > 0 (bounded hysteretic "
            "variable z)"
        )


def __getattr__(attr: str):
    """``drive_exact``: OpenSees' own iteration (:func:`step`) at every sub-step of a history,
    the reference the fast :func:`drive` is tested against: the generic history driver
    (:mod:`rrfrei.laws._history`) instantiated with :func:`step` (same contract as
    :func:`drive`)."""
    if attr == "drive_exact":
        from rrfrei.laws import specialise

        return specialise.instantiate(
            specialise.HISTORY, {"law_step": step, "law_step_robust": step_robust}, "bouc_wen"
        ).drive
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


# --------------------------------------------------------------------------------------------
# Fast solver for whole histories (see "Fast solver" in the module docstring)

NC = 32
"""Taylor coefficients stored per series (the 16-term polynomial, extended to 32 terms)."""

TAYLOR_TOL = 2.0**-55
"""Relative truncation bound of the Taylor polynomial of (1+x)^(eta-1) inside its range."""

REFRESH = 16
"""Every REFRESH-th fast step restarts the multiplicative updates of |z|^eta and 1/|z| from
``pow`` and a division (computed at the start of that step, so off the critical path)."""

HALLEY_STOP = 2e-6
"""Largest relative last Halley correction |dw|/|z_A| accepted as converged."""


@njit(cache=True)
def fast_constants(eta):
    """Taylor coefficients and limits of the fast solver for the exponent ``eta``.

    Returns ``(c, x16, x32, stop)``: ``c[0, k] = C(eta-1, k)`` (series of (1+x)^(eta-1)) and
    ``c[1, k] = eta (eta-1) C(eta-2, k)`` (series of the second derivative of (1+x)^eta),
    k < 32; ``x16`` / ``x32`` the largest |x| for which the 16- / 32-term polynomial of
    (1+x)^(eta-1) is within ``TAYLOR_TOL`` relative (``x32 = 0`` disables the fast solver); and
    ``stop`` the Halley stopping threshold on |dw| / |z_A|.
    """
    c = np.zeros((2, NC))
    e1 = eta - 1.0
    ck = 1.0
    c16 = 0.0
    for k in range(NC):
        c[0, k] = ck
        ck = ck * (e1 - k) / (k + 1)
        if k == 15:
            c16 = ck
    dk = eta * e1
    for k in range(NC):
        c[1, k] = dk
        dk = dk * (e1 - 1.0 - k) / (k + 1)
    if not (eta > 0.0 and eta <= 10.0):
        return c, 0.0, 0.0, 0.0
    # Beyond k = 16 the terms of the series of (1+x)^(eta-1) shrink by |e1 - k| / (k + 1) < 1,
    # so the tail is below |C(e1, N)| |x|^N / (1 - |x|); (1+x)^(eta-1) >= (1 - |x|)^|e1|.
    ex = abs(e1) + 1.0
    x16 = 0.25
    if abs(c16) * x16**16 > TAYLOR_TOL * (1.0 - x16) ** ex:
        x16 = (TAYLOR_TOL * 0.75**ex / abs(c16)) ** (1.0 / 16)
    x32 = 0.45
    if abs(ck) * x32**NC > TAYLOR_TOL * (1.0 - x32) ** ex:
        x32 = (TAYLOR_TOL * 0.55**ex / abs(ck)) ** (1.0 / NC)
    # |z|^eta at the converged iterate is updated from the last polynomial evaluation by a
    # second-order Taylor step dx: its error |(1+x)^(eta-3) eta (eta-1) (eta-2)| dx^3 / 6.
    e3 = abs(eta * e1 * (eta - 2.0))
    stop = HALLEY_STOP
    if e3 > 0.0:
        stop = min(stop, (6.0 * TAYLOR_TOL * 0.55**3 / e3) ** (1.0 / 3.0))
    return c, x16, x32, stop


@njit(inline="always", fastmath={"contract"})
def _estrin16(c, j, o, x, x2, x4, x8):
    """sum_k c[j, o + k] x^k, k < 16, by Estrin's scheme (dependency depth 4)."""
    q0 = (c[j, o] + c[j, o + 1] * x) + (c[j, o + 2] + c[j, o + 3] * x) * x2
    q1 = (c[j, o + 4] + c[j, o + 5] * x) + (c[j, o + 6] + c[j, o + 7] * x) * x2
    q2 = (c[j, o + 8] + c[j, o + 9] * x) + (c[j, o + 10] + c[j, o + 11] * x) * x2
    q3 = (c[j, o + 12] + c[j, o + 13] * x) + (c[j, o + 14] + c[j, o + 15] * x) * x2
    return (q0 + q1 * x4) + (q2 + q3 * x4) * x8


@njit(inline="always", fastmath={"contract"})
def _powers(c, x, ee):
    """((1+x)^eta, (1+x)^(eta-1), eta (eta-1) (1+x)^(eta-2)) for |x| <= x32.

    32-term Taylor polynomial of (1+x)^(eta-1) by Estrin's scheme (no branch: a cut-over to
    fewer terms costs more in mispredictions than it saves), accurate to ``TAYLOR_TOL``;
    (1+x)^eta = (1+x) (1+x)^(eta-1) and (1+x)^(eta-2) = (1+x)^(eta-1) / (1+x).
    """
    x2 = x * x
    x4 = x2 * x2
    x8 = x4 * x4
    p1 = _estrin16(c, 0, 0, x, x2, x4, x8) + _estrin16(c, 0, 16, x, x2, x4, x8) * (x8 * x8)
    return p1 + x * p1, p1, ee * p1 / (1.0 + x)


@njit(inline="always", fastmath={"contract"})
def _guard(ee, bmax, emax, r, cA, aA, G, iA, fA, dfA):
    """Kantorovich condition at the anchor z_A (module docstring, "Guard"), division-free.

    With eta0 = |fA / dfA|, R = 2 eta0, s = R / |z_A|: s <= 1/2; h = L eta0 / |dfA| <= 1/4
    with L = |G eta (eta-1)| |z_A|^-2 max (1 + y)^(eta-2) over |y| <= s, bounded by
    (1 - s)^-2 (eta < 2) or 1.5^(eta-2) = 1 / bmax (eta >= 2); the noise and size margins.
    """
    adf = abs(dfA)
    afa = abs(fA)
    lead = 4.0 * abs(G * ee) * iA * iA * afa
    if bmax > 0.0:
        okh = lead <= bmax * adf * adf
    else:
        m = adf - 2.0 * afa * iA
        okh = lead <= m * m
    return (4.0 * afa * iA <= adf and okh
            and (abs(cA) + abs(r) + emax * abs(G)) * adf + 2.0 * afa <= 32.0 * adf * adf
            and aA * adf + 2.0 * afa <= 64.0 * adf
            and adf >= 1e-8)


@njit(inline="always", fastmath={"contract"})
def _halley(c, stop, eta, ee, cr, G, s, iA, w, x, Q, P1, d2Q):
    """Halley's method on f(w) = w + cr + G (1 + s w iA)^eta, from w with x = s w iA and
    (Q, P1, d2Q) = :func:`_powers` at x.

    Returns ``(converged, w, x, Q, P1, d2Q, dw)``: (x, Q, P1, d2Q) of the last evaluation and
    dw the last correction (converged: |dw| iA <= stop).
    """
    GsiA = G * s * iA * eta
    GiA2 = G * iA * iA
    for _ in range(4):
        f = (w + cr) + G * Q
        df = 1.0 + GsiA * P1
        d2f = GiA2 * d2Q
        dd = f * df / (df * df - 0.5 * f * d2f)
        w -= dd
        if abs(dd) * iA <= stop:
            return True, w, x, Q, P1, d2Q, dd
        x = w * s * iA
        Q, P1, d2Q = _powers(c, x, ee)
    return False, w, x, Q, P1, d2Q, 0.0


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _fast_run(p, c, lim, sc, st, disp, k, substeps, force, tangent):
    """Fast sub-steps from flat sub-step index ``k`` (sample k // substeps) on.

    Returns the flat index of the first sub-step it leaves to :func:`step` (the total count
    when the history is done), with ``sc`` and ``st`` holding the last fast sub-step,
    committed.
    """
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    iuy = k0 / qd
    x32 = lim[1]
    stop = lim[2]
    ee = eta * (eta - 1.0)
    bmax = 1.5 ** (2.0 - eta) if eta >= 2.0 else 0.0
    emax = 1.5**eta
    n = disp.shape[0] * substeps
    z = sc[1]
    uc = sc[0]
    if z == 0.0 or st[1] != z:
        return k
    k_first = k
    q_last = 0.0
    dk_last = 0.0
    s = sgn(z)
    # frame of the committed z: inv ~ 1/|z|, pe ~ |z|^eta (refreshed every 16 steps)
    inv = 1.0 / abs(z)
    pe = st[4] * abs(z) if st[4] > 0.0 else abs(z) ** eta
    # probe point z_k (the last evaluation point of the previous step; here z itself):
    # kP = |z_k|^eta, kP1 = s eta |z_k|^(eta-1), kP2 = eta (eta-1) |z_k|^(eta-2), ki = 1/|z_k|
    kP = pe
    kP1 = s * eta * pe * inv
    kP2 = ee * pe * inv * inv
    ki = inv
    nref = 0
    pw = pe
    iw = inv
    while k < n:
        if substeps == 1:
            i = k
            u = disp[i]
            last = True
        else:
            i = k // substeps
            j = k - i * substeps
            last = j == substeps - 1
            if last:
                u = disp[i]
            else:
                u_prev = disp[i - 1] if i > 0 else 0.0
                u = u_prev + (disp[i] - u_prev) / substeps * (j + 1)
        du = u - uc
        if du == 0.0:
            break
        if nref == REFRESH - 1:  # exact |z|^eta and 1/|z|, used from the end of this step on
            pw = abs(z) ** eta
            iw = 1.0 / abs(z)
        sd = 1.0 if du > 0.0 else -1.0
        r = du * iuy
        t = gamma + beta * (s * sd)
        rt = r * t
        # start: one Halley step from the probe point with its exact derivatives (independent
        # of the last correction of the previous step, so off the critical path)
        F0 = rt * kP - r
        D0 = 1.0 + rt * kP1
        v0 = -F0 * D0 / (D0 * D0 - 0.5 * F0 * (rt * kP2))
        x0 = s * v0 * ki
        Q, P1, d2Q = _powers(c, x0, ee)
        # frame z_A = z (the trial z = z_C of OpenSees' iteration)
        fs = s
        fi = inv
        fp = pe
        G = rt * pe
        cA = 0.0
        fA = G - r
        dfA = 1.0 + G * eta * s * inv
        if _guard(ee, bmax, emax, r, cA, abs(z), G, inv, fA, dfA):
            conv, w, x, Q, P1, d2Q, dd = _halley(c, stop, eta, ee, -r, G, s, inv,
                                                 x0 * (s * abs(z)), x0, Q, P1, d2Q)
        else:
            # frame z_A = OpenSees' first Newton iterate from z_C (one pow)
            if not abs(dfA) > 1e-8:
                break
            dz0 = fA / dfA
            zA = z - dz0
            if not (abs(dz0) >= 1e-10 and zA != 0.0):
                break
            fs = sgn(zA)
            aA = abs(zA)
            fi = 1.0 / aA
            fp = aA**eta
            t = gamma + beta * (fs * sd)
            G = r * t * fp
            cA = zA - z
            fA = (cA - r) + G
            dfA = 1.0 + G * eta * fs * fi
            if not _guard(ee, bmax, emax, r, cA, aA, G, fi, fA, dfA):
                break
            w0 = -fA * dfA / (dfA * dfA - 0.5 * fA * (G * ee * fi * fi))
            x0 = fs * w0 * fi
            Q, P1, d2Q = _powers(c, x0, ee)
            conv, w, x, Q, P1, d2Q, dd = _halley(c, stop, eta, ee, cA - r, G, fs, fi,
                                                 w0, x0, Q, P1, d2Q)
        if not conv:
            break
        zA = z + cA  # exact (cA = zA - z)
        zn = zA + w
        # acceptance: inside the Kantorovich ball (|we| <= R = 2 |fA / dfA|) and the Taylor
        # range, residual at noise level
        we = zn - zA
        xe = fs * we * fi
        dxe = xe - x
        Qe = Q + dxe * (eta * P1 + 0.5 * dxe * d2Q)
        fn = ((we + cA) - r) + G * Qe
        noise = abs(cA) + abs(we) + abs(r) + abs(G * Qe) + abs(zn) * abs(dfA)
        if not (abs(xe) <= x32 and abs(we * dfA) <= 2.0 * abs(fA)
                and abs(fn) <= 16.0 * DBL_EPSILON * noise):
            break
        if nref == REFRESH - 1 and cA == 0.0:
            fp = pw
            fi = iw
        dx = -fs * fi * dd
        pn = fp * (Q + dx * (eta * P1 + 0.5 * dx * d2Q))  # |z_n|^eta
        q = qd * zn + k2 * u
        kt = k0 * (1.0 - pn * t) + k2
        if k3 != 0.0:
            if mu == 2.0:
                q += k3 * u * abs(u)
                kt += 2.0 * k3 * abs(u)
            else:
                q += k3 * sgn(u) * powabs(u, mu)
                kt += k3 * mu * powabs(u, mu - 1.0)
        if not (np.isfinite(q) and np.isfinite(kt)):
            break
        if last:
            force[i] = q
            tangent[i] = kt
        k += 1
        q_last = q
        dk_last = kt - k_init
        # next frame: z_n, with the last evaluation point as the probe
        rho = 1.0 / (1.0 + x)
        kP = fp * Q
        kP1 = fs * eta * fp * fi * P1
        kP2 = fp * fi * fi * d2Q
        ki = fi * rho
        z = zn
        uc = u
        s = fs
        nref = 0 if nref == REFRESH - 1 else nref + 1
        y = rho * dx
        inv = ki * (1.0 + y * (y - 1.0))  # 1 / |z_n| = fi / (1 + x + dx)
        pe = pn
    if k > k_first:
        st[0] = uc
        st[1] = z
        st[2] = q_last
        st[3] = dk_last
        st[4] = 0.0
        for m in range(5):
            sc[m] = st[m]
    return k


@njit(cache=True, error_model="numpy")
def drive(p, sc, st, disp, time, use_time, substeps, force, tangent):
    """Whole-history driver of this law (contract of :func:`rrfrei.laws._history.drive`).

    Runs the fast solver (module docstring, "Fast solver") where its guard certifies that
    OpenSees' Newton iteration converges to the same root, and :func:`step` elsewhere; integer
    eta always goes through :func:`step`.  Forces agree with :func:`drive_exact` (OpenSees'
    iteration at every step) to rounding (~1e-15), and status and failure sample are the same.
    """
    c, x16, x32, stop = fast_constants(p[5])
    if p[5] == 1.0 or p[5] == 2.0 or p[5] == 3.0:
        x32 = 0.0  # integer eta: step() needs no pow and is as fast
    lim = np.array([x16, x32, stop])
    n = disp.shape[0] * substeps
    k = 0
    while True:
        if x32 > 0.0:
            k = _fast_run(p, c, lim, sc, st, disp, k, substeps, force, tangent)
        if k >= n:
            return 0, -1
        i = k // substeps
        j = k - i * substeps
        u_prev = disp[i - 1] if i > 0 else 0.0
        t_prev = (time[i - 1] if i > 0 else time[0]) if use_time else 0.0
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
        f, kt, status = step(p, sc, u, v, dt, st)
        if status != 0:
            return status, i
        if not (np.isfinite(f) and np.isfinite(kt)):
            return -3, i
        commit(sc, st)
        if j == substeps - 1:
            force[i] = f
            tangent[i] = kt
        k += 1


# --------------------------------------------------------------------------------------------
# Robust local solve (opt-in; see "Robust local solve" in the module docstring)

STATUS_ROBUST = 1
"""Status of :func:`step_robust` when OpenSees' iteration failed and :func:`solve_bracketed`
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
"""Certificate of an OpenSees result in :func:`step_robust`: f changes sign within
NEAR_ROOT max(1, |z|) of it (a converged Newton iterate is within ~1e-12 of its root)."""


@njit(cache=True, inline="always")
def _near_root(zc, r, z, eta, beta, gamma):
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


@njit(cache=True, error_model="numpy")
def step_robust(p, sc, u, v, dt, st):
    """:func:`step`, and where OpenSees' iteration fails (status -1 or -2) or stops away from a
    root (:func:`_near_root`), the root of the same equation by :func:`solve_robust` from
    the committed z (status :data:`STATUS_ROBUST`): bracketed, and from a committed state beyond
    the bound where no root exists, from that state projected onto the bound.

    Force and tangent as in :func:`step` (same expressions) at the bracketed root; the |z|^(eta-1)
    cache is cleared.  Status -1 / -2 only for a non-finite state or step.
    """
    q, kt, status = step(p, sc, u, v, dt, st)
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    du = u - sc[0]
    uy = qd / k0
    if status == 0:
        if du == 0.0 or _near_root(sc[1], du / uy, st[1], eta, beta, gamma):
            return q, kt, 0
    elif status != -1 and status != -2:
        return q, kt, status
    z, st2 = solve_robust(sc[1], du / uy, eta, beta, gamma)
    if st2 != 0:
        return q, kt, status
    st[1] = z
    st[4] = 0.0
    pe = abs(z) ** eta
    dzdu = A - pe * (gamma + beta * sgn(z * du))
    q = qd * z + k2 * u
    kt = k0 * dzdu + k2
    if k3 != 0.0:
        q += k3 * sgn(u) * powabs(u, mu)
        kt += k3 * mu * powabs(u, mu - 1.0)
    st[2] = q
    st[3] = kt - k_init
    return q, kt, STATUS_ROBUST


@njit(cache=True, error_model="numpy")
def drive_robust(p, sc, st, disp, time, use_time, substeps, force, tangent, deviated):
    """:func:`drive` with :func:`step_robust` in place of :func:`step`.

    ``deviated`` (int64, n) receives 1 at every sample where the robust solve acted in one of
    its sub-steps (OpenSees' iteration failed there), 0 elsewhere; elsewhere the forces are
    those of :func:`drive`, bit for bit.  Same return contract.
    """
    for i in range(deviated.shape[0]):
        deviated[i] = 0
    c, x16, x32, stop = fast_constants(p[5])
    if p[5] == 1.0 or p[5] == 2.0 or p[5] == 3.0:
        x32 = 0.0
    lim = np.array([x16, x32, stop])
    n = disp.shape[0] * substeps
    k = 0
    while True:
        if x32 > 0.0:
            k = _fast_run(p, c, lim, sc, st, disp, k, substeps, force, tangent)
        if k >= n:
            return 0, -1
        i = k // substeps
        j = k - i * substeps
        u_prev = disp[i - 1] if i > 0 else 0.0
        t_prev = (time[i - 1] if i > 0 else time[0]) if use_time else 0.0
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
        f, kt, status = step_robust(p, sc, u, v, dt, st)
        if status == STATUS_ROBUST:
            deviated[i] = 1
        elif status != 0:
            return status, i
        if not (np.isfinite(f) and np.isfinite(kt)):
            return -3, i
        commit(sc, st)
        if j == substeps - 1:
            force[i] = f
            tangent[i] = kt
        k += 1


SPEC = register(
    LawSpec(
        name="bouc_wen",
        step=step,
        step_robust=step_robust,
        drive=drive,
        drive_robust=drive_robust,
        params=(_PLASTICITY_PARAMS[0], replace(_PLASTICITY_PARAMS[1], lower=1e-9))
        + _PLASTICITY_PARAMS[2:]
        + (
            ParamSpec("eta", "-", 0.1, 10.0, "Bouc-Wen exponent", Prior("uniform", 0.5, 5.0)),
            ParamSpec("beta", "-", 0.0, 5.0, "coefficient of the sign-dependent term",
                      Prior("uniform", 0.0, 2.0), hold=0.5),
            ParamSpec("gamma", "-", -5.0, 5.0, "coefficient of the constant term",
                      Prior("uniform", -1.0, 1.0)),
        ),
        state_size=5,
        description="OpenSees ElastomericBearingBoucWen: smooth Bouc-Wen hysteresis (A = 1).",
        opensees=elastomeric_bearing("elastomericBearingBoucWen"),
        check=_check,
    )
)
