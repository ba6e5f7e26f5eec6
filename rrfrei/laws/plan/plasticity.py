"""ElastomericBearingPlasticity in plan (OpenSees v3.7.1, ``ElastomericBearingPlasticity3d.cpp``).

Coupled bidirectional elastic-plastic shear with a circular yield surface (radius qd) and return
mapping, plus linear and nonlinear hardening (``update``, l.477-517 of the v3.7.1 file;
constants l.224 and l.244-246)::

    k0 = (1 - alpha1) k_init,  k2 = alpha1 k_init,  k3 = alpha2 k_init       [kN/m]
    q_tr = k0 (u - u_p,C)   (2-vector),   Y = |q_tr| - qd,   n = q_tr / |q_tr|
    elastic (Y <= 0):  F_i = q_tr,i + k2 u_i + k3 sgn(u_i) |u_i|^mu
                       K   = (k0 + k2) I + diag(k3 mu |u_i|^(mu-1))
    plastic (Y > 0):   u_p = u_p,C + (Y / k0) n
                       F_i = qd n_i + k2 u_i + k3 sgn(u_i) |u_i|^mu
                       K   = qd k0 (I - n n^T) / |q_tr| + k2 I + diag(k3 mu |u_i|^(mu-1))

u [m], F [kN], K [kN/m].  ``qd`` is the radius of the yield surface of the hysteretic force: a
diagonal push yields when |q_tr| = qd, at a component qd / sqrt(2) per axis, where two
independent springs would carry qd per axis.  The linear hardening k2 u is isotropic; the
nonlinear term k3 sgn(u_i) |u_i|^mu is applied **per component** (OpenSees l.490-491 and
l.505-508), not on the resultant, so for mu != 1 it is not rotation-invariant (a push of
length d along a diagonal carries 2^((1-mu)/2) times the axis value of that term).  Both
hardening terms are elastic: the dissipation is the hysteretic part's alone.

The return mapping is exact (no integration error); K is its consistent tangent (OpenSees
l.510-516).  Energy: 4 qd (d - u_y) per cycle of amplitude d along any straight line in plan,
u_y = qd / k0; 2 pi qd sqrt(r^2 - u_y^2) per revolution of a steady circular orbit of radius r
(docs/plan_laws.md).

State ``[u_p,x, u_p,y]`` (plastic displacement [m]).  As in OpenSees the trial u_p is not reset
in the elastic branch ("sticky" trial variable).

Rounding.  OpenSees writes the return as ``dGamma*qTrial(i)/qTrialNorm`` and
``qYield*qTrial(i)/qTrialNorm``, i.e. (a q_i) / |q|; here n = q / |q| is formed first and
multiplied, (a) n_i, which differs by at most an ulp or two of the result and makes a path along
one axis (n = (+-1, 0) exactly, |q| = sqrt(q_x^2) = |q_x|) reproduce the unidirectional law
:mod:`rrfrei.laws.plasticity` bit for bit (same expressions; |u_i|^mu by the same ``powabs``,
products for mu = 1, 2, 3 where OpenSees calls ``pow``: an ulp at most).
"""

import math

from numba import njit

from rrfrei.laws._util import bearing_constants, hardening, store_plan
from rrfrei.laws.plan.registry import PlanLawSpec, register


@njit(cache=True, error_model="numpy", forceinline=True)
def step(p, sc, u, v, dt, st, f, k):
    """Plan plasticity step (module docstring): forces ``f`` [kN], tangent ``k`` [kN/m],
    trial plastic displacement ``st`` [m]; status 0 (the return mapping cannot fail)."""
    _, qd, k0, k2, k3, mu = bearing_constants(p)
    u0 = u[0]
    u1 = u[1]
    s0 = sc[0]
    s1 = sc[1]
    q0 = k0 * (u0 - s0)
    q1 = k0 * (u1 - s1)
    nrm = math.sqrt(q0 * q0 + q1 * q1)  # OpenSees Vector::Norm
    y = nrm - qd
    h0, g0 = hardening(k3, mu, u0)
    h1, g1 = hardening(k3, mu, u1)
    if y <= 0.0:
        f0 = q0 + k2 * u0 + h0
        f1 = q1 + k2 * u1 + h1
        k00 = k0 + k2 + g0
        k01 = 0.0
        k11 = k0 + k2 + g1
        t0 = st[0]
        t1 = st[1]
    else:
        n0 = q0 / nrm
        n1 = q1 / nrm
        dg = y / k0
        t0 = s0 + dg * n0
        t1 = s1 + dg * n1
        f0 = qd * n0 + k2 * u0 + h0
        f1 = qd * n1 + k2 * u1 + h1
        d = nrm * nrm * nrm
        c = qd * k0
        k00 = c * q1 * q1 / d + k2 + g0
        k01 = -c * q0 * q1 / d
        k11 = c * q0 * q0 / d + k2 + g1
    st[0] = t0
    st[1] = t1
    store_plan(f, k, f0, f1, k00, k01, k01, k11)
    return 0


SPEC = register(
    PlanLawSpec(
        name="plasticity",
        step=step,
        state_size=2,
        description="OpenSees ElastomericBearingPlasticity3d shear: circular yield surface, "
                    "return mapping, per-component hardening.",
    )
)
