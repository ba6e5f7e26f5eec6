"""HDR shear law (OpenSees v3.7.1, ``HDR.cpp``, Grant-Fenves-Whittaker 2004), force form, 1-D.

The element's vector law on one shear direction.  a1..c4 act directly on the shear
displacement u [m] and give force [kN] (in OpenSees the geometry never enters the shear law).

With uh = |u|, uh_C = |u_C|, dU = |u - u_C| and n = sgn(u - u_C) (0 when dU <= DBL_EPSILON):

Scragging and Mullins trackers (update l.530-542), each condition tested independently, and
*sticky*: when a condition is false its trial variables keep their value from the previous call::

    if uh > DS+_C:  DS+ = uh,    DS- = DS-_C + (uh - DS+_C),  DS = DS_C
    if uh < DS-_C:  DS+ = DS+_C, DS- = uh,                    DS = DS_C - (uh - DS-_C)
    if uh < uh_C:   DM  = DM_C + uh_C - uh

Damage and forces (l.544-567)::

    KS1 = exp(-c1 DS^3),  KS2 = exp(-c2 DS^3),  KS2_C = exp(-c2 DS_C^3)
    KM  = c3 + (1 - c3) exp(-c4 DM^3)
    R   = b1 + KS2 b2 uh^2,   R_C = b1 + KS2_C b2 uh_C^2          (bounding surface)
    F1  = KS1 KM (a1 + a2 uh^2 + a3 uh^4) u                       (elastic part)
    Delta = |R_C n - F2_C| / (1 + b3 dU)
    mu  = sgn(R n - F2_C)  (0 when |R n - F2_C| <= DBL_EPSILON)
    F2  = R n - Delta mu                                          (hysteretic part)
    F   = F1 + F2

The tangent is the element's "consistent" one (l.569-612) reduced to 1-D, including its
dKM/dDM typo (c4 (1 - c4) where c3 is meant); it never affects the force.  HDR recomputes on
every call (no du == 0 shortcut).  The approach to the bounding surface is a backward-Euler step,
so the result depends on the step size.  The update is explicit (no local iteration, so it cannot fail to
converge): ``local_solver="robust"`` changes nothing (``local_iteration=False``).

State (float64[6])::

    [0] u     trial (committed, in sc) shear displacement [m]
    [1] F2    hysteretic force [kN]
    [2] DS+   [3] DS-   [4] DS   scragging trackers [m]
    [5] DM    Mullins tracker [m]
"""

import math

from numba import njit

from rrfrei.laws.registry import OPENSEES_VERTICAL, LawSpec, OpenSeesElement, ParamSpec, Prior, register

DBL_EPSILON = 2.220446049250313e-16


@njit(cache=True, inline="always")
def track_damage(st, o, uh, uhc, dsp_c, dsm_c, ds_c, dm_c):
    """Scragging and Mullins trackers of OpenSees' HDR (sticky trial values, written to
    ``st[o:o + 4]`` = DS+, DS-, DS, DM [m]) from the trial and committed displacement magnitudes
    ``uh``, ``uhc`` [m]; returns the trial (DS, DM).  Shared by the 1-D law and the plan law
    (:mod:`rrfrei.laws.plan.hdr`), where the magnitudes are Euclidean norms."""
    if uh > dsp_c:
        st[o] = uh
        st[o + 1] = dsm_c + (uh - dsp_c)
        st[o + 2] = ds_c
    if uh < dsm_c:
        st[o] = dsp_c
        st[o + 1] = uh
        st[o + 2] = ds_c - (uh - dsm_c)
    if uh < uhc:
        st[o + 3] = dm_c + uhc - uh
    return st[o + 2], st[o + 3]


