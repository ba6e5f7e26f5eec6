"""ElastomericX in plan: the element's coupled two-component shear law (OpenSees v3.7.1,
``ElastomericX.cpp``, Kumar, Whittaker & Constantinou 2014), both horizontal directions.

Parameters and units are those of the unidirectional law :mod:`rrfrei.laws.elastomeric_x`
(same order): fy [kN] (the characteristic strength Qd), alpha [-], gr [kN/m^2], d1, d2, tr [m],
n [-], tc [m], cd [kN s/m].  Geometry and stiffness (constructor l.265-305, ``PI`` = 3.14159)::

    A = (PI/4) ((d2 + tc)^2 - d1^2),   ke = gr A / (n tr),   k0 = (1/alpha - 1) ke,   u_y = fy / k0

Shear law (``update()`` l.586-666).  With the increment d = u - u_C over the last commit (a
vector of the two basic shear deformations) and the hard-coded Park-Wen constants A = 1,
"beta" = 0.1 (constant term), "gamma" = 0.9 (sign term, Nagarajaiah's naming)::

    t_i = 0.1 + 0.9 sgn(z_i d_i),       t_3 = z_1 d_1 t_1 + z_2 d_2 t_2
    f_i(z) = z_i - z_C,i - (1/u_y) (d_i - z_i t_3) = 0            i = 1, 2   (l.606-612)

a backward-Euler step of Park, Wen & Ang's (1986) coupled model dz = (1/u_y)(I - z z^T T) du.
It is solved by the element's Newton iteration (l.602-641): from the current *trial* z (not
z_C), the sign terms held fixed in the Jacobian::

    J11 = 1 + (1/u_y)(2 z1 d1 t1 + z2 d2 t2)     J12 = (t2/u_y) z1 d2
    J21 = (t1/u_y) z2 d1                         J22 = 1 + (1/u_y)(z1 d1 t1 + 2 z2 d2 t2)

the 2x2 system by Cramer's rule, iterating while ||dz||_2 >= 1e-8 and iter < 100.  Status -1
when |J11| or |J22| <= DBL_EPSILON (zero Jacobian), -2 when iter reaches 100; the trial z keeps
the iterate reached, as the element's member does.  Then (l.643-666), with the increment ratios
r12 = d1/d2 and r21 = d2/d1 (both 0 when d1 d2 == 0, and, a deviation from OpenSees, when
a ratio exceeds ``RATIO_MAX`` = 1e100 or the tangent built from it overflows: a component below
1e-100 of the other, where OpenSees' tangent is beyond 1e100 kN/m, inf or nan, and a Newmark step
on it overflows; the force is unchanged) and the t_i of the last iteration::

    dz1/du1 = (1/u_y)(1   - z1 (z1 t1 + z2 t2 r21))    dz1/du2 = (1/u_y)(r12 - z1 (z1 t1 r12 + z2 t2))
    dz2/du1 = (1/u_y)(r21 - z2 (z1 t1 + z2 t2 r21))    dz2/du2 = (1/u_y)(1   - z2 (z1 t1 r12 + z2 t2))
    F_i  = cd v_i + fy z_i + ke u_i
    K_ij = delta_ij (cd/dt + ke) + fy dz_i/du_j

This tangent is the element's, not the derivative of its step: applied to the increment, its
hysteretic part gives fy (1/u_y)(d - z t_3) (the Park-Wen rate along d) when one component of d
is 0 but *twice* that when both are non-zero (r12 d2 = d1 counts the cross term again), so a
global Newton iteration on it converges linearly, as OpenSees' does.

OpenSees' static displacement-controlled analysis updates the element twice per step (in
``LoadControl::newStep`` and after the first Newton correction), the second call re-running the
local Newton from the trial z the first reached.  This law is called once per step
(``static_calls = 1``), as the unidirectional law is, so that a path along one axis is that law
bit for bit (issue 14); called twice it would be openseespy's 3-D element bit for bit (one call
moves the last bit at 629 of 2,000 samples of the benchmark's path, by at most 1.2e-16 of the
peak force).

When ||d||_2 = sqrt(d1^2 + d2^2) is 0 (l.588) nothing is recomputed: force and tangent of the
previous call, including the cd v term.

The vertical model (cavitation, buckling-load and stiffness variation: tag1..tag4 = 0, the
defaults, as in the differential harness) does not enter the shear law; with tag3 = 0 ke is
constant.  cd and tc act as in the 1-D port: tc only through the bonded area A, cd as the
viscous term above (the element has no heating).  The element is *not* isotropic: the sign
terms act per axis, so its orbit response depends on the orientation of the path (it is
symmetric under x <-> y and under reflections of either axis).

Along one axis (the other displacement component identically 0) the second component of z, of
its Newton correction and of the force stays exactly 0 and every operation on the first
component is the one of :mod:`rrfrei.laws.elastomeric_x` (adding exact zeros, sqrt(d^2) = |d|),
so the force and tangent are bit for bit the unidirectional ones (for increments above 1e-154 m,
where d^2 does not underflow).

State (float64[10])::

    [0:2] u        trial (committed, in sc) shear displacement (x, y) [m]
    [2:4] z        hysteretic variables [-]
    [4:6] q        force of the last call [kN]
    [6:10] dk      tangent of the last call (row major) minus the initial k_init I, k_init = k0 + ke [kN/m]
"""

import math

from numba import njit

from rrfrei.laws._util import sgn, store_plan, store_plan_state
from rrfrei.laws.elastomeric_x import (
    BETA_CONST,
    DBL_EPSILON,
    GAMMA_SIGN,
    MAX_ITER,
    TOL,
    stiffness,
)
from rrfrei.laws.plan.registry import PlanLawSpec, register

