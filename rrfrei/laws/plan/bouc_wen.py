"""ElastomericBearingBoucWen in plan (OpenSees v3.7.1, ``ElastomericBearingBoucWen3d.cpp``).

Coupled bidirectional Bouc-Wen hysteresis (A = 1; for eta = 2 the model of Park, Wen & Ang 1986,
Earthquake Eng. Struct. Dyn. 14, 543-557) with a vector hysteretic variable z = (z_x, z_y), plus
linear and nonlinear hardening::

    k0 = (1 - alpha1) k_init,  k2 = alpha1 k_init,  k3 = alpha2 k_init,  u_y = qd / k0
    u_y dz = [A I - |z|^(eta-2) (gamma + beta sgn(z . du)) z z^T] du
    F_i    = qd z_i + k2 u_i + k3 sgn(u_i) |u_i|^mu        (hardening per component)

u [m], F [kN], stiffnesses [kN/m].  Along one axis (z_y = du_y = 0) it is the unidirectional
law :mod:`rrfrei.laws.bouc_wen`; under a push in any direction |z| saturates at the same
(beta + gamma)^(-1/eta) as along an axis, so the hysteretic force is bounded by a circle, where
two independent springs would reach that bound per axis (sqrt(2) times it on a diagonal).

Integration (``update``, v3.7.1 l.497-583): one backward-Euler step over the whole increment
du = u - u_C, solved for z by Newton's method on the two components, from the current *trial* z::

    r1 = z . du,  s = gamma + beta sgn(r1),  t3 = |z|^(eta-2) r1 s,  t4 = |z|^(eta-4) s
    f_i(z) = z_i - z_C,i - (1/u_y) (A du_i - z_i t3)
    Df     = the 2x2 Jacobian of OpenSees (l.523-530, term by term, sign terms held constant)
    z <- z - Df^-1 f

with |z| = DBL_EPSILON where z = 0 (l.510-544), while |dz| >= tol = 1e-12 and iter < maxIter = 25
(the element's defaults, l.149-150).  OpenSees solves Df dz = f with ``Vector::operator/(Matrix)``
(LAPACK ``dgesv``); here by Cramer's rule, dz = adj(Df) f / det(Df), one division where LU with
partial pivoting has three in a row (for the diagonally dominant Jacobians of a converging step
the two agree to a few ulp), and by the ``dgesv`` emulation :func:`_solve2` where det(Df) is 0
exactly (a singular U leaves dz = f, as ``dgesv`` leaves the right-hand side unsolved).  Status
-1 if |Df_xx| or |Df_yy| <= DBL_EPSILON (OpenSees' "zero Jacobian", l.533-538), -2 if the loop
ends with iter >= 25 (a solve converging exactly on the 25th iteration also fails, as in
OpenSees, l.547-552).  When |du| <= DBL_EPSILON (Euclidean norm) nothing is recomputed: force
and tangent are those of the previous call (OpenSees l.500).

Two calls per step.  OpenSees' static displacement-controlled analysis (``tests/opensees_plan.py``,
the benchmark) calls ``update()`` twice per step: in ``LoadControl::newStep`` and after the first
Newton correction (zero on the imposed shear DOFs).  The second call starts the local Newton
again from the trial z the first one reached, so it can move z by rounding (a last iteration
from there) or fail where the first converged (e.g. with eta = 0.375 and z driven from 0 to
2633 by one step, a spurious root, below, the second call oscillates between two doubles 3 ulp
apart with |dz| = 1.5e-12 > tol until iter = 25).  The plan history driver therefore makes both
calls per step (this law's carrier :func:`carry_update`, equal bit for bit to the array
carrier :mod:`rrfrei.laws.plan._arrays` with ``PlanLawSpec.static_calls = 2``, which calls this
step twice); the plan building calls it once per Newton iteration, as OpenSees' transient analysis
does.  The second call is skipped when it provably returns the same bits: the first call's last
iteration left z bit for bit unchanged (state entry 10, ``settled_index``), so the second would
repeat that iteration exactly (about 60% of the steps of the benchmark's figure-eight).
Likewise the powers of the first iteration of a call (|z|^(eta-2), |z|^(eta-4), z_x^3, z_y^3)
are taken from the state when the last iteration of the previous call started from that very z
(entries [11:19], keyed bit for bit on z and eta): true after a settled call and after nearly
every second call, so one local iteration's powers per step are saved.

Arithmetic: OpenSees' iteration, iterate for iterate, to rounding.  The residual and the Jacobian
are OpenSees' expressions term by term (with 1/u_y multiplied where OpenSees divides by u_y);
the exact rewrites of its tests: |dz| >= tol as |dz|^2 >= 1e-24 and |du| > DBL_EPSILON as
|du|^2 > 4.930380657631325e-32, the thresholds between which the correctly rounded square root
changes side.  What differs by rounding: the solve (above), z_i^3 as z_i^2 z_i, and the powers.
``pow`` (the C library's, :func:`_bind_pow`) is called for |z|^(eta-2) and |z|^(eta-4) at an
anchor, the first iterate of a call whose powers are not cached; at the later iterates of the
call, where |z|^2 has moved by a relative x with |x| <= 1e-6 (``TAYLOR_MAX``) from the anchor's,
both are the anchor's times (1 + x)^h to second order, h = (eta-2)/2 or (eta-4)/2 (|z|^p =
(|z|^2)^(p/2)): truncation below |C(h, 3)| |x|^3 <= 4e-18 relative for eta in [0.1, 10], under
the ulp, and always from the anchor, so the error does not accumulate; farther away, ``pow``
again and a new anchor.  Near convergence (the iterates where this applies) every step is tiny,
so the iterates are OpenSees' to rounding.  Evidence: on the benchmark's 5,000-step
figure-eight the forces are within 3.4e-16 of the peak of openseespy's; random circular,
figure-eight and step paths agree within 1e-9 (the issue's bound, tested), up to a step onto a
spurious root (a root of the backward-Euler equation beyond the bound |z| <= (beta +
gamma)^(-1/eta), reached by steps |du| >> u_y with gamma > beta), where which root the iteration
lands on, and whether its second call settles, is decided by the last bit, in OpenSees as here.
Following OpenSees operation for operation (every ``pow`` called, the ``dgesv`` sequence) would
give openseespy's bits on that path at a markedly higher cost per step (``docs/plan_laws.md``;
the measurements in ``CHANGELOG.md``).

Speed: the powers above; ``pow`` is glibc's ``__ieee754_pow`` itself, without the wrappers
(:func:`_bind_pow`, same values).  The arithmetic is written once, on scalars (:func:`update`:
state in, state out, inlined by LLVM); :func:`step` loads its arrays, calls it and writes each
output once (with an array touched in several branches Numba kept an atomic incref/decref of
four array arguments per call), and the carrier (:func:`carry_update`, ``PlanLawSpec.carrier``)
carries the state through the history loop in local scalars, runs OpenSees' two calls of a step as
one local iteration restarted (each call with its own anchor, as two :func:`step` calls), and
computes force and tangent once per step.

Tangent (l.555-582): with t5 = |z_prev|^(eta-2) s of the last iteration's start point,
du_x/du_y ratios (0 where du_x du_y = 0)::

    dz/du (times u_y) = [[A - z_x t5 (z_x + z_y du_y/du_x), (A - z_x^2 t5) du_x/du_y - z_x z_y t5],
                         [(A - z_y^2 t5) du_y/du_x - z_x z_y t5, A - z_y t5 (z_y + z_x du_x/du_y)]]

each entry clipped to [-1, 1] as OpenSees does (a diagonal entry beyond 1 in magnitude becomes
+1); K = k0 dz/du + k2 I + diag(k3 mu |u_i|^(mu-1)).  The result depends on the step size
(implicit integration over each increment); see ``rrfrei.simulate_force(substeps=...)``.

Along one axis the iteration is the unidirectional law's (Df is diagonal, dgesv divides), but
OpenSees' 3-D residual is written (1/u_y)(A du - z |z|^(eta-2) (z du) s) where the 2-D one is
(du/u_y)(A - |z|^eta s): the two round differently, so a path along one axis reproduces
:mod:`rrfrei.laws.bouc_wen` to rounding, not bit for bit (same status and failure sample; forces
within 1e-14 of the peak force, worst 6.2e-15 over 3000 random histories); this module follows
the 3-D element, whose openseespy results it reproduces.  A further difference: the 1-D element
skips the update only for du == 0 exactly, the 3-D one for |du| <= DBL_EPSILON.

State (float64[19])::

    [0:2] u   trial (committed, in sc) shear displacement [m]
    [2:4] z   hysteretic variable [-]
    [4:6] q   shear forces of the last call [kN]
    [6:10] K - (k0 + k2) I, tangent of the last call (row-major) as an offset from the initial
           tangent A k0 + k2 [kN/m], so the virgin state (all zeros) is parameter-free
    [10]  settled: 1.0 when a repeated call with the same u and committed state would return
          the same bits (the last local iteration left z unchanged, or |du| <= DBL_EPSILON)
    [11:19] powers cache: 1.0 when valid, z_x, z_y, eta, then |z|^(eta-2), |z|^(eta-4), z_x^3,
          z_y^3 at that z (the start point of the last local iteration), as that iteration
          computed them (``pow`` or the Taylor update from its anchor)
"""

