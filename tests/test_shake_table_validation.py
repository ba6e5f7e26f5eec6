"""Validation of the building-level diagnosis on independently simulated buildings (issue 27.7).

Default tier: one small case, the contract of a row and of the summary, and that a study's runs
are long enough for the block rule.  Slow tier: a subset of the study (seed 0: the control here
and the stiffening in ``test_shake_table_validation_stiffening.py``) through the public entry
point; the full table (every form over three seeds) is the command of
docs/gap/validation_building.md.  What the slow tier asserts is what the issue asks of the tool
whatever the numbers: every case finishes (no candidate lost to numerics), a named effect never
makes the held-out building worse, few false alarms, and the diagnosis pointing at the withheld
stiffening.
"""

from __future__ import annotations

import math

import pandas as pd
import pytest

from structures.shake_table.validation import (
    ACCEPTED,
    FORMS,
    PEAKS,
    _flag,
    run_case,
    run_validation,
    summarise,
)

KEYS = {"effect", "seed", "verdict", "named", "top1", "false_alarm", "holdout_nrmse_before",
        "holdout_nrmse_after", "shrink", "gap_shrink", "peak_disp_cal", "peak_disp_holdout"}


def test_one_case_gives_a_verdict_and_the_held_out_error_before_and_after():
    # a short sequence (6 s runs, no tail): the contract of a row, not a verdict the rule can give
    row = run_case("stiffening", 0, peaks=(0.6, 1.2), duration=6.0, tail_s=0.0, effects=["stiffening"],
                   time_budget=None, draws=10, n_draws=10)  # no wall clock in a test
    assert KEYS <= set(row)
    assert row["verdict"] in {"stiffening", "none", "unexplained", "incomplete"}
    assert row["top1"] == (row["verdict"] == "stiffening")
    assert math.isnan(row["false_alarm"])
    assert row["holdout_nrmse_before"] > 0 and math.isfinite(row["holdout_nrmse_after"])
    # the held-out run goes beyond the calibrated amplitude
    assert row["peak_disp_holdout"] > row["peak_disp_cal"]
    s = summarise(pd.DataFrame([row]))
    assert s["cases"] == 1 and s["false_alarms_n"] == "0/0"


def test_a_validation_run_is_long_enough_for_the_block_rule_to_name_an_effect():
    """The building's blocks are 10 s windows of each run and the rank tests of the block rule
    need at least 8 on the held-out run alone (p = 2^-m with every block gaining): the 20 s runs
    of the first study gave 2, so no effect could be named whatever it closed."""
    from rrfrei.gap.decision import min_blocks
    from structures.shake_table.building_model import WINDOW_S
    from structures.shake_table.validation import DURATION_S, TAIL_S

    held_out = int((DURATION_S + TAIL_S) // WINDOW_S)
    assert held_out >= min_blocks()
    assert (len(PEAKS) - 1) * held_out >= min_blocks()  # the calibration runs too


def test_every_form_has_its_accepted_answers_and_the_control_none():
    assert set(ACCEPTED) == set(FORMS) and ACCEPTED["none"] == frozenset()
    with pytest.raises(ValueError, match="effect = 'creep'"):
        run_case("creep", 0)


def test_a_failed_case_is_recorded_in_the_same_columns_and_is_neither_right_nor_an_alarm(
        tmp_path, monkeypatch):
    import structures.shake_table.validation as v

    def fails(effect, seed, **kw):
        raise ValueError("time budget reached")

    monkeypatch.setattr(v, "run_case", fails)
    out = tmp_path / "cases.csv"
    df = run_validation(["none", "stiffening"], [0], out=out, progress=False)
    back = pd.read_csv(out)
    assert list(back.columns) == list(v.COLUMNS) and list(back["verdict"]) == ["failed", "failed"]
    for table in (df, back):
        s = summarise(table)
        assert s["failed"] == 2 and s["top1_n"] == "0/1" and s["false_alarms_n"] == "0/1"
    # a rerun resumes: nothing left to do
    assert len(run_validation(["none", "stiffening"], [0], out=out, progress=False)) == 2


SLOW_FORMS = ("none", "stiffening")
"""The slow tier's subset of the study (seed 0; 150-235 s a case at load 9-13): the control and
the form whose own candidate comes first on every seed (with ``degradation`` too the test took
9 minutes at load 7-9, over the slow tier's 8).  The full table (5 forms x 3 seeds, about an
hour) is the documented command of docs/gap/validation_building.md.  One case per test file
(the control here, the stiffening in ``test_shake_table_validation_stiffening.py``), so that
pytest-xdist's ``--dist loadfile`` runs the two cases on the two workers at once instead of one
after the other on one (1,081 s on one worker in the slow tier of 28 Nov, at load 5)."""


def run_slow_case(form: str, tmp_path) -> pd.DataFrame:
    """One case of :data:`SLOW_FORMS` (seed 0) through the public entry point, and what the issue
    asks of the tool on buildings it was not written for, whatever the numbers: the case finishes
    with every candidate scored (none lost to numerics) on 8+ blocks each side, and a named
    effect never makes the held-out building worse."""
    assert form in SLOW_FORMS
    df = run_validation((form,), (0,), out=tmp_path / "cases.csv", progress=False, time_budget=1800.0)
    assert len(df) == 1 and df["effect"].iloc[0] == form
    assert not (df["verdict"] == "failed").any(), df[df["verdict"] == "failed"]
    assert (df["skipped"].fillna("") == "").all(), df[["effect", "skipped"]]
    assert (df["blocks_holdout"] >= 8).all() and (df["blocks_cal"] >= 8).all()
    named = df[_flag(df["named"])]
    assert (named["shrink"] >= 0.0).all(), named[["effect", "seed", "verdict", "shrink"]]
    return df


@pytest.mark.slow
def test_validation_subset_the_control_finishes_and_raises_no_false_alarm(tmp_path):
    """The control of the subset (:func:`run_slow_case`), and at most a third of the controls
    raise a false alarm: with the one control of the subset, none."""
    controls = run_slow_case("none", tmp_path)
    assert _flag(controls["false_alarm"]).sum() <= len(controls) // 3, controls[["seed", "verdict"]]