RATIO_MAX = 1e100
"""Largest ratio of the two increment components kept in the tangent (module docstring)."""


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st, f, k):
    """ElastomericX shear forces [kN], tangent [kN/m] and status in plan (module docstring)."""
    # load, compute on scalars, store once at the end: Numba then pairs every array argument's
    # reference count (an early return with array writes left ~4 atomic pairs per call)
    fy = p[0]
    cd = p[8]
    ke, k0 = stiffness(p)
    kinit = k0 + ke
    u0 = u[0]
    u1 = u[1]
    d1 = u0 - sc[0]
    d2 = u1 - sc[1]
    zc1 = sc[2]
    zc2 = sc[3]
    v0 = v[0]
    v1 = v[1]
    z1 = st[2]
    z2 = st[3]
    s4 = st[4]
    s5 = st[5]
    s6 = st[6]
    s7 = st[7]
    s8 = st[8]
    s9 = st[9]
    f0 = s4
    f1_ = s5
    k00 = k[0, 0]
    k01 = k[0, 1]
    k10 = k[1, 0]
    k11 = k[1, 1]
    status = 0
    if not (math.sqrt(d1 * d1 + d2 * d2) > 0.0):
        k00 = s6 + k0 + ke  # as the 1-D port: (dk + k0) + ke
        k01 = s7
        k10 = s8
        k11 = s9 + k0 + ke
    else:
        uy = fy / k0
        ruy = 1.0 / uy
        it = 0
        t1 = 0.0
        t2 = 0.0
        while True:
            t1 = BETA_CONST + GAMMA_SIGN * sgn(z1 * d1)
            t2 = BETA_CONST + GAMMA_SIGN * sgn(z2 * d2)
            t3 = z1 * d1 * t1 + z2 * d2 * t2
            f1 = z1 - zc1 - ruy * (d1 - z1 * t3)
            f2 = z2 - zc2 - ruy * (d2 - z2 * t3)
            j11 = 1.0 + ruy * (2.0 * z1 * d1 * t1 + z2 * d2 * t2)
            j21 = (t1 / uy) * z2 * d1
            j12 = (t2 / uy) * z1 * d2
            j22 = 1.0 + ruy * (z1 * d1 * t1 + 2.0 * z2 * d2 * t2)
            if abs(j11) <= DBL_EPSILON or abs(j22) <= DBL_EPSILON:
                status = -1  # z of this iteration's start kept; force and tangent as before
                break
            dz1 = (f1 * j22 - f2 * j12) / (j11 * j22 - j12 * j21)
            dz2 = (f1 * j21 - f2 * j11) / (j12 * j21 - j11 * j22)
            z1 -= dz1
            z2 -= dz2
            it += 1
            if not (math.sqrt(dz1 * dz1 + dz2 * dz2) >= TOL and it < MAX_ITER):
                break
        if status == 0 and it >= MAX_ITER:
            status = -2
        if status == 0:
            r12 = 0.0
            r21 = 0.0
            if d1 * d2 != 0.0:
                r12 = d1 / d2
                r21 = d2 / d1
                if not (abs(r12) <= RATIO_MAX and abs(r21) <= RATIO_MAX):
                    # a component below 1e-100 of the other is the exact zero it is physically:
                    # OpenSees' tangent there is finite but beyond 1e100 kN/m, and a Newmark step
                    # on it overflows (hypothesis: an azimuth of 1e-308 rad, d2 ~ 1e-310 d1)
                    r12 = 0.0
                    r21 = 0.0
            dz11 = ruy * (1.0 - z1 * (z1 * t1 + z2 * t2 * r21))
            dz12 = ruy * (r12 - z1 * (z1 * t1 * r12 + z2 * t2))
            dz21 = ruy * (r21 - z2 * (z1 * t1 + z2 * t2 * r21))
            dz22 = ruy * (1.0 - z2 * (z1 * t1 * r12 + z2 * t2))
            if not (math.isfinite(fy * dz11) and math.isfinite(fy * dz12)
                    and math.isfinite(fy * dz21) and math.isfinite(fy * dz22)):
                # An increment component ~1e-300 of the other overflows r12 or r21, or the
                # tangent fy dz/du built from them (hypothesis: d2 = 1e-310 d1 with fy = 100)
                # (and so OpenSees' tangent: inf/nan, harmless to its imposed-displacement
                # analyses, fatal to a Newmark step).  That component is taken as the exact
                # zero it is physically (the d1 d2 == 0 branch): the force is unchanged, the
                # tangent deviates from OpenSees only where OpenSees' is not finite.
                dz11 = ruy * (1.0 - z1 * z1 * t1)
                dz12 = -ruy * z1 * z2 * t2
                dz21 = -ruy * z2 * z1 * t1
                dz22 = ruy * (1.0 - z2 * z2 * t2)
            f0 = cd * v0 + fy * z1 + ke * u0
            f1_ = cd * v1 + fy * z2 + ke * u1
            k00 = cd / dt + fy * dz11 + ke
            k01 = fy * dz12
            k10 = fy * dz21
            k11 = cd / dt + fy * dz22 + ke
            s4 = f0
            s5 = f1_
            s6 = k00 - kinit
            s7 = k01
            s8 = k10
            s9 = k11 - kinit
    store_plan_state(st, u0, u1, z1, z2, s4, s5, s6, s7, s8, s9)
    store_plan(f, k, f0, f1_, k00, k01, k10, k11)
    return status


SPEC = register(
    PlanLawSpec(
        name="elastomeric_x",
        step=step,
        state_size=10,
        description="OpenSees ElastomericX (Kumar) in plan: coupled two-component Park-Wen "
        "hysteresis plus elastic rubber (ElastomericX.cpp update(), v3.7.1).",
    )
)
