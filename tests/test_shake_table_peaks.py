"""The shake-table reading states the held-out peaks where a designer reads them: every channel's
peak error, and an unconservative under-prediction called so, with the run's extrapolation when
it lies beyond the calibrated range (structures.shake_table.report.peaks_text)."""

from __future__ import annotations

from types import SimpleNamespace

from structures.shake_table.report import PEAK_TOLERANCE, peaks_text


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
