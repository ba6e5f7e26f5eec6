"""Shared fixtures.

openseespy is the peer every law and time history is checked against.  When it cannot be
imported the differential tests skip locally, but fail under CI (CI=true), so a broken install
never passes silently.
"""

import os

import pytest


def _import_opensees():
    try:
        import openseespy.opensees as ops
    except Exception as exc:  # ImportError, or OSError from a missing system BLAS
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"openseespy cannot be imported under CI: {exc!r}")
        pytest.skip(f"openseespy not importable here: {exc!r}")
    return ops


@pytest.fixture(scope="session")
def ops():
    """The openseespy module (fails under CI if it cannot be imported)."""
    return _import_opensees()


@pytest.fixture(scope="module")
def truth():
    """(a known shake-table building, its runs): ``tests/_shake_table_truth.py``."""
    from tests._shake_table_truth import building_and_runs

    return building_and_runs()


# Scheduling hint for pytest-xdist (pyproject: ``--dist loadfile --no-loadscope-reorder``): these
# modules start first, longest first (measured with --durations), so that the long ones run beside
# the many short ones instead of one of them starting last and running alone on one core (the slow
# tier's two shake-table validation cases, one file each, start at once on the two workers).  The
# other modules keep their collection order.  Only the order changes, never a result.  The
# default tier starts on an empty kernel cache: its list holds no module with a wall-clock budget
# (a shake-table fit within 120 s fails there when it compiles its kernels on a loaded machine),
# those run later, on a warm cache.
FIRST_SLOW = (
    "test_shake_table_validation.py", "test_shake_table_validation_stiffening.py", "test_gap_validate.py",
    "test_calibration_coverage.py",
    "test_rubber_robust.py", "test_rubber_gap_engine.py", "test_rubber_fit.py", "test_demo.py",
    "test_propagate.py",
)
FIRST = (
    "test_plan_building.py", "test_demo.py", "test_effects_shapes.py", "test_effects.py", "test_cli.py",
    "test_plan_cli.py", "test_gap.py", "test_gap_design.py", "test_effects_new.py", "test_jit_cache.py",
)


def pytest_collection_modifyitems(config, items):
    first = FIRST_SLOW if config.getoption("markexpr", "").strip() == "slow" else FIRST
    rank = {name: i for i, name in enumerate(first)}
    items.sort(key=lambda item: rank.get(item.path.name, len(first)))  # stable: modules stay whole
