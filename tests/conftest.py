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
