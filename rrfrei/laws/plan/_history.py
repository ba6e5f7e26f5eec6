"""Template of a plan law's whole-history driver: one time loop, instantiated per law.

Slots (bound per law by :func:`rrfrei.laws.plan.registry.driver`): ``plan_step``, the law's step
kernel (contract in :mod:`rrfrei.laws.plan.registry`); the constants ``plan_static_calls``, the
number of times (1 or 2) it is called per step, and ``plan_settled_index``, the state entry that
says a second call would change nothing (``PlanLawSpec.static_calls`` and ``.settled_index``).

Each sample is one step of OpenSees' static displacement-controlled analysis of the 3-D element
(``tests/opensees_plan.py``), which updates the element twice: once in ``LoadControl::newStep``
and once more after the first ``Newton`` correction (zero on the imposed shear DOFs, after which
``NormDispIncr`` is met).  A law whose step starts from the current trial state (a local
iteration from the trial z, as ``ElastomericBearingBoucWen3d::update``) can move in that second
call by rounding, or fail in it; such a law sets ``static_calls = 2`` and is called twice here,
with the same displacement, the trial state of the first call carried into the second (skipped
when the first call flags its result as settled: the second would repeat it bit for bit).
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit
from rrfrei.laws.plan.registry import NONFINITE_DISP
from rrfrei.laws.specialise import unbound

SLOTS = ("plan_step", "plan_static_calls", "plan_settled_index")
plan_step = unbound("plan_step")
plan_static_calls = 1  # constants bound per law: Numba folds the branches below
plan_settled_index = -1


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
    p : the law's parameters (kN, m, s).
    sc, st : committed and trial state, both the initial state on entry; updated in place.
    disp : (n, 2) displacement [m]; ``disp[0]`` is applied to the virgin state as a first step
        from zero, as an OpenSees displacement-controlled analysis starting at rest.
    time : (n,) time [s], used when ``use_time``; otherwise dt = 1 and velocity 0 (statics).
    substeps : each increment is split into this many equal sub-increments.
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
    u = np.zeros(2)
    v = np.zeros(2)
    u_prev = np.zeros(2)
    du = np.zeros(2)
    f = np.zeros(2)
    k = np.zeros((2, 2))
    t_prev = time[0] if use_time else 0.0
    for i in range(disp.shape[0]):
        dt = 1.0
        if use_time:
            dt = (time[i] - t_prev) / substeps
            if dt <= 0.0:
                dt = 1.0
        for a in range(2):
            du[a] = (disp[i, a] - u_prev[a]) / substeps
            v[a] = du[a] / dt if (use_time and i > 0) else 0.0
        for j in range(substeps):
            for a in range(2):
                u[a] = disp[i, a] if j == substeps - 1 else u_prev[a] + du[a] * (j + 1)
            status = plan_step(p, sc, u, v, dt, st, f, k)
            if plan_static_calls == 2 and status == 0:  # OpenSees' second update() of the step
                if plan_settled_index < 0 or st[plan_settled_index] == 0.0:
                    status = plan_step(p, sc, u, v, dt, st, f, k)
            if status != 0:
                return status, i
            if not (np.isfinite(f[0]) and np.isfinite(f[1]) and np.isfinite(k[0, 0])
                    and np.isfinite(k[0, 1]) and np.isfinite(k[1, 0]) and np.isfinite(k[1, 1])):
                return -3, i
            commit(sc, st)
        for a in range(2):
            force[i, a] = f[a]
            u_prev[a] = disp[i, a]
            for b in range(2):
                tangent[i, a, b] = k[a, b]
        if use_time:
            t_prev = time[i]
    return 0, -1