import ctypes
import ctypes.util
import math

import llvmlite.binding as ll
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from rrfrei.laws._util import powabs, sgn, store_plan, store_plan_state
from rrfrei.laws.plan.registry import Carrier, PlanLawSpec, register

A = 1.0
MAX_ITER = 25
TOL = 1e-12
DBL_EPSILON = 2.220446049250313e-16
DZ2_TOL = 1e-24
"""|dz|^2 threshold: for every double s >= 0 (and NaN), ``s >= DZ2_TOL`` if and only if
``sqrt(s) >= TOL`` (sqrt is correctly rounded and monotone; 1e-24 is the smallest such double,
checked in tests/test_plan_laws_opensees.py): OpenSees' test without the square root."""
DU2_MIN = 4.930380657631325e-32
"""|du|^2 threshold: ``s > DU2_MIN`` if and only if ``sqrt(s) > DBL_EPSILON`` (the largest
double whose square root is <= DBL_EPSILON, one ulp above DBL_EPSILON^2; same check)."""
SETTLED = 10
"""State entry: 1.0 when a repeated call with the same u and committed state returns the same
trial state, force and tangent bit for bit (``PlanLawSpec.settled_index``)."""
POW = 11
"""State entries [11:19]: 1.0 (valid), z_x, z_y, eta and |z|^(eta-2), |z|^(eta-4), z_x^3, z_y^3
computed there (the start point of the last local iteration of the last call)."""
TAYLOR_MAX = 1e-6
"""Largest relative change of |z|^2 since the last ``pow`` for which |z|^(eta-2) and
|z|^(eta-4) are Taylor-updated (module docstring)."""
SFMIN = 2.2250738585072014e-308
"""LAPACK ``dlamch('S')``: below it ``dgetrf2`` divides by the pivot instead of scaling by its
reciprocal."""


