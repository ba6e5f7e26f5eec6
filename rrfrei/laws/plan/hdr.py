"""HDR in plan: the element's vector shear law (OpenSees v3.7.1, ``HDR.cpp``, Grant, Fenves &
Whittaker 2004, as coded by Kumar), both horizontal directions.

Parameters and units are those of the unidirectional law :mod:`rrfrei.laws.hdr` (same order):
a1 [kN/m], a2 [kN/m^3], a3 [kN/m^5], b1 [kN], b2 [kN/m^2], b3 [1/m], c1, c2 [1/m^3], c3 [-],
c4 [1/m^3]; they act directly on the shear displacement vector U [m] (the geometry enters only
the element's vertical terms, which do not feed back into the shear law).

``update()`` (l.512-567), with U and U_C the trial and committed shear displacement vectors::

    uh = |U|,  uh_C = |U_C|,  dU = |U - U_C|,  n = (U - U_C)/dU   (0 when dU <= DBL_EPSILON)

Scragging and Mullins trackers (l.530-542), each condition tested on its own and *sticky* (a
trial variable whose condition is false keeps its value of the previous call)::

    if uh > DS+_C:  DS+ = uh,    DS- = DS-_C + (DS+ - DS+_C),  DS = DS_C
    if uh < DS-_C:  DS+ = DS+_C, DS- = uh,                     DS = DS_C - (DS- - DS-_C)
    if uh < uh_C:   DM  = DM_C + uh_C - uh

Damage and forces (l.544-567)::

    KS1 = exp(-c1 DS^3),  KS2 = exp(-c2 DS^3),  KS2_C = exp(-c2 DS_C^3)
    KM  = c3 + (1 - c3) exp(-c4 DM^3)
    R   = b1 + KS2 b2 uh^2,   R_C = b1 + KS2_C b2 uh_C^2       radius of the bounding surface
    F1  = KS1 KM (a1 + a2 uh^2 + a3 uh^4) U                    elastic part
    Delta = |R_C n - F2_C| / (1 + b3 dU)
    mu  = (R n - F2_C) / |R n - F2_C|   (0 when that norm <= DBL_EPSILON)
    F2  = R n - Delta mu                                       hysteretic part (vector)
    F   = F1 + F2

so the hysteretic force moves towards the point R n of the circular bounding surface in the
direction of the increment, its distance shrunk by 1 + b3 dU: a backward-Euler step whose
result depends on the step size.  The law is isotropic: rotating the path rotates the forces.

Tangent: the element's "consistent" one (l.569-612), the 2x2 form of the 1-D law's, including
its dKM/dDM typo (c4 (1 - c4) where c3 is meant; the force is never affected)::

    dF1/dU = KS1 KM ((a1 + a2 uh^2 + a3 uh^4) I + 2 (a2 + 2 a3 uh^2) U U^T)
             + (KM poly U)(dKS1/dDS dDS/dU)^T + (KS1 poly U)(dKM/dDM dDM/dU)^T
    dF2/dU = n dR/dU^T + R dn/dU - mu dDelta/dU^T - Delta dmu/dU
    dDS/dU = -U/uh (uh < DS-_C, uh > eps),  dDM/dU = -U/uh (uh < uh_C, uh > eps), else 0
    dR/dU  = b2 (2 KS2 U + uh^2 dKS2/dDS dDS/dU),  dn/dU = (I - n n^T)/dU
    dDelta/dU = -Delta_C b3 n / (1 + b3 dU)^2,  dmu/dU = (I - mu mu^T)(n dR/dU^T + R dn/dU)/|R n - F2_C|

It is not the derivative of the step in plan: it holds Delta_C = |R_C n - F2_C| fixed although
n turns with U, so the term -mu (dDelta_C/dU)^T / (1 + b3 dU) is missing (O(1) on a random walk;
it vanishes in 1-D, where n = +-1).  Kept, since it steers OpenSees' global Newton iteration.

Along one axis (the other component identically 0) every norm is sqrt(x^2 + 0) = |x| and every
second component an exact 0, and the arithmetic on the first component is that of
:mod:`rrfrei.laws.hdr` (which uses the same products for OpenSees' ``pow``), so forces and
tangents are bit for bit the unidirectional ones (for displacements above 1e-154 m, where x^2
does not underflow).

State (float64[8])::

    [0:2] U      trial (committed, in sc) shear displacement (x, y) [m]
    [2:4] F2     hysteretic force [kN]
    [4] DS+  [5] DS-  [6] DS   scragging trackers [m]
    [7] DM       Mullins tracker [m]
"""

import math

from numba import njit

from rrfrei.laws.hdr import DBL_EPSILON, shear_terms, track_damage
from rrfrei.laws.plan.registry import PlanLawSpec, register


@njit(cache=True, inline="always")
def _unit(x1, x2):
    """``(|x|, x / |x|)`` of the 2-vector x = (x1, x2), the direction (0, 0) when |x| <=
    DBL_EPSILON: n of the increment (|x| = dU) and mu of the gap to the bounding surface."""
    norm = math.sqrt(x1 * x1 + x2 * x2)
    if norm > DBL_EPSILON:
        return norm, x1 / norm, x2 / norm
    return norm, 0.0, 0.0


