"""Linear spring with an optional linear dashpot, for tests and linear checks.

    F = k u + c v

``k`` [kN/m], ``c`` [kN s/m].  The tangent returned is k + c/dt (velocity taken as the
backward difference over the step, as OpenSees does for element dashpots in statics).
"""

from numba import njit

from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    k = p[0]
    c = p[1]
    return k * u + c * v, k + c / dt, 0


SPEC = register(
    LawSpec(
        name="linear",
        step=step,
        params=(
            ParamSpec("k", "kN/m", 0.0, 1e9, "elastic stiffness", Prior("loguniform", 1.0, 1e7)),
            ParamSpec("c", "kN*s/m", 0.0, 1e9, "viscous coefficient", default=0.0),
        ),
        local_iteration=False,
        state_size=0,
        description="Linear spring F = k u + c v (tests and linear checks).",
        uses_velocity=True,
    )
)
