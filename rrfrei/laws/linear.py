"""Linear spring with an optional linear dashpot, for tests and linear checks.

    F = k u + c v

``k`` [kN/m], ``c`` [kN s/m].  The tangent returned is k + c/dt (velocity taken as the
backward difference over the step, as OpenSees does for element dashpots in statics).
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit, increment
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register

KERNEL_ID = 0


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    k = p[0]
    c = p[1]
    return k * u + c * v, k + c / dt, 0


@njit(cache=True, error_model="numpy")
def drive(p, sc, st, disp, time, use_time, substeps, force, tangent):
    """Whole-history driver of this law (contract of :func:`rrfrei.laws.kernel.drive`)."""
    u_prev = 0.0
    t_prev = time[0] if use_time else 0.0
    for i in range(disp.shape[0]):
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        f = 0.0
        kt = 0.0
        for j in range(substeps):
            u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
            f, kt, status = step(p, sc, u, v, dt, st)
            if status != 0:
                return status, i
            if not (np.isfinite(f) and np.isfinite(kt)):
                return -3, i
            commit(sc, st)
        force[i] = f
        tangent[i] = kt
        u_prev = disp[i]
        if use_time:
            t_prev = time[i]
    return 0, -1


SPEC = register(
    LawSpec(
        name="linear",
        kernel_id=KERNEL_ID,
        params=(
            ParamSpec("k", "kN/m", 0.0, 1e9, "elastic stiffness", Prior("loguniform", 1.0, 1e7)),
            ParamSpec("c", "kN*s/m", 0.0, 1e9, "viscous coefficient", default=0.0),
        ),
        state_size=0,
        description="Linear spring F = k u + c v (tests and linear checks).",
        uses_velocity=True,
    )
)