@njit(cache=True, inline="always")
def damage_moduli(ds, dm, ds_c, c1, c2, c3, c4):
    """Damage moduli of OpenSees' HDR: ks1 = exp(-c1 DS^3), ks2 = exp(-c2 DS^3) (and at the
    committed DS), em = exp(-c4 DM^3), km = c3 + (1 - c3) em."""
    ds3 = ds * ds * ds
    dm3 = dm * dm * dm
    ks1 = math.exp(-c1 * ds3)
    ks2 = math.exp(-c2 * ds3)
    ks2c = math.exp(-c2 * (ds_c * ds_c * ds_c))
    em = math.exp(-c4 * dm3)
    km = c3 + (1.0 - c3) * em
    return ks1, ks2, ks2c, em, km


@njit(cache=True, inline="always")
def shear_terms(p, uh, uhc, ds, dm, ds_c):
    """The scalar terms of OpenSees' HDR update and tangent at the trial and committed
    displacement magnitudes ``uh``, ``uhc`` [m] and damage trackers DS, DM (:func:`track_damage`),
    shared by the 1-D law and the plan law (:mod:`rrfrei.laws.plan.hdr`):
    ``(ks1, ks2, km, uh^2, R, R_C, poly, dKS1/dDS, dKS2/dDS, dKM/dDM)`` with
    poly = a1 + a2 uh^2 + a3 uh^4 and the moduli of :func:`damage_moduli` (dKM/dDM with OpenSees'
    c4 (1 - c4) typo, module docstring)."""
    a1 = p[0]
    a2 = p[1]
    a3 = p[2]
    b1 = p[3]
    b2 = p[4]
    c1 = p[6]
    c2 = p[7]
    c3 = p[8]
    c4 = p[9]
    ks1, ks2, ks2c, em, km = damage_moduli(ds, dm, ds_c, c1, c2, c3, c4)
    uh2 = uh * uh
    uh4 = uh2 * uh2
    r = b1 + ks2 * b2 * uh2
    rc = b1 + ks2c * b2 * (uhc * uhc)
    poly = a1 + a2 * uh2 + a3 * uh4
    dks1_dds = -3.0 * c1 * ds * ds * ks1
    dks2_dds = -3.0 * c2 * ds * ds * ks2
    dkm_ddm = -3.0 * c4 * (1.0 - c4) * dm * dm * em  # OpenSees' typo kept (c4 for c3)
    return ks1, ks2, km, uh2, r, rc, poly, dks1_dds, dks2_dds, dkm_ddm


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    """HDR shear force [kN], tangent [kN/m] and status (see the module docstring)."""
    a2 = p[1]
    a3 = p[2]
    b2 = p[4]
    b3 = p[5]
    uc = sc[0]
    f2c = sc[1]
    dsm_c = sc[3]
    st[0] = u
    uh = abs(u)
    uhc = abs(uc)
    dU = abs(u - uc)
    n = (u - uc) / dU if dU > DBL_EPSILON else 0.0
    ds, dm = track_damage(st, 2, uh, uhc, sc[2], dsm_c, sc[4], sc[5])
    ks1, ks2, km, uh2, r, rc, poly, dks1_dds, dks2_dds, dkm_ddm = shear_terms(p, uh, uhc, ds, dm,
                                                                              sc[4])
    f1 = ks1 * km * poly * u
    fhat = r * n
    delta_c = abs(rc * n - f2c)
    den = 1.0 + b3 * dU
    delta = delta_c / den
    fnorm = abs(fhat - f2c)
    mu = (fhat - f2c) / fnorm if fnorm > DBL_EPSILON else 0.0
    f2 = r * n - delta * mu
    st[1] = f2
    # tangent (1-D reduction of l.569-612)
    df1_du = ks1 * km * (poly + 2.0 * (a2 + 2.0 * a3 * uh2) * u * u)
    ds_du = -(1.0 / uh) * u if (uh < dsm_c and uh > DBL_EPSILON) else 0.0
    dm_du = -(1.0 / uh) * u if (uh < uhc and uh > DBL_EPSILON) else 0.0
    dr_du = b2 * (2.0 * ks2 * u + uh2 * dks2_dds * ds_du)
    dn_du = (1.0 / dU) * (1.0 - n * n) if dU > DBL_EPSILON else 0.0
    ddelta_du = -1.0 * delta_c * b3 * n / (den * den)
    dfhat_du = n * dr_du + r * dn_du
    dmu_du = (1.0 / fnorm) * (1.0 - mu * mu) * dfhat_du if fnorm > DBL_EPSILON else 0.0
    k1 = df1_du + (km * poly * u) * (dks1_dds * ds_du) + (ks1 * poly * u) * (dkm_ddm * dm_du)
    k2 = n * dr_du + r * dn_du - mu * ddelta_du - delta * dmu_du
    return f1 + f2, k1 + k2, 0


