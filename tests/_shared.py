"""The project's shared folder, reached as ``../shared`` relative to the repository root.

Tests that need shared data call :func:`shared` and fail loudly (never skip) when it is absent, so
a machine without it cannot pass by checking nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


def shared(*parts: str) -> Path:
    """Path of ``../shared/<parts>``; fails the test if it does not exist."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.fail(f"shared data missing: {path} (expected ../shared/{'/'.join(parts)} next to the "
                    "repository)")
    return path
