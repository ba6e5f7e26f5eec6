"""The candidates' refits shared with a second process (rrfrei.gap.parallel) give the report of a
sequential run, and a second process that dies loses nothing: the diagnosis fits what it left."""

from __future__ import annotations

import os

import pytest

import rrfrei.gap.checkpoint as ckpt
from rrfrei.gap.diagnose import diagnose
from structures.shake_table.simulation import BuildingData, Superstructure
from tests._shake_table_truth import PL, model_of

EFFECTS = ["isolation_damping", "softening", "rate"]


def _case(truth, monkeypatch):
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), {**PL, "qd": 0.8 * PL["qd"]}, draws=6)
    monkeypatch.setattr(m, "global_evals", 20)
    monkeypatch.setattr(m, "refit_global_evals", 10)
    monkeypatch.setattr(m, "max_nfev", 4)
    cal = BuildingData(tuple(runs), observed=("run1",))
    ho = BuildingData(tuple(runs), observed=("run2",))
    return m, cal, ho


def _summary(rep):
    return (rep.verdict, rep.combination,
            [(s.effect, s.significant, s.shrink_calibration, s.shrink_holdout) for s in rep.ranking])


@pytest.fixture
def sequential(truth, monkeypatch, tmp_path):
    m, cal, ho = _case(truth, monkeypatch)
    return _summary(diagnose(m, cal, [ho], effects=EFFECTS, checkpoint=tmp_path / "one", workers=1,
                             combine=False))


def test_two_processes_give_the_sequential_report(truth, monkeypatch, tmp_path, sequential):
    m, cal, ho = _case(truth, monkeypatch)
    rep = diagnose(m, cal, [ho], effects=EFFECTS, checkpoint=tmp_path / "two", workers=2, combine=False)
    assert _summary(rep) == sequential
    assert not list((tmp_path / "two").glob("*.claim"))  # no claim outlives the diagnosis


def test_a_second_process_that_dies_loses_no_candidate(truth, monkeypatch, tmp_path, sequential):
    m, cal, ho = _case(truth, monkeypatch)
    parent = os.getpid()
    real = ckpt._fit

    def dies_in_the_child(*a, **k):
        if os.getpid() != parent:
            os._exit(1)
        return real(*a, **k)

    monkeypatch.setattr(ckpt, "_fit", dies_in_the_child)
    rep = diagnose(m, cal, [ho], effects=EFFECTS, checkpoint=tmp_path / "dies", workers=2, combine=False)
    assert _summary(rep) == sequential
    assert not any("second process" in str(n) for n in rep.notes)


def test_an_isolator_diagnosis_in_two_processes_is_the_sequential_one(tmp_path):
    from rrfrei.gap import diagnose_gap
    from rrfrei.gap.validate import FIXED, make_tests

    tests = make_tests("degradation", 0, reduced=True)
    kw = dict(holdout=tests[1:], fixed=FIXED, effects=["degradation", "asymmetry", "slip"], draws=50,
              combine=False)
    one = diagnose_gap(tests[0], "plasticity", checkpoint=tmp_path / "one", workers=1, **kw)
    two = diagnose_gap(tests[0], "plasticity", checkpoint=tmp_path / "two", workers=2, **kw)
    assert _summary(two) == _summary(one)


def test_a_pools_worker_diagnoses_in_one_process(truth, monkeypatch, tmp_path, sequential):
    """A daemonic process (a multiprocessing pool's worker) may not start children: the diagnosis
    then runs every refit itself."""
    import multiprocessing

    m, cal, ho = _case(truth, monkeypatch)
    monkeypatch.setattr(multiprocessing.current_process(), "daemon", True, raising=False)
    rep = diagnose(m, cal, [ho], effects=EFFECTS, checkpoint=tmp_path / "pool", workers=2, combine=False)
    assert _summary(rep) == sequential
    assert not any("second process" in str(n) for n in rep.notes)


def _labelled(rep):
    return (rep.verdict, rep.combination, [s.label for s in rep.steps],
            [(s.label, s.significant, s.shrink_calibration, s.shrink_holdout) for s in rep.ranking])


def test_variants_and_combination_steps_in_two_processes_give_the_sequential_report(truth, monkeypatch,
                                                                                   tmp_path):
    """History effects bring their recovering variants (two fits) and the building's combination
    steps their refits: shared with a second process, the report is the sequential one."""
    memory = ["mullins", "scragging", "rate"]
    m, cal, ho = _case(truth, monkeypatch)
    one = diagnose(m, cal, [ho], effects=memory, checkpoint=tmp_path / "one", workers=1)
    m, cal, ho = _case(truth, monkeypatch)
    two = diagnose(m, cal, [ho], effects=memory, checkpoint=tmp_path / "two", workers=2)
    assert _labelled(two) == _labelled(one)
    assert len(list((tmp_path / "two").glob("*recovering*.npz"))) == 2  # both variants were fitted
    assert not list((tmp_path / "two").glob("*.claim"))
