"""The gap map's heat map: a bad segment looks alarming, a good one calm, on a labelled scale.

Colouring each column by its own min-max range made the *best* coverage the darkest red; the map
now colours a fixed-scale concern (0 = what a good model shows, 1 = the column's alarm level).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from rrfrei.gap.report import figures
from rrfrei.gap.segment_map import COLUMNS, concern
from rrfrei.io import ShearTest

GOOD = {"n": 100, "error_share": 0.1, "rms_over_noise": 1.0, "coverage": 0.96, "energy_error": 0.02}
BAD = {"n": 30, "error_share": 0.9, "rms_over_noise": 4.0, "coverage": 0.30, "energy_error": -0.5}


def _where(*rows) -> pd.DataFrame:
    return pd.DataFrame([{"axis": "amplitude", "segment": f"s{i}", "bias": 0.0, "excess": 0.0, **r}
                         for i, r in enumerate(rows)])


def _luminance(rgba) -> float:
    r, g, b = rgba[:3]
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def _fake_report(where: pd.DataFrame):
    """Just what ``figures`` reads of a GapReport: one test, one fit, the segment table."""
    u = 0.01 * np.sin(np.linspace(0, 6 * np.pi, 300))
    test = ShearTest("t", np.arange(300.0), u, 100.0 * u)
    fit = SimpleNamespace(predict=lambda t: SimpleNamespace(mean=100.0 * np.asarray(t.disp)))
    return SimpleNamespace(calibration_data=test, fits={"plasticity": fit}, law="plasticity", where=where,
                           combination=[], holdout_data=[], ranking=[])


def test_a_segment_at_the_noise_with_nominal_coverage_is_calm_and_a_missed_one_alarming():
    c = concern(_where(GOOD, BAD))
    assert c.shape == (2, len(COLUMNS))
    assert np.all(c[0] < 0.1), c[0]
    assert np.all(c[1] == 1.0), c[1]


def test_concern_is_absolute_two_good_segments_are_both_calm():
    """Per-column min-max scaling painted one of two equally good segments dark red."""
    slightly = {**GOOD, "coverage": 0.94, "rms_over_noise": 1.05}
    c = concern(_where(GOOD, slightly))
    assert np.nanmax(c) < 0.1


def test_an_undefined_energy_error_has_no_concern():
    c = concern(_where({**GOOD, "energy_error": float("nan")}))
    assert np.isnan(c[0, 3]) and np.isfinite(c[0, :3]).all()


@pytest.mark.parametrize("column", ["coverage", "rms_over_noise", "error_share", "energy_error"])
def test_in_the_gap_map_the_good_cell_is_paler_than_the_bad_one_with_a_labelled_colour_bar(column):
    fig = figures(_fake_report(_where(GOOD, BAD)))["gap_map.png"]
    ax = fig.axes[1]
    (im,) = ax.get_images()
    j = [c for c, _ in COLUMNS].index(column)
    colours = im.cmap(im.norm(im.get_array()))
    good, bad = colours[0, j], colours[1, j]
    assert _luminance(good) > _luminance(bad) + 0.3, (column, good, bad)
    bars = [a for a in fig.axes if a.get_ylabel().startswith("concern")]
    assert bars, "no colour bar labelled with what the colour means"
