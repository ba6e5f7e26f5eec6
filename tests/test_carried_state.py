"""State carried between tests (issue 15 point 5): a bearing does not reset between runs.

``ShearTest.after(*earlier)`` names the runs a specimen went through before a test; the gap
engine's model simulates them first and scores only the test's own samples.
"""

import dataclasses

import numpy as np
import pytest

from rrfrei.gap.isolator import IsolatorFit, IsolatorModel, _simulate
from rrfrei.io import ShearTest, concat_tests
from rrfrei.laws import get
from rrfrei.laws.specialise import history

PL = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}


def _run(name, amp, cycles=2, n=200, t0=0.0, dt=0.01, has_time=True, geometry=None, shift=0.0):
    t = t0 + dt * np.arange(cycles * n + 1)
    u = amp * np.sin(2 * np.pi * np.arange(cycles * n + 1) / n) + shift
    f = 100.0 * u
    return ShearTest(name, t, u, f, has_time=has_time, geometry=geometry or {})


RUN1 = _run("run1", 0.04, t0=5.0)
RUN2 = _run("run2", 0.02, t0=0.0, dt=0.02)


def _old_simulate(spec, p, test):
    """The simulation of a test from a virgin state (the code before ``preceding``)."""
    F, T = np.empty(len(test)), np.empty(len(test))
    sc = np.array(spec.initial_state, dtype=float)
    status, _ = history(spec)(p, sc, sc.copy(), test.disp, test.time, bool(test.has_time), 1, F, T)
    assert status == 0
    return F


# --- ShearTest.after and concat_tests ----------------------------------------------------------
def test_concat_joins_samples_with_time_shifted_by_one_step_after_the_previous_part():
    c = concat_tests([RUN1, RUN2])
    assert len(c) == len(RUN1) + len(RUN2) and c.name == "run1+run2"
    np.testing.assert_array_equal(c.disp, np.concatenate([RUN1.disp, RUN2.disp]))
    np.testing.assert_array_equal(c.force, np.concatenate([RUN1.force, RUN2.force]))
    np.testing.assert_array_equal(c.time[: len(RUN1)], RUN1.time)
    assert c.time[len(RUN1)] == pytest.approx(RUN1.time[-1] + 0.02)  # the next part's own step
    np.testing.assert_allclose(np.diff(c.time[len(RUN1):]), 0.02)
    assert c.has_time and c.meta["parts"] == [("run1", len(RUN1)), ("run2", len(RUN2))]
    assert concat_tests([RUN1, RUN2], name="both").name == "both"


def test_concat_has_time_only_when_every_part_has_it():
    c = concat_tests([RUN1, _run("static", 0.01, has_time=False)])
    assert not c.has_time
    np.testing.assert_array_equal(c.time, np.arange(len(c), dtype=float))


def test_concat_merges_geometry_and_refuses_disagreeing_geometry_or_non_tests():
    a = _run("a", 0.01, geometry={"d2": 0.08, "tr": 0.002})
    b = _run("b", 0.01, geometry={"d2": 0.08, "n": 15})
    assert concat_tests([a, b]).geometry == {"d2": 0.08, "tr": 0.002, "n": 15.0}
    c = _run("c", 0.01, geometry={"d2": 0.1})
    with pytest.raises(ValueError, match=r"geometry of test 'c' disagrees with test 'a': d2 = 0.1 m"):
        concat_tests([a, c])
    with pytest.raises(ValueError, match="non-empty sequence of ShearTest"):
        concat_tests([])
    with pytest.raises(ValueError, match=r"tests\[1\] must be a ShearTest, got ndarray"):
        concat_tests([a, np.zeros(3)])
    with pytest.raises(ValueError, match=r"geometry of test 'a' disagrees"):
        a.after(c)