OPENSEES_GEOMETRY = {"gr": 500.0, "d1": 0.0, "d2": 0.3, "tr": 0.005, "n": 20.0}
"""HDR's geometry [kN/m^2, m, -] written into the OpenSees element: it enters only the vertical
terms (the shear law uses a1..c4 directly)."""


def opensees_args(p, ndm, orient, materials=None) -> list:
    """OpenSees' 32 positional HDR arguments after the tag and nodes (``OPS_HDR``):
    Gr Kbulk D1 D2 ts tr n a1..c4 | x1..y3 | kc PhiM ac sDratio m tc (geometry
    :data:`OPENSEES_GEOMETRY`, vertical terms :data:`~rrfrei.laws.registry.OPENSEES_VERTICAL`)."""
    g, v = OPENSEES_GEOMETRY, OPENSEES_VERTICAL
    return [g["gr"], v["kbulk"], g["d1"], g["d2"], v["ts"], g["tr"], g["n"],
            *(p[n] for n in ("a1", "a2", "a3", "b1", "b2", "b3", "c1", "c2", "c3", "c4")),
            *orient, v["kc"], v["phi_m"], v["ac"], v["sd_ratio"], v["m"], 0.0]


SPEC = register(
    LawSpec(
        name="hdr",
        step=step,
        params=(
            ParamSpec("a1", "kN/m", 1e-6, 1e9, "initial elastic stiffness",
                      Prior("loguniform", 10.0, 1e6)),
            ParamSpec("a2", "kN/m^3", -1e12, 1e12, "quadratic elastic stiffening",
                      Prior("normal", 0.0, 1e6)),
            ParamSpec("a3", "kN/m^5", -1e16, 1e16, "quartic elastic stiffening",
                      Prior("normal", 0.0, 1e9)),
            ParamSpec("b1", "kN", 0.0, 1e6, "bounding-surface radius at zero displacement",
                      Prior("loguniform", 1e-2, 1e3)),
            ParamSpec("b2", "kN/m^2", -1e9, 1e9, "growth of the bounding surface with |u|^2",
                      Prior("normal", 0.0, 1e4)),
            ParamSpec("b3", "1/m", 0.0, 1e6, "rate of approach to the bounding surface",
                      Prior("loguniform", 1.0, 1e4)),
            ParamSpec("c1", "1/m^3", 0.0, 1e12, "scragging damage of the elastic part",
                      Prior("halfnormal", 1e3)),
            ParamSpec("c2", "1/m^3", 0.0, 1e12, "scragging damage of the bounding surface",
                      Prior("halfnormal", 1e3)),
            ParamSpec("c3", "-", 0.0, 1.0, "residual fraction after Mullins damage",
                      Prior("uniform", 0.0, 1.0)),
            ParamSpec("c4", "1/m^3", 0.0, 1e12, "Mullins damage rate",
                      Prior("halfnormal", 1e3)),
        ),
        state_size=6,
        local_iteration=False,
        description="OpenSees HDR (Grant et al. 2004): elastic + bounding-surface hysteresis "
        "with scragging and Mullins damage.",
        opensees=OpenSeesElement("HDR", opensees_args, dims=(3,)),
    )
)
