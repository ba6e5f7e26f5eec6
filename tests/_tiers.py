"""One hypothesis test in two tiers: a quick run in the default suite and a long sweep under
``pytest -m slow``, from one body.

    @pytest.mark.parametrize("tier", tiers(Tier(60), Tier(500)))
    def test_x(ops, law, tier):
        run_examples(tier, lambda p, d: check(ops, law, p, d), p=params(), d=paths())
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st


@dataclass(frozen=True)
class Tier:
    """How hard a tier tries: ``examples`` hypothesis examples, drawn histories of at most
    ``max_size`` samples (for the tests whose strategies take one)."""

    examples: int
    max_size: int = 60


def tiers(quick: Tier, sweep: Tier) -> list:
    """pytest parameters: ``quick`` (id "quick") and ``sweep`` (id "sweep", marked slow)."""
    return [pytest.param(quick, id="quick"), pytest.param(sweep, id="sweep", marks=pytest.mark.slow)]


def run_examples(tier: Tier, check: Callable[..., None], **strategies: st.SearchStrategy) -> None:
    """Run ``check(**drawn)`` on ``tier.examples`` hypothesis examples of ``strategies`` (no
    deadline: the peer and a cold kernel are slow)."""
    test = given(**strategies)(check)
    settings(max_examples=tier.examples, deadline=None,
             suppress_health_check=[HealthCheck.too_slow])(test)()
