"""ElastomericBearingPlasticity (OpenSees v3.7.1, ``ElastomericBearingPlasticity2d.cpp``).

Elastic-plastic hysteresis plus linear and nonlinear hardening::

    k0 = (1 - alpha1) k_init,  k2 = alpha1 k_init,  k3 = alpha2 k_init
    q_tr = k0 (u - u_p,C),     Y = |q_tr| - qd
    elastic (Y <= 0):  F = q_tr + k2 u + k3 sgn(u) |u|^mu
    plastic (Y > 0):   u_p = u_p,C + (Y / k0) sgn(q_tr)
                       F = qd sgn(q_tr) + k2 u + k3 sgn(u) |u|^mu

(update, l.450-476).  The return mapping is exact, so the result does not depend on the step
size beyond how the history is sampled.  Energy per cycle at amplitude d: 4 qd (d - u_y),
u_y = qd / k0.

State: ``[u_p]`` (plastic displacement).  As in OpenSees the trial u_p is not reset in the
elastic branch ("sticky" trial variable).
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import bearing_constants, hardening, sgn
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, elastomeric_bearing, register


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    _, qd, k0, k2, k3, mu = bearing_constants(p)
    s0 = sc[0]
    q_tr = k0 * (u - s0)
    y = abs(q_tr) - qd
    nl_f, nl_k = hardening(k3, mu, u)
    if y <= 0.0:
        t0 = st[0]
        f = q_tr + k2 * u + nl_f
        kt = k0 + k2 + nl_k
    else:
        s = sgn(q_tr)
        t0 = s0 + (y / k0) * s
        f = qd * s + k2 * u + nl_f
        kt = k2 + nl_k
    st[0] = t0
    return f, kt, 0


def _check(p: np.ndarray) -> None:
    if p[2] >= 1.0:
        raise ValueError(f"law 'plasticity': alpha1 = {p[2]:g} must be < 1 (k0 = (1-alpha1) k_init > 0)")


PARAMS = (
    ParamSpec("k_init", "kN/m", 1e-6, 1e9, "initial elastic shear stiffness",
              Prior("loguniform", 10.0, 1e6)),
    ParamSpec("qd", "kN", 0.0, 1e6, "characteristic strength", Prior("loguniform", 1e-2, 1e3)),
    ParamSpec("alpha1", "-", 0.0, 0.9999, "post-yield stiffness ratio (linear part)",
              Prior("uniform", 0.0, 0.99)),
    ParamSpec("alpha2", "-", -1.0, 1.0, "post-yield ratio of the nonlinear hardening term",
              Prior("normal", 0.0, 0.1)),
    ParamSpec("mu", "-", 1.0, 10.0, "exponent of the nonlinear hardening term",
              Prior("uniform", 1.0, 5.0)),
)

SPEC = register(
    LawSpec(
        name="plasticity",
        step=step,
        params=PARAMS,
        local_iteration=False,
        state_size=1,
        description="OpenSees ElastomericBearingPlasticity: elastic-plastic with hardening.",
        opensees=elastomeric_bearing("elastomericBearingPlasticity"),
        check=_check,
    )
)
