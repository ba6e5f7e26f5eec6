"""The tangent check shared by the effect tests: within one step from a committed history, the
kernel's tangent dF/du is the derivative of its own force (a central difference)."""

from __future__ import annotations

import numpy as np
import pytest


def committed_after(spec, p, path):
    """(committed, trial) state of ``spec`` after the quasi-static displacement ``path`` [m]
    from its virgin state, every step committed (status asserted 0)."""
    sc = np.array(spec.initial_state, dtype=float)
    stt = sc.copy()
    for u in path:
        assert spec.step(p, sc, u, 0.0, 1.0, stt)[2] == 0
        sc[:] = stt
    return sc, stt


def assert_tangent_is_the_derivative(spec, p, path, trials, *, h: float, rel: float,
                                     dt: float | None = 0.05, abs_: float = 1e-6) -> None:
    """After committing ``path`` [m], at each trial displacement of ``trials`` [m] the tangent
    [kN/m] of ``spec.step`` equals (F(u + h) - F(u - h)) / 2h to ``rel`` (and ``abs_``).  The
    step lasts ``dt`` [s] with the velocity of the increment from the last committed sample, or,
    with ``dt=None``, is static (v = 0, dt = 1)."""
    sc, stt = committed_after(spec, p, path)

    def force_tangent(u):
        v, step = (0.0, 1.0) if dt is None else ((u - path[-1]) / dt, dt)
        f, k, _ = spec.step(p, sc, u, v, step, stt.copy())
        return f, k

    for u in trials:
        _, k = force_tangent(u)
        fp, _ = force_tangent(u + h)
        fm, _ = force_tangent(u - h)
        assert k == pytest.approx((fp - fm) / (2 * h), rel=rel, abs=abs_), f"at u = {u} m"
