"""A building's numbers are checked once (structures.building.checks), whether they come from a
ShearBuilding or from a shake-table run's metadata: the error names the field, the entry, the
value and the unit."""

from __future__ import annotations

import numpy as np
import pytest

from structures.building.checks import positive, positive_vector
from structures.shake_table import read_run


def test_a_story_mass_of_zero_is_refused_naming_the_entry_and_unit():
    with pytest.raises(ValueError, match=r"story_masses\[1\] = 0 t is invalid: expected a finite number > 0"):
        positive_vector("story_masses", [100.0, 0.0], "t")
    with pytest.raises(ValueError, match=r"must be a non-empty 1-D sequence \[m\]"):
        positive_vector("story_heights", [], "m")
    assert positive("damping_ratio", 0, allow_zero=True) == 0.0
    with pytest.raises(ValueError, match=r"base_mass = nan is invalid"):
        positive("base_mass", float("nan"))


def test_a_run_with_a_negative_level_weight_is_refused_like_a_building(tmp_path):
    n = 50
    for name in ("a1", "a2", "d1", "d2", "u", "du"):
        np.savetxt(tmp_path / f"{name}.txt", np.zeros(n))
    with pytest.raises(ValueError, match=r"weights\[1\] = -3 kN is invalid: expected a finite number > 0"):
        read_run(tmp_path, rate_hz=50, weights=[10.0, -3.0], weight_unit="kN")
