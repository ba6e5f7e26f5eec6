"""A tiny coupled plan law for the plan-building tests: the toy bilinear spring made radial.

The unidirectional toy (``tests/_toy_law.py``, ``toy_bilinear``) acts on the length of the
displacement in plan, along its direction:

    a = |u|,   F = g(a) u / a,   g(a) = k a                      for a <= d_b
                                 g(a) = k d_b + r k (a - d_b)    beyond

a nonlinear elastic spring that is isotropic (a rotated path gives the rotated force) and
couples the two axes beyond d_b (its tangent r k n n^T + (g / a)(I - n n^T), n = u / a, is not
diagonal off the axes).  Along one axis it is ``toy_bilinear`` bit for bit (u / a = +-1
exactly).  State: ``[u_max]``, the largest |u| in plan (it does not change the force).
Registered in :mod:`rrfrei.laws.plan` under ``toy_bilinear`` when imported.
"""

import math

import _toy_law  # noqa: F401  (registers the unidirectional law: the parameters)
from numba import njit

from rrfrei.laws.plan import PlanLawSpec, register


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st, f, k):
    """Force (2,) [kN] and tangent (2, 2) [kN/m] of the radial bilinear spring; status 0."""
    kk = p[0]
    r = p[1]
    db = p[2]
    a = math.sqrt(u[0] * u[0] + u[1] * u[1])
    st[0] = max(sc[0], a)
    if a <= db:
        for i in range(2):
            f[i] = kk * u[i]
            for j in range(2):
                k[i, j] = kk if i == j else 0.0
        return 0
    g = kk * db + r * kk * (a - db)
    secant = g / a
    for i in range(2):
        ni = u[i] / a
        f[i] = g * ni
        for j in range(2):
            nn = ni * (u[j] / a)
            k[i, j] = r * kk * nn + secant * ((1.0 if i == j else 0.0) - nn)
    return 0


SPEC = register(PlanLawSpec(name="toy_bilinear", step=step, state_size=1,
                            description="Toy radial bilinear elastic spring in plan (tests)."))
