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
(the element's defaults, l.149-150).  Df^-1 f is solved as OpenSees' ``Vector::operator/(Matrix)`` does:
LAPACK ``dgesv`` (``dgetrf2`` LU with partial pivoting, L scaled by the reciprocal pivot,
``dgetrs`` with reference-BLAS ``dtrsm``); a singular U leaves dz = f, as ``dgesv`` leaves the
right-hand side unsolved.  Status -1 if |Df_xx| or |Df_yy| <= DBL_EPSILON (OpenSees' "zero
Jacobian", l.533-538), -2 if the loop ends with iter >= 25 (a solve converging exactly on the 25th
iteration also fails, as in OpenSees, l.547-552).  When |du| <= DBL_EPSILON (Euclidean norm)
nothing is recomputed: force and tangent are those of the previous call (OpenSees l.500).

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

State (float64[10])::

    [0:2] u   trial (committed, in sc) shear displacement [m]
    [2:4] z   hysteretic variable [-]
    [4:6] q   shear forces of the last call [kN]
    [6:10] K - (k0 + k2) I, tangent of the last call (row-major) as an offset from the initial
           tangent A k0 + k2 [kN/m], so the virgin state (all zeros) is parameter-free
"""

import math

from numba import njit

from rrfrei.laws._util import powabs, sgn
from rrfrei.laws.plan.registry import PlanLawSpec, register

A = 1.0
MAX_ITER = 25
TOL = 1e-12
DBL_EPSILON = 2.220446049250313e-16
SFMIN = 2.2250738585072014e-308
"""LAPACK ``dlamch('S')``: below it ``dgetrf2`` divides by the pivot instead of scaling by its
reciprocal."""


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


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st, f, k):
    """Plan Bouc-Wen step (module docstring): forces ``f`` [kN], tangent ``k`` [kN/m], trial
    state ``st``; status 0, -1 (zero Jacobian diagonal) or -2 (no convergence in 25)."""
    k_init = p[0]
    qd = p[1]
    k0 = (1.0 - p[2]) * k_init
    k2 = p[2] * k_init
    k3 = p[3] * k_init
    mu = p[4]
    eta = p[5]
    beta = p[6]
    gamma = p[7]
    du0 = u[0] - sc[0]
    du1 = u[1] - sc[1]
    st[0] = u[0]
    st[1] = u[1]
    if not (math.sqrt(du0 * du0 + du1 * du1) > DBL_EPSILON):
        # OpenSees keeps q and K of the previous update() call
        kini = A * k0 + k2
        f[0] = st[4]
        f[1] = st[5]
        k[0, 0] = st[6] + kini
        k[0, 1] = st[7]
        k[1, 0] = st[8]
        k[1, 1] = st[9] + kini
        return 0
    uy = qd / k0
    iuy = 1.0 / uy
    zc0 = sc[2]
    zc1 = sc[3]
    z0 = st[2]
    z1 = st[3]
    em1 = eta - 1.0
    em2 = eta - 2.0
    it = 0
    tmp2 = 0.0
    pw2 = 0.0
    while True:
        znrm = math.sqrt(z0 * z0 + z1 * z1)
        if znrm == 0.0:
            znrm = DBL_EPSILON
        tmp1 = z0 * du0 + z1 * du1
        tmp2 = gamma + beta * sgn(tmp1)
        pw2 = znrm ** (eta - 2.0)
        tmp3 = pw2 * tmp1 * tmp2
        tmp4 = znrm ** (eta - 4.0) * tmp2
        f0 = (z0 - zc0) - iuy * (A * du0 - z0 * tmp3)
        f1 = (z1 - zc1) - iuy * (A * du1 - z1 * tmp3)
        a0 = z0 * z0
        a1 = z1 * z1
        c0 = z0 ** 3.0
        c1 = z1 ** 3.0
        t = tmp4 / uy
        d00 = 1.0 + t * (c1 * du1 + 2.0 * a1 * z0 * du0 + z1 * a0 * du1 * em1 + c0 * du0 * eta)
        d10 = z1 * tmp4 / uy * (a1 * du0 + z0 * z1 * du1 * em2 + a0 * du0 * em1)
        d01 = z0 * tmp4 / uy * (a0 * du1 + z0 * z1 * du0 * em2 + a1 * du1 * em1)
        d11 = 1.0 + t * (c0 * du0 + 2.0 * a0 * z1 * du1 + z0 * a1 * du0 * em1 + c1 * du1 * eta)
        if abs(d00) <= DBL_EPSILON or abs(d11) <= DBL_EPSILON:
            st[2] = z0
            st[3] = z1
            return -1
        dz0, dz1 = _solve2(d00, d01, d10, d11, f0, f1)
        z0 -= dz0
        z1 -= dz1
        it += 1
        if not (math.sqrt(dz0 * dz0 + dz1 * dz1) >= TOL and it < MAX_ITER):
            break
    st[2] = z0
    st[3] = z1
    if it >= MAX_ITER:
        return -2
    tmp5 = pw2 * tmp2  # OpenSees recomputes pow(zNrm, eta-2) of the last iteration: same value
    r12 = du0 / du1
    r21 = du1 / du0
    if du0 * du1 == 0.0:
        r12 = 0.0
        r21 = 0.0
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
    q0 = qd * z0 + k2 * u[0]
    q1 = qd * z1 + k2 * u[1]
    k00 = k0 * g00 + k2
    k11 = k0 * g11 + k2
    if k3 != 0.0:
        q0 += k3 * sgn(u[0]) * powabs(u[0], mu)
        q1 += k3 * sgn(u[1]) * powabs(u[1], mu)
        k00 += k3 * mu * powabs(u[0], mu - 1.0)
        k11 += k3 * mu * powabs(u[1], mu - 1.0)
    f[0] = q0
    f[1] = q1
    k[0, 0] = k00
    k[0, 1] = k0 * g01
    k[1, 0] = k0 * g10
    k[1, 1] = k11
    kini = A * k0 + k2
    st[4] = q0
    st[5] = q1
    st[6] = k00 - kini
    st[7] = k[0, 1]
    st[8] = k[1, 0]
    st[9] = k11 - kini
    return 0


SPEC = register(
    PlanLawSpec(
        name="bouc_wen",
        step=step,
        state_size=10,
        description="OpenSees ElastomericBearingBoucWen3d shear: vector Bouc-Wen z, local "
                    "Newton on its two components, per-component hardening.",
        opensees_element="elastomericBearingBoucWen",
    )
)
