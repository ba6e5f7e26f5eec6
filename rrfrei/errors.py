"""Exceptions that tell a user's mistake from a numerical failure.

The CLI maps them to exit codes: a user error (bad path, malformed file, unknown name, bad
value: ``ValueError`` and the ``OSError`` family) exits 2; a :class:`NumericalFailure` exits 1
with what failed where.  ``NumericalFailure`` subclasses ``ValueError`` so existing callers that
catch ``ValueError`` keep working, but every handler must test for it *first*.
"""

from __future__ import annotations

import numpy as np


class NumericalFailure(ValueError):
    """A computation failed on valid input: a local Newton solve, a singular matrix, a blow-up.

    The message names what failed and where (law, sample index, state, effect, step).
    """


#: Exceptions raised by numerical libraries on valid input (singular matrices, overflow).
NUMERICAL_ERRORS: tuple[type[BaseException], ...] = (
    NumericalFailure,
    np.linalg.LinAlgError,
    FloatingPointError,
    ZeroDivisionError,
    OverflowError,
)


def is_numerical(exc: BaseException) -> bool:
    """True for a numerical failure (exit 1), False for anything else."""
    return isinstance(exc, NUMERICAL_ERRORS)
