"""Text for users: numbers written as numbers.

NumPy 2 writes a scalar's ``repr`` as ``np.float64(-674.0)``; a message that formats a value with
``!r``, or a list or tuple of values, shows that to a user.  :func:`plain_numbers` turns every such
repr into the plain number (``-674.0``); the command lines pass their messages through it.
"""

from __future__ import annotations

import re

__all__ = ["plain_numbers"]

_NUMPY_SCALAR = re.compile(r"\bnp\.(?:float|int|uint|complex)\d*\(([^()]*)\)"
                           r"|\bnp\.(?:bool_?|str_)\(([^()]*)\)")


def plain_numbers(text: object) -> str:
    """``str(text)`` with NumPy scalar reprs (``np.float64(-674.0)``, ``np.int64(3)``,
    ``np.True_`` stays) written as plain values (``-674.0``, ``3``)."""
    return _NUMPY_SCALAR.sub(lambda m: m.group(1) if m.group(1) is not None else m.group(2), str(text))
