"""Small Numba helpers shared by the law kernels."""

from numba import njit


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
def increment(i, disp, time, use_time, substeps, u_prev, t_prev):
    """(du, v, dt) of sub-increment steps into sample ``i`` (see :func:`rrfrei.laws._history.drive`).

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
