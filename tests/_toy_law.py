"""A toy law defined in one module with one registry entry (issue 13.1: "a law is added in one
place"): a bilinear elastic spring that also records the largest |u| it has seen.

    F = k u                                   for |u| <= d_b
    F = sgn(u) (k d_b + r k (|u| - d_b))      beyond

``k`` [kN/m], ``r`` [-] post-break stiffness ratio, ``d_b`` [m] break displacement.
State: ``[u_max]`` [m], the largest |u| reached (it does not change the force).
Nothing else in the repository names this law: ``tests/test_toy_law.py`` runs it through
``simulate_force``, ``calibrate``, ``time_history`` and ``propagate``.
"""

from numba import njit

from rrfrei.laws import LawSpec, ParamSpec, Prior, register

NAME = "toy_bilinear"


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    """Bilinear elastic force [kN], tangent [kN/m] and status (contract of the registry)."""
    k = p[0]
    r = p[1]
    db = p[2]
    a = abs(u)
    st[0] = max(sc[0], a)
    if a <= db:
        return k * u, k, 0
    s = 1.0 if u > 0.0 else -1.0
    return s * (k * db + r * k * (a - db)), r * k, 0


SPEC = register(
    LawSpec(
        name=NAME,
        step=step,
        params=(
            ParamSpec("k", "kN/m", 1e-6, 1e9, "initial stiffness", Prior("loguniform", 1.0, 1e6)),
            ParamSpec("r", "-", 0.0, 1.0, "post-break stiffness ratio", default=0.3),
            ParamSpec("d_b", "m", 1e-6, 10.0, "break displacement", default=0.005),
        ),
        state_size=1,
        description="Toy bilinear elastic spring (tests of the law table).",
        local_iteration=False,
    )
)