POW_SYMBOL = "rrfrei_libm_pow"
"""The JIT symbol :func:`_pow` calls (bound at import by :func:`_bind_pow`)."""


def _bind_pow() -> str:
    """Bind ``POW_SYMBOL`` to the C library's power function and say which entry it is.

    glibc: ``__pow_finite@GLIBC_2.15``, the IFUNC of ``__ieee754_pow`` itself (resolved to its
    FMA or SSE2 build), which both ``pow`` entries call: the SVID-compatible wrapper
    ``pow@GLIBC_2.2.5`` that Numba's ``x ** y`` reaches (through a trampoline of its own) and
    ``pow@@GLIBC_2.29``.  Their values are the same for every argument: a wrapper only sets
    errno, or calls ``__kernel_standard``, whose POSIX-mode results on overflow, underflow and
    invalid arguments are those ``__ieee754_pow`` already returns (checked over 10^6 random and
    special arguments, bit for bit).  Skipping the wrappers saves a trampoline and a wrapper
    call per power.  Elsewhere (no ``dlvsym``, or no such symbol): the C library's ``pow``."""
    name = ctypes.util.find_library("m")
    libm = ctypes.CDLL(name) if name else ctypes.CDLL(None)
    addr = None
    try:
        dlvsym = ctypes.CDLL(None).dlvsym
        dlvsym.restype = ctypes.c_void_p
        dlvsym.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_char_p]
        addr = dlvsym(libm._handle, b"__pow_finite", b"GLIBC_2.15")
    except AttributeError:  # not glibc
        addr = None
    entry = "__pow_finite@GLIBC_2.15"
    if not addr:
        addr = ctypes.cast(libm.pow, ctypes.c_void_p).value
        entry = "pow"
    ll.add_symbol(POW_SYMBOL, addr)
    return entry


