"""Template of a plan law's whole-history driver: the one time loop of the plan laws.

Slots (bound per law by :func:`rrfrei.laws.plan.registry.driver`): the law's local solver in the
form the loop carries it, ``plan_begin``, ``plan_update``, ``plan_commit`` and ``plan_end``::

    ctx, cs = plan_begin(p, sc, st)           constants and the committed state, as carried
    (status, ts, f0, f1, k00, k01, k10, k11) = plan_update(p, ctx, cs, u0, u1, v0, v1, dt)
                                              one step from the committed state: the trial
                                              state, forces [kN] and tangent [kN/m]
    cs = plan_commit(ctx, ts)                 the trial state committed
    plan_end(sc, st, ctx, cs, ts)             the carried states written back to the arrays

A law with only an array step kernel (``PlanLawSpec.step``) is carried by the adapter
:mod:`rrfrei.laws.plan._arrays` (the state stays in ``sc`` and ``st``; committing copies); a law
may carry its state in scalars instead (``PlanLawSpec.carrier``, Bouc-Wen's
:mod:`rrfrei.laws.plan.bouc_wen`: no loads and stores around each step), with the same results
bit for bit.  The step is that of OpenSees' static displacement-controlled analysis of the 3-D
element (``tests/opensees_plan.py``), whose two ``update()`` calls per step
(``PlanLawSpec.static_calls``) are the local solver's business.
"""

import numpy as np
from numba import njit

from rrfrei.laws.plan.registry import NONFINITE_DISP
from rrfrei.laws.specialise import unbound

SLOTS = ("plan_begin", "plan_update", "plan_commit", "plan_end")
plan_begin = unbound("plan_begin")
plan_update = unbound("plan_update")
plan_commit = unbound("plan_commit")
plan_end = unbound("plan_end")


@njit(cache=True)
def first_nonfinite(disp):
    """Index of the first sample of the (n, 2) history ``disp`` with a non-finite component, or
    -1.  One pass that LLVM vectorizes (x - x == 0 exactly for finite x: an AND of comparisons),
    then, only where it fails, the search for the sample."""
    ok = True
    for i in range(disp.shape[0]):
        ok &= (disp[i, 0] - disp[i, 0] == 0.0) & (disp[i, 1] - disp[i, 1] == 0.0)
    if ok:
        return -1
    for i in range(disp.shape[0]):
        if not (np.isfinite(disp[i, 0]) and np.isfinite(disp[i, 1])):
            return i
    return -1


@njit(cache=True, error_model="numpy")
def drive(p, sc, st, disp, time, use_time, substeps, force, tangent):
    """Drive the law along a two-component displacement history.

    Parameters
    ----------
    p, sc, st, time, use_time, substeps : as for the unidirectional loop
        (:func:`rrfrei.laws._history.walk`).
    disp : (n, 2) displacement [m]; ``disp[0]`` is applied to the virgin state as a first step
        from zero, as an OpenSees displacement-controlled analysis starting at rest.
    force : (n, 2) output shear forces [kN].
    tangent : (n, 2, 2) output tangent [kN/m].

    Returns
    -------
    (status, index) : 0 and -1 on success, else the failing status and sample index
        (``NONFINITE_DISP`` and the first non-finite sample of ``disp``, before any step).
    """
    bad = first_nonfinite(disp)
    if bad >= 0:
        return NONFINITE_DISP, bad
    ctx, cs = plan_begin(p, sc, st)
    t_prev = time[0] if use_time else 0.0
    up0 = 0.0
    up1 = 0.0
    for i in range(disp.shape[0]):
        x0 = disp[i, 0]
        x1 = disp[i, 1]
        dt = 1.0
        if use_time:
            dt = (time[i] - t_prev) / substeps
            if dt <= 0.0:
                dt = 1.0
        dp0 = (x0 - up0) / substeps
        dp1 = (x1 - up1) / substeps
        v0 = dp0 / dt if (use_time and i > 0) else 0.0
        v1 = dp1 / dt if (use_time and i > 0) else 0.0
        f0 = f1 = k00 = k01 = k10 = k11 = 0.0
        for j in range(substeps):
            u0 = x0
            u1 = x1
            if j != substeps - 1:
                u0 = up0 + dp0 * (j + 1)
                u1 = up1 + dp1 * (j + 1)
            status, ts, f0, f1, k00, k01, k10, k11 = plan_update(p, ctx, cs, u0, u1, v0, v1, dt)
            # f and k finite: x * 0 is 0 for every finite x, NaN for an infinity or NaN
            if status != 0 or not (f0 * 0.0 + f1 * 0.0 + k00 * 0.0 + k01 * 0.0 + k10 * 0.0
                                   + k11 * 0.0 == 0.0):
                plan_end(sc, st, ctx, cs, ts)
                return (status if status != 0 else -3), i
            cs = plan_commit(ctx, ts)
        force[i, 0] = f0
        force[i, 1] = f1
        tangent[i, 0, 0] = k00
        tangent[i, 0, 1] = k01
        tangent[i, 1, 0] = k10
        tangent[i, 1, 1] = k11
        up0 = x0
        up1 = x1
        if use_time:
            t_prev = time[i]
    plan_end(sc, st, ctx, cs, cs)
    return 0, -1
