"""The results of ground_motions (spectra, RotD spectra, scaled suites) hold read-only arrays,
also after a round trip through pickle (a Dask worker's copy): one rule, ``ReadOnlyArrays``."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import ground_motions as gm
from ground_motions.asce7 import ScaledSuite
from ground_motions.rotd import RotDSpectrum
from ground_motions.spectra import Spectrum

ONE = np.ones(3)
CASES = {
    "spectrum": lambda: Spectrum(ONE, ONE, ONE, ONE, 0.05, "x"),
    "rotd": lambda: RotDSpectrum(ONE, (50, 100), np.ones((2, 3)), np.ones((2, 3)), np.arange(3.0),
                                 np.ones((3, 3)), 0.05, "x"),
    "suite": lambda: ScaledSuite((), ONE, ONE, ONE, np.ones((1, 3)), ONE, ONE, 1.0, 2.0, 3.0),
}


@pytest.mark.parametrize("kind", list(CASES))
def test_arrays_are_read_only_copies_and_stay_so_through_pickle(kind):
    obj = CASES[kind]()
    again = pickle.loads(pickle.dumps(obj))
    assert type(again) is type(obj)
    for name in obj.ARRAYS:
        for o in (obj, again):
            a = getattr(o, name)
            assert a.dtype == np.float64 and not a.flags.writeable, f"{kind}.{name}"
            with pytest.raises(ValueError):
                a[...] = 0.0
        np.testing.assert_array_equal(getattr(again, name), getattr(obj, name))
    assert ONE.flags.writeable  # a copy was frozen, not the caller's array


def test_a_computed_spectrum_survives_pickle_with_every_field():
    s = gm.response_spectrum(gm.load("elcentro"), np.geomspace(0.1, 3.0, 5))
    t = pickle.loads(pickle.dumps(s))
    assert (t.name, t.damping) == (s.name, s.damping)
    np.testing.assert_array_equal(t.psa, s.psa)
