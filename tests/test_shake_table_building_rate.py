"""The building is fitted at one rate whatever the recorder's (structures.shake_table.gap,
``building_hz``): runs recorded at an integer multiple of it are decimated to it first (anti-alias,
then every q-th sample), so the raw 200 Hz BNCS folders and the bundled 50 Hz runs made from them
give one answer; other rates, or ``building_hz=None``, keep the runs as recorded."""

from __future__ import annotations

import numpy as np
import pytest

import structures.shake_table.gap as gap_mod
from structures.shake_table.gap import BUILDING_HZ, shake_table_gap
from structures.shake_table.synthetic import SyntheticBuilding, synthetic_sequence


class _Stop(Exception):
    pass


@pytest.fixture(scope="module")
def runs_100hz():
    return synthetic_sequence(SyntheticBuilding(), (0.5, 0.9), seed=0, duration=12.0, tail_s=0.0,
                              rate_hz=100.0)


def _runs_seen(monkeypatch, runs, **kw):
    """The runs the pipeline's first step (the isolation tests) receives."""
    seen = {}

    def stop(rs, rate_hz):
        seen["runs"] = list(rs)
        raise _Stop

    monkeypatch.setattr(gap_mod, "calibration_test", stop)
    with pytest.raises(_Stop):
        shake_table_gap(runs, effects=[], **kw)
    return seen["runs"]


def test_runs_at_a_multiple_of_the_building_rate_are_decimated_to_it(monkeypatch, runs_100hz):
    assert BUILDING_HZ == 50.0
    (seen,) = _runs_seen(monkeypatch, runs_100hz)  # calibrated on the first run
    assert seen.rate_hz == pytest.approx(50.0)
    ref = runs_100hz[0].decimate(50.0)
    np.testing.assert_array_equal(seen.disp, ref.disp)
    np.testing.assert_array_equal(seen.table_accel, ref.table_accel)


@pytest.mark.parametrize("building_hz", [None, 30.0])
def test_building_hz_none_or_not_a_divisor_keeps_the_recorded_rate(monkeypatch, runs_100hz, building_hz):
    (seen,) = _runs_seen(monkeypatch, runs_100hz, building_hz=building_hz)
    assert seen.rate_hz == pytest.approx(100.0)


@pytest.mark.parametrize("bad", [0.0, -50.0, True, "50"])
def test_a_bad_building_rate_is_a_value_error_naming_it(runs_100hz, bad):
    with pytest.raises(ValueError, match="building_hz"):
        shake_table_gap(runs_100hz, effects=[], building_hz=bad)
