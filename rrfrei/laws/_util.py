"""Small Numba helpers shared by the law kernels."""

from numba import njit

DBL_EPSILON = 2.220446049250313e-16
"""C's ``DBL_EPSILON`` (2^-52), as OpenSees uses it."""


@njit(cache=True, inline="always")
def sgn(x):
    """Sign with sgn(0) = 0."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@njit(cache=True, inline="always")
def powabs(x, e):
    """|x|**e with integer exponents 1, 2, 3 specialised (no pow call)."""
    a = abs(x)
    if e == 1.0:
        return a
    if e == 2.0:
        return a * a
    if e == 3.0:
        return a * a * a
    return a**e


@njit(cache=True, inline="always")
def bearing_constants(p):
    """``(k_init, qd, k0, k2, k3, mu)`` of an elastomeric bearing's parameter row ``p = (k_init,
    qd, alpha1, alpha2, mu, ...)`` (OpenSees' ``elastomericBearing*`` arguments; kN, m):
    k0 = (1 - alpha1) k_init, k2 = alpha1 k_init, k3 = alpha2 k_init [kN/m]."""
    k_init = p[0]
    return k_init, p[1], (1.0 - p[2]) * k_init, p[2] * k_init, p[3] * k_init, p[4]


@njit(cache=True, inline="always")
def hardening(k3, mu, x):
    """``(k3 sgn(x) |x|^mu, k3 mu |x|^(mu-1))``: the nonlinear hardening force [kN] and tangent
    [kN/m] of an elastomeric bearing at displacement (component) ``x`` [m]; (0, 0) for k3 = 0."""
    if k3 == 0.0:
        return 0.0, 0.0
    return k3 * sgn(x) * powabs(x, mu), k3 * mu * powabs(x, mu - 1.0)


@njit(cache=True, inline="always")
def power_excess(k, onset, n, ex):
    """(force magnitude, tangent) ``(k u_s (e / u_s)^n / n, k (e / u_s)^(n - 1))`` of a power
    ``n`` of the excess ``e = ex > 0`` over an onset ``u_s = onset > 0``: the shape of the
    ``stiffening`` effect and, with ``k < 0``, of the smooth ``rollover``."""
    r = ex / onset
    t = r ** (n - 1.0)
    return k * onset * t * r / n, k * t


@njit(cache=True, inline="always")
def increment(i, disp, time, use_time, substeps, u_prev, t_prev):
    """(du, v, dt) of sub-increment steps into sample ``i`` (see :func:`rrfrei.laws._history.walk`).

    ``du`` is the displacement sub-increment [m], ``v`` the velocity [m/s] (0 in statics and at
    the first sample), ``dt`` the sub-step [s] (1.0 in statics, as OpenSees' pseudo-time).
    """
    du = (disp[i] - u_prev) / substeps
    if use_time:
        dt = (time[i] - t_prev) / substeps
        if i == 0 or dt <= 0.0:
            return du, 0.0, (1.0 if dt <= 0.0 else dt)
        return du, du / dt, dt
    return du, 0.0, 1.0


@njit(cache=True, inline="always")
def commit(sc, st):
    """Copy the trial state into the committed state."""
    for k in range(sc.shape[0]):
        sc[k] = st[k]


@njit(cache=True, inline="always")
def store_plan(f, k, f0, f1, k00, k01, k10, k11):
    """Write a plan step's shear forces ``f`` [kN] and 2 x 2 tangent ``k`` [kN/m], once each, at
    the step's single exit (a step that loads its arrays, computes on scalars and stores once lets
    Numba pair every array argument's reference count: ``rrfrei.laws.plan.bouc_wen``)."""
    f[0] = f0
    f[1] = f1
    k[0, 0] = k00
    k[0, 1] = k01
    k[1, 0] = k10
    k[1, 1] = k11


@njit(cache=True, inline="always")
def store_plan_state(st, u0, u1, z0, z1, q0, q1, e00, e01, e10, e11):
    """Write the first ten trial-state entries shared by the plan Bouc-Wen-type steps: trial
    displacement [m], hysteretic z [-], force [kN] and tangent offset [kN/m] (row-major)."""
    st[0] = u0
    st[1] = u1
    st[2] = z0
    st[3] = z1
    st[4] = q0
    st[5] = q1
    st[6] = e00
    st[7] = e01
    st[8] = e10
    st[9] = e11


@njit(cache=True, inline="always")
def no_run_setup(p):
    """The ``law_run_setup`` slot of a law without a fast history solver
    (:mod:`rrfrei.laws._history`): no constants."""
    return 0.0


@njit(cache=True, inline="always")
def no_run(p, ctx, sc, st, disp, k, substeps, force, tangent):
    """The ``law_run`` slot of a law without a fast history solver (:mod:`rrfrei.laws._history`):
    takes no sub-step (returns ``k``; inlined, so the loop's test of it folds away)."""
    return k
