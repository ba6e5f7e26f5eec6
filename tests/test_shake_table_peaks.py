"""The shake-table report puts what a designer must read first where it is read: the reader's
warnings about the runs before the results (structures.shake_table.report.data_warnings), and
the held-out peaks in the reading: every channel's peak error, and an unconservative
under-prediction called so, with the run's extrapolation when it lies beyond the calibrated range
(structures.shake_table.report.peaks_text)."""

from __future__ import annotations

from types import SimpleNamespace

from rrfrei.notes import Note
from structures.shake_table.report import PEAK_TOLERANCE, data_warnings, peaks_text


def _res(errors: dict, extrapolation: float) -> SimpleNamespace:
    return SimpleNamespace(holdout=("R2",), extrapolation={"R2": extrapolation},
                           runs={"R2": {c: {"peak_error": v} for c, v in errors.items()}})


def test_an_under_predicted_force_peak_beyond_the_calibrated_range_is_called_unconservative():
    txt = peaks_text(_res({"isolator_disp": 0.05, "isolator_force": -0.29, "base_shear": -0.26,
                           "roof_accel": -0.31}, 1.95))
    assert "isolator displacement +5 %" in txt and "isolation-layer force -29 %" in txt
    assert "unconservative" in txt
    assert "isolation-layer force (R2), story-1 shear (R2), roof acceleration (R2)" in txt
    assert "1.95 x the calibrated displacement" in txt


def test_peaks_within_the_tolerance_or_over_predicted_raise_no_warning():
    txt = peaks_text(_res({"isolator_disp": 0.3, "isolator_force": -0.5 * PEAK_TOLERANCE}, 1.95))
    assert "unconservative" not in txt
    assert "isolator displacement +30 %" in txt


def test_an_unconservative_peak_within_the_calibrated_range_does_not_blame_extrapolation():
    txt = peaks_text(_res({"isolator_force": -0.2}, 0.8))
    assert "unconservative" in txt and "calibrated range" not in txt


def test_the_readers_warnings_open_the_report_and_other_notes_stay_at_the_end():
    notes = (Note("reading: run 'CNP100' (raw/CNP100): the levels look upside down", "warning"),
             Note("6 of the candidates' refits ran in a second process", "info"))
    lines = data_warnings(SimpleNamespace(notes=notes))
    assert lines[0].startswith("**Check the data first.**")
    assert "- run 'CNP100' (raw/CNP100): the levels look upside down" in lines
    assert not any("second process" in ln for ln in lines)
    assert data_warnings(SimpleNamespace(notes=notes[1:])) == []