@njit(cache=True, inline="always")
def _projector(a1, a2, norm):
    """(I - a a^T) / norm for a unit 2-vector ``a`` = (a1, a2), as (p11, p12, p21, p22); zeros
    when norm <= DBL_EPSILON.  The derivative of a normalised vector x / |x| with respect to x
    (dn/dU with norm dU, dmu/dU with norm |R n - F2_C|)."""
    if norm > DBL_EPSILON:
        r = 1.0 / norm
        return r * (1.0 - a1 * a1), r * (0.0 - a1 * a2), r * (0.0 - a2 * a1), r * (1.0 - a2 * a2)
    return 0.0, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st, f, k):
    """HDR shear forces [kN], tangent [kN/m] and status in plan (see the module docstring)."""
    a2 = p[1]
    a3 = p[2]
    b2 = p[4]
    b3 = p[5]
    u1 = u[0]
    u2 = u[1]
    uc1 = sc[0]
    uc2 = sc[1]
    f2c1 = sc[2]
    f2c2 = sc[3]
    dsp_c = sc[4]
    dsm_c = sc[5]
    ds_c = sc[6]
    dm_c = sc[7]
    st[0] = u1
    st[1] = u2
    uh = math.sqrt(u1 * u1 + u2 * u2)
    uhc = math.sqrt(uc1 * uc1 + uc2 * uc2)
    dU, n1, n2 = _unit(u1 - uc1, u2 - uc2)
    ds, dm = track_damage(st, 4, uh, uhc, dsp_c, dsm_c, ds_c, dm_c)
    ks1, ks2, km, uh2, r, rc, poly, dks1_dds, dks2_dds, dkm_ddm = shear_terms(p, uh, uhc, ds, dm,
                                                                              ds_c)
    s1 = ks1 * km * poly
    g1 = rc * n1 - f2c1
    g2 = rc * n2 - f2c2
    delta_c = math.sqrt(g1 * g1 + g2 * g2)
    den = 1.0 + b3 * dU
    delta = delta_c / den
    fnorm, mu1, mu2 = _unit(r * n1 - f2c1, r * n2 - f2c2)
    f21 = r * n1 - delta * mu1
    f22 = r * n2 - delta * mu2
    st[2] = f21
    st[3] = f22
    f[0] = s1 * u1 + f21
    f[1] = s1 * u2 + f22
    # tangent (l.569-612)
    c = 2.0 * (a2 + 2.0 * a3 * uh2)
    kk = ks1 * km
    dds1 = 0.0
    dds2 = 0.0
    if uh < dsm_c and uh > DBL_EPSILON:
        dds1 = -(1.0 / uh) * u1
        dds2 = -(1.0 / uh) * u2
    ddm1 = 0.0
    ddm2 = 0.0
    if uh < uhc and uh > DBL_EPSILON:
        ddm1 = -(1.0 / uh) * u1
        ddm2 = -(1.0 / uh) * u2
    dr1 = b2 * (2.0 * ks2 * u1 + uh2 * dks2_dds * dds1)
    dr2 = b2 * (2.0 * ks2 * u2 + uh2 * dks2_dds * dds2)
    dn11, dn12, dn21, dn22 = _projector(n1, n2, dU)
    dd1 = -1.0 * delta_c * b3 * n1 / (den * den)
    dd2 = -1.0 * delta_c * b3 * n2 / (den * den)
    fh11 = n1 * dr1 + r * dn11
    fh12 = n1 * dr2 + r * dn12
    fh21 = n2 * dr1 + r * dn21
    fh22 = n2 * dr2 + r * dn22
    dmu11 = 0.0
    dmu12 = 0.0
    dmu21 = 0.0
    dmu22 = 0.0
    if fnorm > DBL_EPSILON:
        p11, p12, p21, p22 = _projector(mu1, mu2, fnorm)
        dmu11 = p11 * fh11 + p12 * fh21
        dmu12 = p11 * fh12 + p12 * fh22
        dmu21 = p21 * fh11 + p22 * fh21
        dmu22 = p21 * fh12 + p22 * fh22
    w1 = km * poly
    w2 = ks1 * poly
    # dF1/dU: elastic part, its scragging and Mullins terms
    k1_11 = kk * (poly + c * u1 * u1) + (w1 * u1) * (dks1_dds * dds1) + (w2 * u1) * (dkm_ddm * ddm1)
    k1_12 = kk * (0.0 + c * u1 * u2) + (w1 * u1) * (dks1_dds * dds2) + (w2 * u1) * (dkm_ddm * ddm2)
    k1_21 = kk * (0.0 + c * u2 * u1) + (w1 * u2) * (dks1_dds * dds1) + (w2 * u2) * (dkm_ddm * ddm1)
    k1_22 = kk * (poly + c * u2 * u2) + (w1 * u2) * (dks1_dds * dds2) + (w2 * u2) * (dkm_ddm * ddm2)
    # dF2/dU: hysteretic part
    k[0, 0] = k1_11 + (n1 * dr1 + r * dn11 - mu1 * dd1 - delta * dmu11)
    k[0, 1] = k1_12 + (n1 * dr2 + r * dn12 - mu1 * dd2 - delta * dmu12)
    k[1, 0] = k1_21 + (n2 * dr1 + r * dn21 - mu2 * dd1 - delta * dmu21)
    k[1, 1] = k1_22 + (n2 * dr2 + r * dn22 - mu2 * dd2 - delta * dmu22)
    return 0


SPEC = register(
    PlanLawSpec(
        name="hdr",
        step=step,
        state_size=8,
        description="OpenSees HDR (Grant et al. 2004) in plan: isotropic elastic part plus a "
        "vector bounding-surface hysteresis with scragging and Mullins damage (HDR.cpp "
        "update(), v3.7.1).",
    )
)
