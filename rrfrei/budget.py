"""Wall-clock budgets and progress bars for long commands (calibrate, gap, rubber fit).

A long command on real data must show that it is working, estimate when it will end, and stop
at a stated time with what it has rather than run for an hour in silence.  One mechanism for
all of them:

- :class:`TimeBudget` measures elapsed wall time [s] against a limit (``None``: no limit) and
  builds the message that names the command, the limit and how to raise it;
- :func:`progress` returns a tqdm bar (with its rate and remaining-time estimate) that writes to
  stderr, or a silent stand-in with the same methods when progress is off, so callers never
  test for it.

A budget that runs out is not an error: the command returns (and checkpoints) what it has,
marked as stopped by the budget, and says so.  :class:`BudgetExceeded` is for the places that
must unwind from inside a loop (an optimiser's objective) to get there.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["TimeBudget", "BudgetExceeded", "progress", "seconds_arg", "stderr_is_tty"]


class BudgetExceeded(RuntimeError):
    """Raised inside a loop to unwind when its :class:`TimeBudget` has run out."""


@dataclass
class TimeBudget:
    """A wall-clock limit for one command.

    Parameters
    ----------
    seconds : limit in seconds; ``None`` or ``math.inf`` for no limit.  Must be > 0.
    what : the command or step it limits, used in messages (e.g. ``"calibrate"``).
    option : the option a user changes to raise it (e.g. ``"--time-budget"``).
    """

    seconds: float | None
    what: str = "this run"
    option: str = "time_budget"
    start: float = field(default_factory=time.perf_counter)

    @classmethod
    def of(cls, value: TimeBudget | float | None, what: str, option: str = "time_budget") -> TimeBudget:
        """``value`` if it is already a running budget, else a new one of ``value`` seconds.

        ValueError naming ``option`` for anything but a number of seconds > 0, None or a budget.
        """
        if isinstance(value, TimeBudget):
            return value
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.number))):
            raise ValueError(f"{option} = {value!r}: expected a number of seconds > 0 or None")
        return cls(value, what=what, option=option)

    def __post_init__(self) -> None:
        if self.seconds is not None:
            s = float(self.seconds)
            if not (s > 0.0) or math.isnan(s):
                raise ValueError(f"{self.option} = {self.seconds!r}: expected a number of seconds > 0 "
                                 "(or None for no limit)")
            self.seconds = None if math.isinf(s) else s

    @property
    def elapsed(self) -> float:
        """Seconds since the budget started."""
        return time.perf_counter() - self.start

    @property
    def remaining(self) -> float:
        """Seconds left (``inf`` without a limit, never negative)."""
        if self.seconds is None:
            return math.inf
        return max(0.0, self.seconds - self.elapsed)

    def expired(self) -> bool:
        """True once the elapsed time has reached the limit."""
        return self.seconds is not None and self.elapsed >= self.seconds

    def check(self) -> None:
        """Raise :class:`BudgetExceeded` (with :meth:`message`) once the limit is reached."""
        if self.expired():
            raise BudgetExceeded(self.message())

    def message(self, done: str = "") -> str:
        """One line for the user: what stopped, after how long, what was kept, how to go on."""
        kept = f"; {done}" if done else ""
        return (f"{self.what}: time budget of {self.seconds:.0f} s reached after {self.elapsed:.0f} s"
                f"{kept}. Raise it with {self.option} (none: no limit).")


class _Silent:
    """A do-nothing stand-in for a tqdm bar."""

    n = 0

    def update(self, n: int = 1) -> None:
        self.n += n

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def set_description_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> _Silent:
        return self

    def __exit__(self, *exc: object) -> None:
        pass


def stderr_is_tty() -> bool:
    """True when stderr is a terminal (a bar redraws in place there; in a log every refresh is a
    new line)."""
    import sys

    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress(total: int | None, desc: str, *, enabled: bool = True, unit: str = "it", leave: bool = False):
    """A tqdm progress bar on stderr (rate and remaining-time estimate), or a silent stand-in.

    ``leave=False`` by default so that nested steps of one command do not pile up lines.
    """
    if not enabled:
        return _Silent()
    from tqdm.auto import tqdm

    # on a terminal the bar redraws in place; in a log every refresh is a new line: refresh rarely
    return tqdm(total=total, desc=desc, unit=unit, leave=leave, dynamic_ncols=True,
                mininterval=0.5 if stderr_is_tty() else 10.0)


def seconds_arg(text: str) -> float | None:
    """argparse type of every ``--time-budget``: seconds > 0, or ``none``/``off``/``inf`` for no limit."""
    import argparse

    if text.strip().lower() in ("none", "off", "inf", "infinite"):
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or math.isnan(value):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0 or 'none', got {text!r}")
    return None if math.isinf(value) else value
