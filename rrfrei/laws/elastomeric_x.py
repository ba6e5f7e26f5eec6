"""ElastomericX shear law (OpenSees v3.7.1, ``ElastomericX.cpp``, Kumar et al. 2014), 1-D.

The element's two-component Park-Wen law reduced to one shear direction (the second component
and its increment zero, so every 2x2 expression below is the OpenSees one with those zeros).

Geometry and stiffness (constructor l.265-320; PI is the macro 3.14159, not pi)::

    A  = (PI/4) ((d2 + tc)^2 - d1^2)        bonded area (note d2 + tc, as in OpenSees)
    Tr = n tr                               total rubber thickness
    ke = gr A / Tr                          rubber (elastic) shear stiffness
    k0 = (1/alpha - 1) ke                   initial stiffness of the hysteretic part
    u_y = fy / k0                           fy acts as the characteristic strength Qd

Hysteresis (update l.586-666), A = 1, hard-coded "beta" = 0.1 on the constant term and
"gamma" = 0.9 on the sign term (Nagarajaiah's naming), backward Euler over du = u - u_C::

    t1 = 0.1 + 0.9 sgn(z du)
    f(z) = z - z_C - (1/u_y) (du - z (z du t1)) = 0

solved by the element's 2x2 Newton (J11 = 1 + 2 z du t1/u_y, J22 = 1 + z du t1/u_y, off-diagonal
terms zero, Cramer's rule) from the current *trial* z, iterating while |dz| >= 1e-8 and
iter < 100; status -2 when iter reaches 100, -1 if |J11| or |J22| <= DBL_EPSILON.  Then::

    dz/du = (1/u_y) (1 - z (z t1))           (continuous tangent, t1 of the last iteration)
    F     = cd v + fy z + ke u
    k_t   = cd/dt + fy dz/du + ke

When du == 0 exactly nothing is recomputed (force and tangent of the previous call, including
the cd v term).  Robust local solve (``local_solver="robust"``, :func:`step_robust`): where
the element's iteration fails, the same equation, which is Bouc-Wen's with eta = 2, is solved by
Bouc-Wen's bracketed safeguarded Newton (a deviation from OpenSees, reported).
On loading dz/du = (1 - z^2)/u_y, so z = tanh(u/u_y) from a virgin state.

State (float64[4])::

    [0] u   trial (committed, in sc) shear displacement [m]
    [1] z   hysteretic variable [-]
    [2] q   force of the last call [kN]
    [3] dk  tangent of the last call minus the initial tangent k0 + ke [kN/m]
"""

from numba import njit

from rrfrei.laws._bouc_wen_robust import STATUS_ROBUST, solve_robust
from rrfrei.laws._util import sgn
from rrfrei.laws.registry import OPENSEES_VERTICAL, LawSpec, OpenSeesElement, ParamSpec, Prior, register

PI_OPENSEES = 3.14159
"""The ``PI`` macro of ElastomericX.cpp / HDR.cpp (``3.14159L``), used instead of math.pi."""
MAX_ITER = 100
TOL = 1e-8
BETA_CONST = 0.1
GAMMA_SIGN = 0.9
DBL_EPSILON = 2.220446049250313e-16


@njit(cache=True, inline="always")
def stiffness(p):
    """(ke, k0) [kN/m] of the parameter vector ``p`` (OpenSees constructor l.265-305)."""
    alpha = p[1]
    gr = p[2]
    d1 = p[3]
    d2 = p[4]
    tr = p[5]
    n = p[6]
    tc = p[7]
    area = (PI_OPENSEES / 4.0) * ((d2 + tc) * (d2 + tc) - d1 * d1)
    ke = gr * area / (n * tr)
    k0 = (1.0 / alpha - 1.0) * ke
    return ke, k0


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    """ElastomericX shear force [kN], tangent [kN/m] and status (see the module docstring)."""
    fy = p[0]
    cd = p[8]
    ke, k0 = stiffness(p)
    du = u - sc[0]
    st[0] = u
    if du == 0.0:
        return st[2], st[3] + k0 + ke, 0
    uy = fy / k0
    ruy = 1.0 / uy
    zc = sc[1]
    z = st[1]
    it = 0
    tmp1 = 0.0
    while True:
        tmp1 = BETA_CONST + GAMMA_SIGN * sgn(z * du)
        tmp3 = z * du * tmp1
        f = z - zc - ruy * (du - z * tmp3)
        j11 = 1.0 + ruy * (2.0 * z * du * tmp1)
        j22 = 1.0 + ruy * (z * du * tmp1)
        if abs(j11) <= DBL_EPSILON or abs(j22) <= DBL_EPSILON:
            st[1] = z
            return st[2], st[3] + k0 + ke, -1
        dz = (f * j22) / (j11 * j22)
        z -= dz
        it += 1
        if not (abs(dz) >= TOL and it < MAX_ITER):
            break
    st[1] = z
    if it >= MAX_ITER:
        return st[2], st[3] + k0 + ke, -2
    dzdu = ruy * (1.0 - z * (z * tmp1))
    q = cd * v + fy * z + ke * u
    kt = cd / dt + fy * dzdu + ke
    st[2] = q
    st[3] = kt - (k0 + ke)
    return q, kt, 0


