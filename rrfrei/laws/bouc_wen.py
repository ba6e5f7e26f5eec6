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

State (float64[4])::

    [0] u      trial (committed, in sc) shear displacement [m]
    [1] z      hysteretic variable [-]
    [2] q      shear force of the last update() call [kN]
    [3] dk     tangent of the last call minus the initial tangent k_init [kN/m]
               (stored as an offset so the virgin state, all zeros, is parameter-free)

Speed: integer ``eta`` (1, 2, 3) is specialised; otherwise one ``pow`` per Newton iteration.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import powabs, sgn
from rrfrei.laws.plasticity import PARAMS as _PLASTICITY_PARAMS
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register

KERNEL_ID = 2

A = 1.0
MAX_ITER = 25
TOL = 1e-12
DBL_EPSILON = 2.220446049250313e-16


@njit(cache=True, inline="always")
def _zpow(za, eta):
    """(|z|^eta, |z|^(eta-1)) for |z| = za > 0, with eta = 1, 2, 3 specialised."""
    if eta == 1.0:
        return za, 1.0
    if eta == 2.0:
        return za * za, za
    if eta == 3.0:
        zz = za * za
        return zz * za, zz
    pm1 = za ** (eta - 1.0)
    return pm1 * za, pm1


@njit(cache=True)
def step(p, sc, u, v, dt, st):
    """Bouc-Wen bearing shear force [kN], tangent [kN/m] and status (see the module docstring)."""
    k_init = p[0]
    qd = p[1]
    k0 = (1.0 - p[2]) * k_init
    k2 = p[2] * k_init
    k3 = p[3] * k_init
    mu = p[4]
    eta = p[5]
    beta = p[6]
    gamma = p[7]
    du = u - sc[0]
    st[0] = u
    if du == 0.0:  # OpenSees keeps q and k_t of the previous update() call
        return st[2], st[3] + k_init, 0
    uy = qd / k0
    r = du / uy
    zc = sc[1]
    z = st[1]
    it = 0
    while True:
        za = abs(z)
        if za == 0.0:
            za = DBL_EPSILON
        tmp1 = gamma + beta * sgn(z * du)
        pe, pm1 = _zpow(za, eta)
        f = z - zc - r * (A - pe * tmp1)
        df = 1.0 + r * eta * pm1 * sgn(z) * tmp1
        if abs(df) <= DBL_EPSILON:
            st[1] = z
            return st[2], st[3] + k_init, -1
        dz = f / df
        z -= dz
        it += 1
        if not (abs(dz) >= TOL and it < MAX_ITER):
            break
    st[1] = z
    if it >= MAX_ITER:
        return st[2], st[3] + k_init, -2
    pe, pm1 = _zpow(abs(z), eta) if z != 0.0 else (0.0, 0.0)
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


SPEC = register(
    LawSpec(
        name="bouc_wen",
        kernel_id=KERNEL_ID,
        params=_PLASTICITY_PARAMS
        + (
            ParamSpec("eta", "-", 0.1, 10.0, "Bouc-Wen exponent", Prior("uniform", 0.5, 5.0)),
            ParamSpec("beta", "-", 0.0, 5.0, "coefficient of the sign-dependent term",
                      Prior("uniform", 0.0, 2.0)),
            ParamSpec("gamma", "-", -5.0, 5.0, "coefficient of the constant term",
                      Prior("uniform", -1.0, 1.0)),
        ),
        state_size=4,
        description="OpenSees ElastomericBearingBoucWen: smooth Bouc-Wen hysteresis (A = 1).",
        opensees_element="elastomericBearingBoucWen",
        check=_check,
    )
)
