"""The Newmark options have one home (structures.dynamics.history.solver_settings): the 1-D and
plan time-history verbs take the same names with the same defaults, and a misspelt option is
named in a ValueError instead of being ignored."""

from __future__ import annotations

import numpy as np
import pytest

import ground_motions
import structures
from structures.dynamics.history import NEWMARK_OPTIONS, solver_settings

DEFAULTS = dict(gamma=0.5, beta=0.25, tol=1e-12, max_iter=50, max_subdivisions=6)


@pytest.fixture(scope="module")
def case():
    b = structures.load_building("three_story")
    r = ground_motions.load("elcentro")
    n = 400
    return b, ground_motions.Record("cut", r.dt, np.asarray(r.accel[:n])), np.column_stack(
        [r.accel[:n], 0.5 * np.asarray(r.accel[:n])]), r.dt


def test_the_defaults_are_the_settings_of_the_standard_average_acceleration_step():
    s = solver_settings()
    assert tuple(s) == (0.5, 0.25, 1e-12, 50, 6, False)  # gamma, beta, tol, max_iter, levels, robust
    assert set(DEFAULTS) == set(NEWMARK_OPTIONS)


def test_every_verb_runs_the_same_with_the_defaults_spelt_out(case):
    b, rec, pair, dt = case
    a, c = structures.time_history(b, rec), structures.time_history(b, rec, **DEFAULTS)
    np.testing.assert_array_equal(a.isolator_disp, c.isolator_disp)
    P = b.isolator.packed()[None, :]
    np.testing.assert_array_equal(structures.time_history_batch(b, rec, P)["iso_disp_peak"],
                                  structures.time_history_batch(b, rec, P, **DEFAULTS)["iso_disp_peak"])
    pa = structures.plan_time_history(b, ground=pair, dt=dt)
    pc = structures.plan_time_history(b, ground=pair, dt=dt, **DEFAULTS)
    np.testing.assert_array_equal(pa.isolator_plan_disp, pc.isolator_plan_disp)


@pytest.mark.parametrize("verb", ["time_history", "time_history_batch", "plan_time_history",
                                  "plan_time_history_batch"])
def test_a_misspelt_option_is_named(case, verb):
    b, rec, pair, dt = case
    P = b.isolator.packed()[None, :]
    args = {"time_history": (b, rec), "time_history_batch": (b, rec, P),
            "plan_time_history": (b, None, None, pair),
            "plan_time_history_batch": (b, None, None, pair)}[verb]
    kw = {"dt": dt} if verb.startswith("plan") else {}
    with pytest.raises(ValueError, match=r"unknown option\(s\) 'max_iters'.*max_iter"):
        getattr(structures, verb)(*args, max_iters=3, **kw)
    with pytest.raises(ValueError, match=r"max_iter = 0 is invalid"):
        getattr(structures, verb)(*args, max_iter=0, **kw)
