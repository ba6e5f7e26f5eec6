"""Augmentations ("effects") that wrap any base law's step kernel.

An augmented law ``base+effect[+effect...]`` has the base law's parameters followed by each
effect's parameters, and the base state followed by each effect's state.  Its dispatch code
(:data:`rrfrei.laws.registry.CODE_LEN`) lists the effect ids with their parameter and state
offsets.  The catalogue itself (kernels and parameter specs) is filled by the gap-diagnosis
work (issue 7); this module holds the composition mechanism.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from rrfrei.laws.dispatch import base_step
from rrfrei.laws.registry import CODE_LEN, MAX_EFFECTS, LawSpec, ParamSpec


@dataclass(frozen=True)
class EffectSpec:
    """An effect: its kernel id, parameters, state size and a one-line physical meaning."""

    name: str
    effect_id: int
    params: tuple[ParamSpec, ...]
    state_size: int
    description: str


EFFECTS: dict[str, EffectSpec] = {}


def compose(base: LawSpec, effect_names: list[str]) -> LawSpec:
    """Compose ``base`` with the named effects into a new :class:`LawSpec`."""
    if base.effects:
        raise ValueError(f"law {base.name!r} is already augmented")
    if len(effect_names) > MAX_EFFECTS:
        raise ValueError(f"at most {MAX_EFFECTS} effects can be combined, got {len(effect_names)}")
    if len(set(effect_names)) != len(effect_names):
        raise ValueError(f"effects repeat in {effect_names}")
    params = list(base.params)
    state = base.state_size
    code = np.zeros(CODE_LEN, dtype=np.int64)
    code[0] = base.kernel_id
    code[1] = len(base.params)
    code[2] = base.state_size
    code[3] = len(effect_names)
    init = [np.asarray(base.initial_state)]
    for i, name in enumerate(effect_names):
        if name not in EFFECTS:
            raise ValueError(
                f"unknown effect {name!r}; available effects: {', '.join(EFFECTS) or '(none)'}"
            )
        eff = EFFECTS[name]
        code[4 + 3 * i] = eff.effect_id
        code[5 + 3 * i] = len(params)
        code[6 + 3 * i] = state
        params.extend(eff.params)
        state += eff.state_size
        init.append(np.zeros(eff.state_size))
    return LawSpec(
        name=base.name + "".join("+" + n for n in effect_names),
        kernel_id=base.kernel_id,
        params=tuple(params),
        state_size=state,
        description=base.description + " Augmented with " + ", ".join(effect_names) + ".",
        uses_velocity=True,
        effects=tuple(effect_names),
        code=code,
        initial_state=np.concatenate(init),
    )


@njit(cache=True)
def augmented_step(code, p, sc, u, v, dt, st):
    """Step of an augmented law (catalogue pending: the base law only)."""
    nb = code[1]
    ns = code[2]
    return base_step(code[0], p[:nb], sc[:ns], u, v, dt, st[:ns])