def test_after_records_earlier_runs_flattened_in_order_and_leaves_the_test_unchanged():
    run3 = _run("run3", 0.01)
    later = run3.after(RUN2.after(RUN1))
    assert [t.name for t in later.preceding] == ["run1", "run2"]
    assert all(not t.preceding for t in later.preceding)
    assert run3.preceding == () and RUN2.preceding == ()
    assert later.disp is run3.disp  # same samples, shared read-only arrays
    assert list(later.to_frame().columns) == ["time_s", "disp_m", "force_kN"]
    assert "preceding" not in repr(later)
    assert not any(f.compare for f in dataclasses.fields(ShearTest) if f.name == "preceding")
    with pytest.raises(ValueError, match=r"preceding\[0\] of test 'run3' must be a ShearTest, got str"):
        ShearTest("run3", run3.time, run3.disp, run3.force, preceding=("run1",))
    with pytest.raises(ValueError, match="must be a tuple of ShearTest"):
        ShearTest("run3", run3.time, run3.disp, run3.force, preceding=RUN1)


# --- the model simulates the preceding runs first ----------------------------------------------
@pytest.mark.parametrize("law,values", [
    ("plasticity", {}),
    ("plasticity+scragging", {"scrag": 0.3, "scrag_disp": 0.01}),
    ("plasticity+degradation", {"deg_rate": 5.0}),
])
def test_a_test_after_earlier_runs_is_the_tail_of_simulating_their_concatenation(law, values):
    spec = get(law)
    p = spec.pack({**PL, **values})
    run2 = _run("run2", 0.02, shift=0.003)
    st, after = _simulate(spec, p, run2.after(RUN1))
    assert st == 0
    tail = _old_simulate(spec, p, concat_tests([RUN1, run2]))[-len(run2):]
    assert np.array_equal(after, tail)
    alone = _old_simulate(spec, p, run2)
    assert not np.allclose(after, alone, rtol=1e-3, atol=0)  # the state carried over shows
    if "scragging" in law:  # softer after a larger earlier run
        assert np.abs(after).max() < 0.97 * np.abs(alone).max()


@pytest.mark.parametrize("law,values", [("plasticity", {}),
                                        ("bouc_wen+scragging", {"eta": 1.0, "beta": 0.5, "gamma": 0.5,
                                                                "scrag": 0.3, "scrag_disp": 0.01})])
def test_without_preceding_runs_the_simulation_is_the_virgin_one_bit_for_bit(law, values):
    spec = get(law)
    p = spec.pack({**PL, **values})
    out = np.empty(len(RUN2))
    st, f = _simulate(spec, p, RUN2, out)
    assert st == 0 and f is out
    assert np.array_equal(f, _old_simulate(spec, p, RUN2))


def test_predict_and_loglik_see_the_carried_state():
    spec = get("plasticity+scragging")
    p = spec.pack({**PL, "scrag": 0.3, "scrag_disp": 0.01})
    P = np.repeat(p[None, :], 10, axis=0)
    P[:, spec.param_names.index("scrag")] = np.linspace(0.2, 0.4, 10)
    fit = IsolatorFit(spec=spec, p_opt=p, P=P, sig=np.full(10, 0.1), sigma=0.1, noise=0.1,
                      free=("scrag",))
    later = RUN2.after(RUN1)
    pred = fit.predict(later)
    assert pred.draws.shape == (10, len(RUN2))
    for s in range(10):
        full = _old_simulate(spec, P[s], concat_tests([RUN1, RUN2]))
        assert np.array_equal(pred.draws[s], full[-len(RUN2):])
    assert not np.allclose(pred.mean, fit.predict(RUN2).mean)
    assert fit.loglik(later).shape == (10, len(RUN2))


def test_checkpoint_key_includes_the_preceding_runs():
    model = IsolatorModel("plasticity", draws=10)
    key = model.checkpoint_key(RUN2)
    assert model.checkpoint_key(dataclasses.replace(RUN2)) == key
    k1 = model.checkpoint_key(RUN2.after(RUN1))
    assert k1 != key
    assert model.checkpoint_key(RUN2.after(RUN1)) == k1
    assert model.checkpoint_key(RUN2.after(_run("run1", 0.05))) != k1
    assert model.checkpoint_key(RUN2.after(RUN1, RUN1)) != k1