POW_ENTRY = _bind_pow()
"""Which C library entry :func:`_pow` calls (:func:`_bind_pow`)."""


@intrinsic
def _pow(typingctx, x, y):
    """x^y as the C library's ``pow`` (``__ieee754_pow`` under glibc, without its wrapper:
    :func:`_bind_pow`); declared ``readnone nounwind`` as ``llvm.pow`` is."""
    sig = types.float64(types.float64, types.float64)

    def codegen(context, builder, signature, args):
        fn = builder.module.globals.get(POW_SYMBOL)
        if fn is None:
            fnty = ir.FunctionType(ir.DoubleType(), [ir.DoubleType(), ir.DoubleType()])
            fn = ir.Function(builder.module, fnty, POW_SYMBOL)
            fn.attributes.add("nounwind")
            fn.attributes.add("readnone")
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, inline="always")
def _solve2(a00, a01, a10, a11, b0, b1):
    """x = A^-1 b as reference LAPACK ``dgesv`` computes it for n = 2 (``dgetrf2``: pivot row
    by ``idamax``, L = a * (1/pivot); ``dgetrs``: row swap, unit-lower then upper ``dtrsm``,
    skipping zero entries).  A singular U (dgesv INFO > 0) returns b unchanged."""
    x0 = b0
    x1 = b1
    if abs(a10) > abs(a00):  # idamax: first index of the largest |entry|
        a00, a01, a10, a11 = a10, a11, a00, a01
        b0, b1 = b1, b0
    if a00 == 0.0:  # dgetrf2 INFO = 1: dgesv returns the right-hand side unsolved
        return x0, x1
    if abs(a00) >= SFMIN:
        l10 = a10 * (1.0 / a00)
    else:
        l10 = a10 / a00
    u11 = a11 + (-a01) * l10
    if u11 == 0.0:  # INFO = 2
        return x0, x1
    if b0 != 0.0:
        b1 = b1 - b0 * l10
    if b1 != 0.0:
        b1 = b1 / u11
        b0 = b0 - b1 * a01
    if b0 != 0.0:
        b0 = b0 / a00
    return b0, b1


