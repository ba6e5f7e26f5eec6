"""Template of a law's whole-history drivers: one time loop, instantiated per law.

Slots (bound per law by :func:`rrfrei.laws.specialise.history`): ``law_step`` and
``law_step_robust``, the law's step kernels (contract in :mod:`rrfrei.laws.registry`).  Each
instance inlines its law's step in the loop, which is about twice as fast as calling a law
through a dispatch at every step (``benchmarks/bench_laws.py``).  A law may override these
drivers in its registry entry (``LawSpec.drive``, ``LawSpec.drive_robust``), as Bouc-Wen does
with its fast solver; the contract is the same.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit, increment
from rrfrei.laws.specialise import unbound

SLOTS = ("law_step", "law_step_robust")
law_step = unbound("law_step")
law_step_robust = unbound("law_step_robust")


@njit(cache=True, error_model="numpy")
def drive(p, sc, st, disp, time, use_time, substeps, force, tangent):
    """Drive the law along a displacement history, writing ``force`` [kN] and ``tangent`` [kN/m].

    Parameters
    ----------
    p : the law's parameters (kN, m, s).
    sc, st : committed and trial state, both the initial state on entry; updated in place, so
        after a failure at sample ``index`` they hold the last committed and the failed trial
        state.
    disp : (n,) displacement [m]; ``disp[0]`` is applied to the initial state as a first step
        from zero, exactly as an OpenSees displacement-controlled analysis starting at rest.
    time : (n,) time [s], used when ``use_time``; otherwise dt = 1 and velocity 0 (statics).
    substeps : each increment is split into this many equal sub-increments.

    Returns
    -------
    (status, index) : 0 and -1 on success, else the failing status and sample index.
    """
    u_prev = 0.0
    t_prev = time[0] if use_time else 0.0
    for i in range(disp.shape[0]):
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        f = 0.0
        kt = 0.0
        for j in range(substeps):
            u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
            f, kt, status = law_step(p, sc, u, v, dt, st)
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


@njit(cache=True, error_model="numpy")
def drive_robust(p, sc, st, disp, time, use_time, substeps, force, tangent, deviated):
    """:func:`drive` with ``law_step_robust``: a positive status (the robust local solve acted,
    a deviation from OpenSees) is accepted and marks the sample in ``deviated`` (int64, n: 1
    there, 0 elsewhere).  Same return contract."""
    for i in range(deviated.shape[0]):
        deviated[i] = 0
    u_prev = 0.0
    t_prev = time[0] if use_time else 0.0
    for i in range(disp.shape[0]):
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        f = 0.0
        kt = 0.0
        for j in range(substeps):
            u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
            f, kt, status = law_step_robust(p, sc, u, v, dt, st)
            if status > 0:
                deviated[i] = 1
            elif status != 0:
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
