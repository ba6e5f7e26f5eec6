"""Fast solver of :mod:`rrfrei.laws.bouc_wen` for whole histories: the ``law_run`` slot of the
history loop (:mod:`rrfrei.laws._history`, ``LawSpec.fast_run`` / ``LawSpec.fast_setup``).

It takes the sub-steps of a history where its guard certifies that OpenSees' Newton iteration
converges to the same root, and leaves the others to the law's step (or its robust local
solve, which keeps every certified root as it is).  Integer eta (1, 2, 3) takes no fast step:
the law's step needs no ``pow`` there and is as fast.  The law (equation, state) is described
in :mod:`rrfrei.laws.bouc_wen`; f is its backward-Euler residual.

Per sub-step, with the trial z equal to z_C (always so in a history), the root of f is found by
Halley's method in the frame of an anchor z_A: f(w) = w + (z_A - z_C) - r + G (1 + x)^eta,
x = sgn(z_A) w / |z_A|, G = r (gamma + beta sgn(z_A du)) |z_A|^eta, where (1 + x)^(eta-1) is a
32-term Taylor polynomial (Estrin's scheme, truncation below 2^-55 relative for |x| <= x32, from
the tail bound |C(eta-1, 32)| |x|^32 / (1 - |x|)), |z_A|^eta and 1/|z_A| are carried from step
to step by second-order Taylor updates (restarted from ``pow`` every ``REFRESH`` steps), and the
start is one Halley step from the previous step's last evaluation point.  No ``pow`` is on the
critical path.  z_A = z_C; where the guard fails there, z_A = OpenSees' first Newton iterate
(one ``pow``).

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
Otherwise the history loop runs :func:`rrfrei.laws.bouc_wen.step` (the OpenSees iteration)
from the original trial state, so status and failure sample are OpenSees' own.  Forces agree
with ``bouc_wen.drive_exact`` (OpenSees' iteration at every step) to ~1e-15.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import DBL_EPSILON, bearing_constants, powabs, sgn

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
    k_init, qd, k0, k2, k3, mu = bearing_constants(p)
    eta = p[5]
    beta = p[6]
    gamma = p[7]
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


@njit(cache=True)
def fast_setup(p):
    """The ``law_run_setup`` slot: ``(c, lim)`` of :func:`fast_constants` for the law's eta,
    ``lim = (x16, x32, stop)``; x32 = 0 (no fast step) for integer eta."""
    c, x16, x32, stop = fast_constants(p[5])
    if p[5] == 1.0 or p[5] == 2.0 or p[5] == 3.0:
        x32 = 0.0  # integer eta: the law's step needs no pow and is as fast
    return c, np.array([x16, x32, stop])


@njit(cache=True, inline="always")
def fast_run(p, ctx, sc, st, disp, k, substeps, force, tangent):
    """The ``law_run`` slot (contract in :mod:`rrfrei.laws._history`): :func:`_fast_run` from the
    flat sub-step index ``k``, or -1 where the fast solver is off (integer eta): the loop then
    leaves every sub-step of the history to the step."""
    c, lim = ctx
    if lim[1] > 0.0:
        return _fast_run(p, c, lim, sc, st, disp, k, substeps, force, tangent)
    return -1
