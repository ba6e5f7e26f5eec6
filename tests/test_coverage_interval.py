"""A band's coverage on one run comes with an interval that knows the run's samples are not
independent (structures.shake_table.sequence.coverage_interval): whole 10 s windows in or out of
the band give a wide interval, a band that holds everything a point, and more runs a narrower one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from structures.shake_table.sequence import coverage_interval

DT = 0.02  # 50 Hz, as the bundled runs


def _windows(pattern, per_window_s=10.0):
    """Samples at 50 Hz, each 10 s window wholly inside (1) or outside (0) the band."""
    n = int(per_window_s / DT)
    inside = np.repeat(np.asarray(pattern, bool), n)
    return inside, np.arange(inside.size) * DT


def test_whole_windows_in_or_out_give_an_interval_as_wide_as_nine_windows_allow():
    """Nine 10 s windows, six inside: the coverage is 2/3 and, since the windows are the
    independent units, the interval spans about +-0.25 (binomial sd of 9 trials: 0.16), not the
    +-0.02 that 4,500 independent samples would give."""
    inside, t = _windows([1, 1, 0, 1, 1, 0, 1, 1, 0])
    lo, hi = coverage_interval([inside], [t])
    assert lo < 2 / 3 < hi
    assert hi - lo > 0.3


def test_a_band_that_holds_every_sample_has_no_spread():
    inside, t = _windows([1] * 9)
    assert coverage_interval([inside], [t]) == (1.0, 1.0)


def test_more_runs_narrow_the_interval():
    inside, t = _windows([1, 0, 1, 1, 0, 1, 1, 1, 0])
    one = coverage_interval([inside], [t])
    four = coverage_interval([inside] * 4, [t] * 4)
    assert four[1] - four[0] < one[1] - one[0]


@settings(max_examples=25, deadline=None)
@given(st.lists(st.booleans(), min_size=3, max_size=30), st.integers(0, 1000))
def test_the_interval_lies_within_the_observed_window_coverages(pattern, seed):
    """Every resample is a mix of the run's windows, so the interval lies between its least and its
    most covered window (here 0 and 1 whenever both kinds occur) and is reproducible by seed."""
    inside, t = _windows(pattern)
    lo, hi = coverage_interval([inside], [t], seed=seed)
    assert min(pattern) <= lo <= hi <= max(pattern)
    assert (lo, hi) == coverage_interval([inside], [t], seed=seed)
    if min(pattern) == max(pattern):
        assert lo == hi == pytest.approx(float(pattern[0]))
