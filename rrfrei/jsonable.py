"""JSON-ready values: the one rule by which every command's ``--json`` writes a number (public:
every package's reports use it)."""

from __future__ import annotations

import math

__all__ = ["number"]


def number(x) -> float | None:
    """``float(x)``, or None for None, NaN and infinities (JSON has no NaN: null means "no value")."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None
