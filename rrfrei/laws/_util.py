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
