"""The three tables (laws, plan laws, effects) register through one rule: a name holds one
entry; registering the same entry again is harmless, a different entry of a taken name is
refused with an error that says which table."""

from __future__ import annotations

import dataclasses

import pytest

from rrfrei.laws import get, plan, registry
from rrfrei.laws.effects import EFFECTS, register_effect


@pytest.mark.parametrize("register,spec,kind", [
    (registry.register, lambda: get("plasticity"), "a law"),
    (plan.registry.register, lambda: plan.get("plasticity"), "a plan law"),
    (register_effect, lambda: EFFECTS["rate"], "an effect"),
], ids=["law", "plan law", "effect"])
def test_a_taken_name_refuses_another_entry_and_says_which_table(register, spec, kind):
    spec = spec()
    assert register(spec) is spec
    impostor = dataclasses.replace(spec)
    with pytest.raises(ValueError, match=f"{kind} named {spec.name!r} is already registered"):
        register(impostor)
    assert register(spec) is spec


def test_discovery_imports_a_package_once_and_fills_its_table():
    registry.discover("rrfrei.laws")
    before = registry.names()
    registry.discover("rrfrei.laws")
    assert registry.names() == before and "plasticity" in before
    assert "plasticity" in plan.names()
