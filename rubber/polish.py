"""The least-squares polish of the rubber fits: scipy's ``trf`` on the unit box, keeping the best
point it evaluated, with an evaluation cap or clock (``stop``) and one BLAS thread."""

from __future__ import annotations

import math

import numpy as np

from rrfrei.blas import one_blas_thread

__all__ = ["least_squares_best"]


def least_squares_best(fun, x0: np.ndarray, *, start_cost: float = math.inf, stop=None, **kw):
    """``scipy.optimize.least_squares`` on the unit box that keeps the best point it evaluated.

    Every evaluation counts (finite-difference Jacobians included); ``stop(n)``, asked before each
    one with the number done so far, ends the search when it returns True (an evaluation budget,
    a clock).  The best point seen is returned, or ``x0`` when none beats ``start_cost`` (the
    cost 2 f = r.r already known at ``x0``; trf moves a start on a bound inside before evaluating).

    Returns
    -------
    (x, cost, evaluations) : best point, its r.r, number of evaluations made.
    """
    from scipy.optimize import least_squares

    seen = {"n": 0, "c": float(start_cost), "x": x0}

    class _Stop(Exception):
        pass

    def f(x):
        if stop is not None and stop(seen["n"]):
            raise _Stop
        seen["n"] += 1
        r = fun(x)
        c = float(r @ r)
        if c < seen["c"]:
            seen["c"], seen["x"] = c, np.array(x, dtype=float)
        return r

    try:
        with one_blas_thread():  # trf's SVD of a thin Jacobian: one thread is far faster on shared cores
            least_squares(f, x0, bounds=(0.0, 1.0), **kw)
    except _Stop:
        pass
    return seen["x"], seen["c"], seen["n"]
