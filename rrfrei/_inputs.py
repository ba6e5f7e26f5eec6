"""Validation helpers for the public boundary (one home for each check)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np


def as_history(values, name: str, *, min_len: int = 1) -> np.ndarray:
    """A finite 1-D float64 array, or ValueError naming ``name``, the index and the value."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 1-D array of numbers, got {type(values).__name__}") from None
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    if arr.size < min_len:
        raise ValueError(f"{name} must have at least {min_len} value(s), got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"{name} is not finite at index {bad[0]} (value {arr[bad[0]]})")
    arr = np.ascontiguousarray(arr)
    # writable: Numba compiles a read-only array (a ShearTest's, a Record's) as a second signature
    return arr if arr.flags.writeable else arr.copy()


def read_toml(path: str | Path) -> dict:
    """Parse a TOML file; a missing file raises FileNotFoundError, a directory, a binary or
    non-UTF-8 file or bad TOML a ValueError naming it."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    if path.is_dir():
        raise ValueError(f"{path}: is a directory; expected a TOML file")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 TOML text file (byte {exc.start} is not UTF-8 text: a "
                         "binary file, or another encoding)") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML ({exc})") from None
