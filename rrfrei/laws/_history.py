"""Template of a law's whole-history driver: the one time loop of a unidirectional law.

Slots (bound per law by :func:`rrfrei.laws.specialise.history`):

* ``law_step``: the local solver, ``(p, sc, u, v, dt, st) -> (force, tangent, status)``
  (contract in :mod:`rrfrei.laws.registry`): the law's step, or its robust local solve
  (``LawSpec.step_robust``) for ``local_solver="robust"``;
* ``law_run`` and ``law_run_setup``: an optional fast solver for whole histories
  (``LawSpec.fast_run`` / ``LawSpec.fast_setup``, Bouc-Wen's :mod:`rrfrei.laws._bouc_wen_fast`),
  tried before every sub-step: ``law_run(p, ctx, sc, st, disp, k, substeps, force, tangent)``
  advances from the flat sub-step index ``k`` (sample ``k // substeps``) as far as it certifies
  its result to be the step's own, writes the forces and tangents of the samples it completes,
  commits its last sub-step and returns the index of the first sub-step it leaves to
  ``law_step`` (``k`` itself when it takes none, -1 when it will take none in this history:
  it is then not called again); ``ctx = law_run_setup(p)`` holds its constants.  A law
  without one binds :func:`rrfrei.laws._util.no_run` (returns ``k``: inlined, the test folds
  away and the loop is the plain one).

Each instance inlines its law's step in the loop, which is about twice as fast as calling a law
through a dispatch at every step (``benchmarks/bench_laws.py``).  A law thus has two instances:
the step bound to ``LawSpec.step`` (:func:`drive`) and to ``LawSpec.step_robust``
(:func:`drive_robust`), the same loop.
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit, increment
from rrfrei.laws.specialise import unbound

SLOTS = ("law_step", "law_run", "law_run_setup")
law_step = unbound("law_step")
law_run = unbound("law_run")
law_run_setup = unbound("law_run_setup")


@njit(cache=True, error_model="numpy")
def walk(p, sc, st, disp, time, use_time, substeps, force, tangent, deviated):
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
    deviated : int64, (n,) or (0,).  With n entries a positive status of ``law_step`` (a robust
        local solve acted, a deviation from OpenSees) is accepted and marks its sample (1 there,
        0 elsewhere); empty, a positive status fails like a negative one.

    Returns
    -------
    (status, index) : 0 and -1 on success, else the failing status and sample index.
    """
    for i in range(deviated.shape[0]):
        deviated[i] = 0
    ctx = law_run_setup(p)
    n = disp.shape[0]
    u_prev = 0.0
    t_prev = time[0] if use_time else 0.0
    i = 0
    j = 0
    kr = 0
    run = True  # the fast solver may take sub-steps (-1 from it: not in this history)
    ran = False  # the fast solver stopped at sub-step (i, j): the step takes it
    while i < n:
        du, v, dt = increment(i, disp, time, use_time, substeps, u_prev, t_prev)
        f = 0.0
        kt = 0.0
        done = True
        j0 = j
        for j in range(j0, substeps):
            if ran:
                ran = False
            elif run:
                k = i * substeps + j
                kr = law_run(p, ctx, sc, st, disp, k, substeps, force, tangent)
                if kr != k:
                    if kr < 0:
                        run = False
                    else:
                        ran = True
                        done = False
                        break
            u = disp[i] if j == substeps - 1 else u_prev + du * (j + 1)
            f, kt, status = law_step(p, sc, u, v, dt, st)
            if status != 0:
                if status > 0 and deviated.shape[0] > 0:
                    deviated[i] = 1
                else:
                    return status, i
            if not (np.isfinite(f) and np.isfinite(kt)):
                return -3, i
            commit(sc, st)
        if done:
            force[i] = f
            tangent[i] = kt
            u_prev = disp[i]
            if use_time:
                t_prev = time[i]
            i += 1
            j = 0
        else:  # the fast solver took sub-steps k .. kr - 1
            i = kr // substeps
            j = kr - i * substeps
            u_prev = disp[i - 1] if i > 0 else 0.0
            t_prev = (time[i - 1] if i > 0 else time[0]) if use_time else 0.0
    return 0, -1


@njit(cache=True, error_model="numpy")
def drive(p, sc, st, disp, time, use_time, substeps, force, tangent):
    """:func:`walk` without deviations: ``(p, sc, st, disp, time, use_time, substeps, force,
    tangent) -> (status, index)``, the contract of every whole-history driver."""
    return walk(p, sc, st, disp, time, use_time, substeps, force, tangent,
                np.zeros(0, dtype=np.int64))


@njit(cache=True, error_model="numpy")
def drive_robust(p, sc, st, disp, time, use_time, substeps, force, tangent, deviated):
    """:func:`walk` with ``deviated`` (int64, n): 1 at every sample where the robust local solve
    acted in one of its sub-steps, 0 elsewhere.  Same return contract as :func:`drive`."""
    return walk(p, sc, st, disp, time, use_time, substeps, force, tangent, deviated)