@njit(cache=True, inline="always")
def _same(a, b):
    """a and b are the same double (sign of zero included; NaN is never the same)."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


@njit(cache=True, error_model="numpy", forceinline=True)
def _finish(k0, k2, k3, qd, mu, kini, u0, u1, z0, z1, tmp5, r12, r21):
    """Force and tangent after a converged call (OpenSees l.555-582, module docstring), with
    tmp5 = |z_s|^(eta-2) s of the last iteration's start point z_s: ``(q0, q1, e00, e01, e10,
    e11, k00, k01, k10, k11)``, the forces [kN], the tangent's offset from A k0 + k2 (``kini``)
    as stored in the state, and the tangent [kN/m]."""
    g00 = A - z0 * tmp5 * (z0 + z1 * r21)
    g01 = (A - z0 * z0 * tmp5) * r12 - z0 * z1 * tmp5
    g10 = (A - z1 * z1 * tmp5) * r21 - z0 * z1 * tmp5
    g11 = A - z1 * tmp5 * (z1 + z0 * r12)
    if abs(g00) > 1.0:
        g00 = 1.0
    if abs(g01) > 1.0:
        g01 = sgn(g01)
    if abs(g10) > 1.0:
        g10 = sgn(g10)
    if abs(g11) > 1.0:
        g11 = 1.0
    q0 = qd * z0 + k2 * u0
    q1 = qd * z1 + k2 * u1
    k00 = k0 * g00 + k2
    k11 = k0 * g11 + k2
    if k3 != 0.0:
        q0 += k3 * sgn(u0) * powabs(u0, mu)
        q1 += k3 * sgn(u1) * powabs(u1, mu)
        k00 += k3 * mu * powabs(u0, mu - 1.0)
        k11 += k3 * mu * powabs(u1, mu - 1.0)
    k01 = k0 * g01
    k10 = k0 * g10
    return q0, q1, k00 - kini, k01, k10, k11 - kini, k00, k01, k10, k11


@njit(cache=True, error_model="numpy", forceinline=True)
def update(k0, k2, k3, qd, mu, eta, beta, gamma, u0, u1, uc0, uc1, zc0, zc1,
           z0, z1, q0, q1, e00, e01, e10, e11, pv, pz0, pz1, peta, ppw2, ppw4, pc0, pc1,
           f0, f1, k00, k01, k10, k11, calls):
    """``calls`` (1 or 2) ``update()`` calls of the element on scalars: state in, state out
    (module docstring).

    ``calls = 2`` is OpenSees' static step, two calls with the same u from the same committed
    state: the second one, unless the first is settled, restarts the local iteration from the
    first call's trial z with its counter reset, i.e. continues the same loop (its powers are
    fresh: z moved), and the force and tangent are computed once, after it (the first call's
    are only needed where the second one fails, for the trial state).  The results are those
    of two calls of :func:`step`, bit for bit (``tests/test_plan_laws_opensees.py``).

    In: the stiffnesses k0 = (1 - alpha1) k_init, k2 = alpha1 k_init, k3 = alpha2 k_init
    [kN/m], qd [kN], mu, eta, beta, gamma; the trial displacement (u0, u1) [m]; the committed
    displacement (uc0, uc1) and z (zc0, zc1); the trial state entries [2:10] and [11:19] on entry
    (z, q, tangent offset e, powers cache); the forces and tangent of the previous call, returned
    unchanged on a failure (status < 0).

    Out: ``(status, settled, z0, z1, q0, q1, e00, e01, e10, e11, pv, pz0, pz1, peta, ppw2,
    ppw4, pc0, pc1, f0, f1, k00, k01, k10, k11)``: the status (0, -1, -2), the new trial state
    entries [10], [2:10], [11:19] (entries [0:2] are (u0, u1)), the forces [kN] and the tangent
    [kN/m] (row-major).  Written once for :func:`step` (arrays, one call: the plan building)
    and the carrier :func:`carry_update` (scalars carried through the history loop, two calls);
    ``forceinline``: LLVM inlines it into both (``calls`` a constant there), so the tuple costs
    nothing."""
    du0 = u0 - uc0
    du1 = u1 - uc1
    kini = A * k0 + k2
    status = 0
    settled = 1.0
    if not (du0 * du0 + du1 * du1 > DU2_MIN):  # sqrt(du . du) > DBL_EPSILON, exactly
        # OpenSees keeps q and K of the previous update() call (a repeated call does the same)
        f0 = q0
        f1 = q1
        k00 = e00 + kini
        k01 = e01
        k10 = e10
        k11 = e11 + kini
    else:
        uy = qd / k0
        iuy = 1.0 / uy
        em1 = eta - 1.0
        em2 = eta - 2.0
        em4 = eta - 4.0
        r12 = du0 / du1  # the tangent's ratios (used after the loop; divided here, off its path)
        r21 = du1 / du0
        if du0 * du1 == 0.0:
            r12 = 0.0
            r21 = 0.0
        it = 0
        call = 1
        fz0 = fz1 = fpw2 = ftmp2 = 0.0
        same = False
        tmp2 = 0.0
        pw2 = pw4 = c0 = c1 = 0.0
        s0 = s1 = 0.0
        # the four powers at the start point are a pure function of (z, eta): reused from the
        # state when the last iteration of the previous call started from this very z
        hit = pv == 1.0 and _same(z0, pz0) and _same(z1, pz1) and eta == peta
        # the anchor of the Taylor updates of the powers: 1 / |z|^2 and the powers where ``pow``
        # was last called in this call (none yet: x = n2 * 0 - 1 = -1 takes ``pow``)
        ian2 = 0.0
        apw2 = apw4 = 0.0
        h2 = 0.5 * em2  # |z|^(eta-2) = (|z|^2)^h2, |z|^(eta-4) = (|z|^2)^h4
        h2b = 0.5 * h2 * (h2 - 1.0)
        h4 = 0.5 * em4
        h4b = 0.5 * h4 * (h4 - 1.0)
        while True:
            a0 = z0 * z0
            a1 = z1 * z1
            if hit:
                pw2 = ppw2
                pw4 = ppw4
                c0 = pc0
                c1 = pc1
                hit = False
            else:
                n2 = a0 + a1
                x = n2 * ian2 - 1.0  # relative change of |z|^2 since the anchor (-1: none)
                if abs(x) <= TAYLOR_MAX:
                    # (1 + x)^h to second order: relative error <= |C(h, 3)| x^3 (module docstring)
                    pw2 = apw2 * (1.0 + x * (h2 + h2b * x))
                    pw4 = apw4 * (1.0 + x * (h4 + h4b * x))
                else:
                    znrm = math.sqrt(n2)  # Vector::Norm: sqrt(0 + z0^2 + z1^2), the same double
                    if znrm == 0.0:
                        znrm = DBL_EPSILON
                    pw2 = _pow(znrm, em2)
                    pw4 = _pow(znrm, em4)
                    # the new anchor: 1 / |z|^2 (|z| = 0: none, x stays -1)
                    ian2 = 1.0 / n2 if n2 > 0.0 else 0.0
                    apw2 = pw2
                    apw4 = pw4
                c0 = z0 * a0
                c1 = z1 * a1
            s0 = z0
            s1 = z1
            tmp1 = z0 * du0 + z1 * du1
            tmp2 = gamma + beta * sgn(tmp1)
            tmp3 = pw2 * tmp1 * tmp2
            r0 = (z0 - zc0) - iuy * (A * du0 - z0 * tmp3)
            r1 = (z1 - zc1) - iuy * (A * du1 - z1 * tmp3)
            tmp4 = pw4 * tmp2
            t = tmp4 * iuy
            d00 = 1.0 + t * (c1 * du1 + 2.0 * a1 * z0 * du0 + z1 * a0 * du1 * em1 + c0 * du0 * eta)
            d10 = z1 * t * (a1 * du0 + z0 * z1 * du1 * em2 + a0 * du0 * em1)
            d01 = z0 * t * (a0 * du1 + z0 * z1 * du0 * em2 + a1 * du1 * em1)
            d11 = 1.0 + t * (c0 * du0 + 2.0 * a0 * z1 * du1 + z0 * a1 * du0 * em1 + c1 * du1 * eta)
            if abs(d00) <= DBL_EPSILON or abs(d11) <= DBL_EPSILON:
                status = -1  # z of this iteration's start is kept, the powers cache unchanged
                break
            det = d00 * d11 - d01 * d10
            if det != 0.0:
                idet = 1.0 / det
                dz0 = (d11 * r0 - d01 * r1) * idet
                dz1 = (d00 * r1 - d10 * r0) * idet
            else:  # (d00, d11 > DBL_EPSILON: |d01 d10| = d00 d11) what dgesv leaves then
                dz0, dz1 = _solve2(d00, d01, d10, d11, r0, r1)
            n0 = z0 - dz0
            n1 = z1 - dz1
            same = _same(n0, z0) and _same(n1, z1)  # this iteration left z bit for bit as it was
            z0 = n0
            z1 = n1
            it += 1
            if not (dz0 * dz0 + dz1 * dz1 >= DZ2_TOL and it < MAX_ITER):  # |dz| >= tol, exactly
                # end of an update() call: the powers at its last iteration's start point (z
                # itself when settled)
                pv = 1.0
                pz0 = s0
                pz1 = s1
                peta = eta
                ppw2 = pw2
                ppw4 = pw4
                pc0 = c0
                pc1 = c1
                if it >= MAX_ITER:
                    status = -2
                    break
                if call == calls or same:
                    break
                # OpenSees' second update(): the same u and committed state, from this trial
                # z, i.e. the same iteration restarted (its first powers are fresh: z moved)
                call = 2
                it = 0
                ian2 = 0.0  # a call's anchor is its own (as a separate step() call)
                fz0 = z0
                fz1 = z1
                fpw2 = pw2
                ftmp2 = tmp2
        if status != 0 or not same:
            settled = 0.0
        if status == 0:
            q0, q1, e00, e01, e10, e11, k00, k01, k10, k11 = _finish(
                k0, k2, k3, qd, mu, kini, u0, u1, z0, z1, pw2 * tmp2, r12, r21)
            f0 = q0
            f1 = q1
        elif call == 2:
            # failed in the second call: the trial force and tangent are the first call's
            q0, q1, e00, e01, e10, e11, k00, k01, k10, k11 = _finish(
                k0, k2, k3, qd, mu, kini, u0, u1, fz0, fz1, fpw2 * ftmp2, r12, r21)
            f0 = q0
            f1 = q1
    return (status, settled, z0, z1, q0, q1, e00, e01, e10, e11, pv, pz0, pz1, peta, ppw2,
            ppw4, pc0, pc1, f0, f1, k00, k01, k10, k11)


@njit(cache=True, error_model="numpy", forceinline=True)
def step(p, sc, u, v, dt, st, f, k):
    """Plan Bouc-Wen step (module docstring): forces ``f`` [kN], tangent ``k`` [kN/m], trial
    state ``st``; status 0, -1 (zero Jacobian diagonal) or -2 (no convergence in 25).

    Load, :func:`update` on scalars, store (every output entry written once, at the end): an
    array touched in several branches made Numba keep an atomic incref and decref of four array
    arguments per call (its reference-count pruning could not pair them).  ``forceinline``: LLVM
    inlines it into its callers (the plan building), which saves the call of seven array
    arguments without compiling it again (Numba's ``inline="always"`` does the same at the IR
    level, at a longer compilation)."""
    k_init = p[0]
    u0 = u[0]
    u1 = u[1]
    (status, settled, z0, z1, q0, q1, e00, e01, e10, e11, pv, pz0, pz1, peta, ppw2, ppw4, pc0,
     pc1, f0, f1, k00, k01, k10, k11) = update(
        (1.0 - p[2]) * k_init, p[2] * k_init, p[3] * k_init, p[1], p[4], p[5], p[6], p[7],
        u0, u1, sc[0], sc[1], sc[2], sc[3], st[2], st[3], st[4], st[5], st[6], st[7], st[8],
        st[9], st[POW], st[POW + 1], st[POW + 2], st[POW + 3], st[POW + 4], st[POW + 5],
        st[POW + 6], st[POW + 7], f[0], f[1], k[0, 0], k[0, 1], k[1, 0], k[1, 1], 1)
    _store_state(st, u0, u1, z0, z1, q0, q1, e00, e01, e10, e11, settled, pv, pz0, pz1, peta,
                 ppw2, ppw4, pc0, pc1)
    store_plan(f, k, f0, f1, k00, k01, k10, k11)
    return status


@njit(cache=True, inline="always")
def _store_state(s, u0, u1, z0, z1, q0, q1, e00, e01, e10, e11, settled, pv, pz0, pz1, peta,
                 ppw2, ppw4, pc0, pc1):
    """Write the 19 state entries (module docstring) into ``s``."""
    store_plan_state(s, u0, u1, z0, z1, q0, q1, e00, e01, e10, e11)
    s[SETTLED] = settled
    s[POW] = pv
    s[POW + 1] = pz0
    s[POW + 2] = pz1
    s[POW + 3] = peta
    s[POW + 4] = ppw2
    s[POW + 5] = ppw4
    s[POW + 6] = pc0
    s[POW + 7] = pc1


# --- the carrier: the state in scalars through the history loop (PlanLawSpec.carrier) ------

@njit(cache=True, inline="always")
def carry_begin(p, sc, st):
    """``plan_begin`` of the history loop (:mod:`rrfrei.laws.plan._history`): the stiffnesses and
    coefficients of :func:`update`, and the state as 19 scalars (module docstring).

    The loop carries one state: the contract's "sc and st both the initial state on entry" is
    checked (ValueError otherwise), so the trial and committed state are one set of scalars at
    each step's start; committing is renaming them.  Where the state lives in arrays that may
    alias the outputs, LLVM must load and store all 19 entries around every call (step entry
    and exit, commit: about a tenth of a step)."""
    for a in range(sc.shape[0]):
        if not _same(sc[a], st[a]):
            raise ValueError("bouc_wen plan driver: sc and st must both hold the initial state "
                             "on entry (the trial state equal to the committed one)")
    k_init = p[0]
    ctx = ((1.0 - p[2]) * k_init, p[2] * k_init, p[3] * k_init, p[1], p[4], p[5], p[6], p[7])
    cs = (st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7], st[8], st[9], st[SETTLED],
          st[POW], st[POW + 1], st[POW + 2], st[POW + 3], st[POW + 4], st[POW + 5], st[POW + 6],
          st[POW + 7])
    return ctx, cs


@njit(cache=True, inline="always")
def carry_update(p, ctx, cs, u0, u1, v0, v1, dt):
    """``plan_update``: OpenSees' two ``update()`` calls of a static step from the committed
    state (the second skipped when the first is settled), :func:`update` with ``calls = 2``;
    velocity and time are not used (the law has no rate term)."""
    k0, k2, k3, qd, mu, eta, beta, gamma = ctx
    (uc0, uc1, zc0, zc1, qc0, qc1, ec00, ec01, ec10, ec11, sdc, pvc, pzc0, pzc1, petac, ppw2c,
     ppw4c, pc0c, pc1c) = cs
    (status, sd, z0, z1, q0, q1, e00, e01, e10, e11, pv, pz0, pz1, peta, ppw2, ppw4, pc0,
     pc1, f0, f1, k00, k01, k10, k11) = update(
        k0, k2, k3, qd, mu, eta, beta, gamma, u0, u1, uc0, uc1, zc0, zc1,
        zc0, zc1, qc0, qc1, ec00, ec01, ec10, ec11, pvc, pzc0, pzc1, petac, ppw2c,
        ppw4c, pc0c, pc1c, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2)
    ts = (u0, u1, z0, z1, q0, q1, e00, e01, e10, e11, sd, pv, pz0, pz1, peta, ppw2, ppw4, pc0,
          pc1)
    return status, ts, f0, f1, k00, k01, k10, k11


@njit(cache=True, inline="always")
def carry_commit(ctx, ts):
    """``plan_commit``: the trial scalars become the committed ones."""
    return ts


@njit(cache=True, inline="always")
def carry_end(sc, st, ctx, cs, ts):
    """``plan_end``: the committed and trial scalars written to ``sc`` and ``st``."""
    _store_tuple(sc, cs)
    _store_tuple(st, ts)


@njit(cache=True, inline="always")
def _store_tuple(s, t):
    """Write the 19 state scalars ``t`` (in state order) into ``s``."""
    _store_state(s, t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], t[10], t[11],
                 t[12], t[13], t[14], t[15], t[16], t[17], t[18])


SPEC = register(
    PlanLawSpec(
        name="bouc_wen",
        step=step,
        state_size=19,
        description="OpenSees ElastomericBearingBoucWen3d shear: vector Bouc-Wen z, local "
                    "Newton on its two components, per-component hardening.",
        static_calls=2,
        settled_index=SETTLED,
        carrier=Carrier(carry_begin, carry_update, carry_commit, carry_end),
    )
)
