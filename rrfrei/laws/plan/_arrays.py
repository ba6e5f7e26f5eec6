"""Template of the carrier of a plan law's array step kernel (``PlanLawSpec.step``) through the
history loop (:mod:`rrfrei.laws.plan._history`): the state stays in the arrays ``sc`` and
``st``, and committing copies ``st`` into ``sc``.

Slots (bound per law by :func:`rrfrei.laws.plan.registry.driver`): ``plan_step``, the law's
step kernel (contract in :mod:`rrfrei.laws.plan.registry`); the constants ``plan_static_calls``,
the number of times (1 or 2) it is called per step, and ``plan_settled_index``, the state entry
that says a second call would change nothing (``PlanLawSpec.static_calls`` and
``.settled_index``).

OpenSees' static displacement-controlled analysis of the 3-D element (``tests/opensees_plan.py``)
updates the element twice per step: once in ``LoadControl::newStep`` and once more after the
first ``Newton`` correction (zero on the imposed shear DOFs, after which ``NormDispIncr`` is met).
A law whose step starts from the current trial state (a local iteration from the trial z, as
``ElastomericBearingBoucWen3d::update``) can move in that second call by rounding, or fail in
it; such a law sets ``static_calls = 2`` and is called twice here, with the same displacement,
the trial state of the first call carried into the second (skipped when the first call flags its
result as settled: the second would repeat it bit for bit).
"""

import numpy as np
from numba import njit

from rrfrei.laws._util import commit as _copy
from rrfrei.laws.specialise import unbound

SLOTS = ("plan_step", "plan_static_calls", "plan_settled_index")
plan_step = unbound("plan_step")
plan_static_calls = 1  # constants bound per law: Numba folds the branches below
plan_settled_index = -1


@njit(cache=True, inline="always")
def begin(p, sc, st):
    """Work arrays (u, v, f, k) and the state arrays in the constants; the carried state is a
    placeholder (0.0: nothing to carry, no reference counts in the loop)."""
    return (np.zeros(2), np.zeros(2), np.zeros(2), np.zeros((2, 2)), sc, st), 0.0


@njit(cache=True, inline="always")
def update(p, ctx, cs, u0, u1, v0, v1, dt):
    """One step of the law from the committed state ``sc`` into the trial state ``st``
    (twice with ``plan_static_calls = 2``, unless the first call is settled)."""
    ctx[0][0] = u0
    ctx[0][1] = u1
    ctx[1][0] = v0
    ctx[1][1] = v1
    status = plan_step(p, ctx[4], ctx[0], ctx[1], dt, ctx[5], ctx[2], ctx[3])
    if plan_static_calls == 2 and status == 0:  # OpenSees' second update() of the step
        if plan_settled_index < 0 or ctx[5][plan_settled_index] == 0.0:
            status = plan_step(p, ctx[4], ctx[0], ctx[1], dt, ctx[5], ctx[2], ctx[3])
    f = ctx[2]
    k = ctx[3]
    return status, cs, f[0], f[1], k[0, 0], k[0, 1], k[1, 0], k[1, 1]


@njit(cache=True, inline="always")
def commit(ctx, ts):
    """Copy the trial state into the committed state."""
    _copy(ctx[4], ctx[5])
    return ts


@njit(cache=True, inline="always")
def end(sc, st, ctx, cs, ts):
    """Nothing to write: the state lives in the arrays."""
    return None
