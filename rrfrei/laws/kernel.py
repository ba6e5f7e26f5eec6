"""The single step entry point and the displacement-history driver (Numba).

``step(code, p, sc, u, v, dt, st)`` evaluates any registered law, base or augmented, given its
dispatch ``code`` (:attr:`rrfrei.laws.registry.LawSpec.code`).  Drivers (displacement histories,
Newmark, likelihoods) call only this function, so every law and effect works everywhere.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit, increment
from rrfrei.laws.dispatch import base_drive, base_step
from rrfrei.laws.effects import augmented_step


@njit(cache=True)
def step(code, p, sc, u, v, dt, st):
    """(force [kN], tangent [kN/m], status) of the law ``code`` at trial (u, v)."""
    if code[3] == 0:
        return base_step(code[0], p, sc, u, v, dt, st)
    return augmented_step(code, p, sc, u, v, dt, st)


@njit(cache=True)
def run_history(code, p, state0, disp, time, use_time, substeps, force, tangent):
    """Drive a law along a displacement history, writing ``force`` and ``tangent``.

    Parameters
    ----------
    code, p : law code and parameters.
    state0 : initial committed state (copied, not modified).
    disp : (n,) displacement [m]; ``disp[0]`` is applied to the initial state as a first step
        from zero, exactly as an OpenSees displacement-controlled analysis starting at rest.
    time : (n,) time [s], used when ``use_time``; otherwise dt = 1 and velocity 0 (statics).
    substeps : each increment is split into this many equal sub-increments.

    Returns
    -------
    (status, index) : 0 and -1 on success, else the failing status and sample index.
    """
    sc = state0.copy()
    st = state0.copy()
    return drive(code, p, sc, st, disp, time, use_time, substeps, force, tangent)


@njit(cache=True)
def drive(code, p, sc, st, disp, time, use_time, substeps, force, tangent):
    """:func:`run_history` on caller-owned state arrays.

    ``sc`` (committed) and ``st`` (trial) start as the initial state and are updated in place, so
    after a failure at sample ``index`` they hold the last committed and the failed trial state.
    A base law runs its own module's ``drive`` (same loop, its step inlined); an augmented law
    goes through :func:`step` at every sub-step.
    """
    if code[3] == 0:
        return base_drive(code[0], p, sc, st, disp, time, use_time, substeps, force, tangent)
    u_prev = 0.0
    t_prev = time[0] if use_time else 0.0
    for i in range(disp.shape[0]):
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        f = 0.0
        kt = 0.0
        for j in range(substeps):
            u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
            f, kt, status = step(code, p, sc, u, v, dt, st)
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