@njit(cache=True, error_model="numpy")
def step_robust(p, sc, u, v, dt, st):
    """:func:`step`, and where the element's Newton iteration fails (status -1 or -2) the root of
    the same backward-Euler equation by :func:`rrfrei.laws._bouc_wen_robust.solve_robust` from the
    committed z (status :data:`rrfrei.laws._bouc_wen_robust.STATUS_ROBUST`, a deviation from OpenSees).

    The equation is Bouc-Wen's with eta = 2, the sign coefficient 0.9 and the constant 0.1
    (module docstring), so its bracket (|z| <= 1) and its safeguarded Newton apply unchanged.
    Where the element's iteration converges the result is :func:`step`'s, bit for bit; force
    and tangent at the bracketed root by :func:`step`'s expressions.
    """
    q, kt, status = step(p, sc, u, v, dt, st)
    if status != -1 and status != -2:
        return q, kt, status
    fy = p[0]
    cd = p[8]
    ke, k0 = stiffness(p)
    du = u - sc[0]
    ruy = k0 / fy
    z, st2 = solve_robust(sc[1], du * ruy, 2.0, GAMMA_SIGN, BETA_CONST)
    if st2 != 0:
        return q, kt, status
    st[1] = z
    tmp1 = BETA_CONST + GAMMA_SIGN * sgn(z * du)
    dzdu = ruy * (1.0 - z * (z * tmp1))
    q = cd * v + fy * z + ke * u
    kt = cd / dt + fy * dzdu + ke
    st[2] = q
    st[3] = kt - (k0 + ke)
    return q, kt, STATUS_ROBUST


def opensees_args(p, ndm, orient, materials=None) -> list:
    """OpenSees' 29 positional ElastomericX arguments after the tag and nodes (``OPS_ElastomericX``):
    Fy alpha Gr Kbulk D1 D2 ts tr n | x1 x2 x3 y1 y2 y3 | kc PhiM ac sDratio m cd tc tag1-4
    (vertical terms :data:`~rrfrei.laws.registry.OPENSEES_VERTICAL`, tags 0: the defaults)."""
    v = OPENSEES_VERTICAL
    return [p["fy"], p["alpha"], p["gr"], v["kbulk"], p["d1"], p["d2"], v["ts"], p["tr"], p["n"],
            *orient, v["kc"], v["phi_m"], v["ac"], v["sd_ratio"], v["m"], p["cd"], p["tc"],
            0, 0, 0, 0]


SPEC = register(
    LawSpec(
        name="elastomeric_x",
        step=step,
        step_robust=step_robust,
        params=(
            ParamSpec("fy", "kN", 1e-9, 1e6,
                      "characteristic strength Qd (OpenSees' name Fy)", Prior("loguniform", 1e-2, 1e3)),
            ParamSpec("alpha", "-", 1e-4, 0.9999,
                      "ratio of post-yield to initial shear stiffness", Prior("uniform", 0.01, 0.99)),
            ParamSpec("gr", "kN/m^2", 1e-3, 1e8, "rubber shear modulus",
                      Prior("loguniform", 10.0, 1e5)),
            ParamSpec("d1", "m", 0.0, 100.0, "inner (lead/hole) diameter", geometry=True,
                      default=0.0),
            ParamSpec("d2", "m", 1e-4, 100.0, "outer diameter", geometry=True),
            ParamSpec("tr", "m", 1e-5, 10.0, "thickness of one rubber layer", geometry=True),
            ParamSpec("n", "-", 1.0, 1000.0, "number of rubber layers", geometry=True),
            ParamSpec("tc", "m", 0.0, 10.0, "rubber cover thickness", geometry=True, default=0.0),
            ParamSpec("cd", "kN*s/m", 0.0, 1e9, "viscous damping coefficient", default=0.0),
        ),
        state_size=4,
        description="OpenSees ElastomericX (Kumar): Park-Wen hysteresis plus elastic rubber.",
        opensees=OpenSeesElement("ElastomericX", opensees_args, dims=(3,)),
        uses_velocity=True,
    )
)
