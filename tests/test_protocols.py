"""The RR-FREI protocols reproduce the bundled tests' displacement columns and validate input."""

from importlib import resources

import numpy as np
import pandas as pd
import pytest

from rrfrei import protocols
from rrfrei.energy import cycle_bounds

ROUNDING_MM = 0.5e-5 + 1e-12  # the CSVs carry 5 decimals of a millimetre


def _bundled(k: int) -> pd.DataFrame:
    path = resources.files("rrfrei.data") / "isolator_synthetic" / f"protocol{k}.csv"
    with resources.as_file(path) as p:
        return pd.read_csv(p)


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_protocol_reproduces_bundled_displacement_to_file_rounding(k):
    data = _bundled(k)
    t, u = protocols.protocol(k)
    assert t.shape == u.shape == (len(data),)
    np.testing.assert_allclose(t, data["time_s"].to_numpy(), rtol=0, atol=0.5e-5)
    assert np.max(np.abs(u * 1e3 - data["disp_mm"].to_numpy())) <= ROUNDING_MM


def test_named_helpers_equal_numbered_protocols():
    for k, fn in enumerate([protocols.protocol1, protocols.protocol2, protocols.protocol3,
                            protocols.protocol4], start=1):
        t1, u1 = fn(dd=0.05, dm=0.07)
        t2, u2 = protocols.protocol(k, dd=0.05, dm=0.07)
        assert np.array_equal(t1, t2) and np.array_equal(u1, u2)


def test_protocol1_is_three_cycles_at_each_fema_amplitude():
    dd, dm = 0.04, 0.06
    t, u = protocols.protocol1(dd=dd, dm=dm, period=5.0, rate=40.0)
    b = cycle_bounds(u)
    assert b.shape == (12, 2)
    peaks = np.array([u[s:e + 1].max() for s, e in b])
    troughs = np.array([u[s:e + 1].min() for s, e in b])
    expected = np.repeat([0.25 * dd, 0.5 * dd, dd, dm], 3)
    np.testing.assert_allclose(peaks, expected, rtol=1e-12)
    np.testing.assert_allclose(troughs, -expected, rtol=1e-12)
    assert t[-1] == pytest.approx(12 * 5.0) and u[0] == 0.0 and u[-1] == 0.0


def test_protocol4_is_a_monotonic_push_to_1p5_dm():
    t, u = protocols.protocol4(dm=0.05)
    assert np.all(np.diff(u) > 0) and u[-1] == pytest.approx(0.075) and t[-1] == pytest.approx(30.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"number": 5}, "protocol number"),
        ({"number": 1.0}, "protocol number"),
        ({"number": 1, "dd": 0.0}, "dd"),
        ({"number": 1, "dd": -0.01}, "dd"),
        ({"number": 1, "dm": float("nan")}, "dm"),
        ({"number": 1, "dd": 0.03, "dm": 0.02}, "dm = 0.02 m must be >= dd"),
        ({"number": 2, "period": 0.0}, "period"),
        ({"number": 2, "rate": -1.0}, "rate"),
        ({"number": 3, "period": 1.0, "rate": 2.0}, "samples per cycle"),
        ({"number": 1, "dd": "x"}, "dd"),
    ],
)
def test_protocol_rejects_bad_arguments(kwargs, match):
    number = kwargs.pop("number")
    with pytest.raises(ValueError, match=match):
        protocols.protocol(number, **kwargs)
