"""The Newmark kernel: one template, instantiated per isolator law, condensed onto the base.

:mod:`structures.dynamics.newmark` calls the isolator law only through its slots; each law gets its own
instance (:func:`rrfrei.laws.specialise.instantiate`), so no branch over laws exists.  The
superstructure is linear and condensed onto the base DOF, so Newton is a scalar iteration there:
with a linear isolator it must converge in one correction (the second at rounding level).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import ground_motions
import structures
from rrfrei import laws
from rrfrei.laws import specialise
from structures.dynamics import history, newmark


def test_the_template_itself_runs_no_law():
    with pytest.raises(RuntimeError, match="not bound"):
        newmark.law_step(np.zeros(2), np.zeros(0), 0.0, 0.0, 1.0, np.zeros(0))


@pytest.mark.parametrize("law", laws.names())
def test_each_law_runs_in_its_own_instance_bound_to_its_own_step(law):
    spec = laws.get(law)
    kernel = history.kernel(spec)
    bound = specialise.bindings(spec)
    assert kernel.law_step is bound["law_step"]
    assert kernel.law_step_robust is bound["law_step_robust"]
    assert kernel is history.kernel(spec)  # one instance per law and process
    others = [history.kernel(laws.get(n)) for n in laws.names() if n != law]
    assert all(kernel is not other for other in others)


def test_a_linear_isolator_converges_in_one_correction_per_step():
    """The base residual after a correction is k_t du_0 - dF = 0 for a linear spring, so the
    second correction is at rounding level and ends every step (the first ends a step at rest)."""
    b = structures.load_building("three_story")
    b = replace(b, isolator=structures.Isolator("linear", {"k": 4000.0}, 4, 1.0))
    r = ground_motions.load("elcentro").with_leading_zero()
    rec = ground_motions.Record(r.name, r.dt, r.accel[:1001], r.meta)
    out = structures.time_history(b, rec)
    assert np.abs(out.isolator_disp).max() > 1e-3  # it moved
    assert set(np.unique(out.newton_iterations[1:])) <= {1, 2}
    assert (out.newton_iterations[1:] == 2).mean() > 0.9
    assert out.energy_error < 1e-12
