"""An effect is added in one place: a module with one effect-table entry (``tests/_toy_effect.py``)
composes with every law, is the base law bit for bit at its neutral value, changes the force
away from it, and is a candidate of the gap diagnosis, without any other file naming it."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrfrei import simulate_force
from rrfrei.gap.catalogue import catalogue
from rrfrei.laws.effects import EFFECTS
from rrfrei.protocols import protocol1

ROOT = Path(__file__).resolve().parents[1]
BASE = dict(k_init=1000.0, qd=2.0, alpha1=0.1, alpha2=0.0, mu=2.0)


@pytest.fixture
def toy():
    """The toy effect registered for one test only (the other tests' default diagnoses run over
    the shipped effects alone)."""
    mod = importlib.import_module("_toy_effect")
    EFFECTS[mod.NAME] = mod.EFFECT
    try:
        yield mod
    finally:
        EFFECTS.pop(mod.NAME, None)
        sys.modules.pop("_toy_effect", None)


def test_the_toy_effect_is_named_nowhere_but_its_module(toy):
    out = subprocess.run(["git", "grep", "-l", toy.NAME], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert set(out.stdout.split()) == {"tests/_toy_effect.py"}  # this test says toy.NAME


def test_at_its_neutral_value_the_augmented_law_is_the_base_law_bit_for_bit(toy):
    _, u = protocol1()
    base = simulate_force("plasticity", BASE, u)
    aug = simulate_force(f"plasticity+{toy.NAME}", {**BASE, "offset_c": 0.0}, u)
    assert np.array_equal(base, aug)


def test_away_from_neutral_it_adds_the_offset_of_the_largest_displacement(toy):
    _, u = protocol1()
    c = 50.0
    base = simulate_force("plasticity", BASE, u)
    aug = simulate_force(f"plasticity+{toy.NAME}", {**BASE, "offset_c": c}, u)
    expected = base + c * np.maximum.accumulate(np.abs(u)) * np.sign(base)
    assert np.allclose(aug, expected, rtol=0, atol=1e-12 * np.abs(base).max())
    assert not np.allclose(aug, base)


def test_the_gap_diagnosis_lists_it_among_its_candidates_in_its_stated_order(toy):
    cat = catalogue()
    assert toy.NAME in cat
    assert list(cat)[-1] == toy.NAME  # order 50, after the nine shipped effects (1-9)
    assert cat[toy.NAME].spec is toy.EFFECT


def test_once_unregistered_it_is_no_longer_a_candidate(toy):
    name = toy.NAME
    EFFECTS.pop(name)
    assert name not in catalogue()
