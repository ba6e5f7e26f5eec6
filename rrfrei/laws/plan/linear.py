"""Isotropic linear spring with an optional linear dashpot, in plan (tests and linear checks).

    F = k u + c v     (each horizontal axis; no coupling)

``k`` [kN/m], ``c`` [kN s/m]; the tangent is (k + c/dt) I, as the unidirectional
:mod:`rrfrei.laws.linear`.
"""

from numba import njit

from rrfrei.laws.plan.registry import PlanLawSpec, register


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st, f, k):
    kk = p[0]
    c = p[1]
    for a in range(2):
        f[a] = kk * u[a] + c * v[a]
        for b in range(2):
            k[a, b] = kk + c / dt if a == b else 0.0
    return 0


SPEC = register(PlanLawSpec(name="linear", step=step, state_size=0,
                            description="Isotropic linear spring F = k u + c v in plan."))
