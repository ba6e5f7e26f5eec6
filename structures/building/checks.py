"""Boundary checks of a building's numbers: a positive finite number or a non-empty vector of
them, with errors that name the field, the value and the unit (the building model and the
shake-table readers validate masses, stiffness, heights and weights with these)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["positive", "positive_vector"]


def positive(name: str, x: Any, *, allow_zero: bool = False) -> float:
    """``x`` as a float, finite and > 0 (>= 0 with ``allow_zero``); ValueError naming ``name``."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not math.isfinite(v) or (v < 0.0 if allow_zero else v <= 0.0):
        need = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} = {x!r} is invalid: expected a finite number {need}")
    return v


def positive_vector(name: str, values: Any, unit: str) -> np.ndarray:
    """``values`` as a non-empty 1-D float array of finite numbers > 0 [``unit``]; ValueError
    naming ``name``, the bad entry's index, its value and the unit."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a sequence of numbers [{unit}], got {values!r}") from None
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence [{unit}], got shape {arr.shape}")
    for i, x in enumerate(arr):
        if not math.isfinite(x) or x <= 0.0:
            raise ValueError(f"{name}[{i}] = {x:g} {unit} is invalid: expected a finite number > 0")
    return arr
