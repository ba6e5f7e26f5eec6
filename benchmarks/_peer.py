"""openseespy as the timed peer of a benchmark: its fastest path, the model and a ``-binary``
recorder built before the timer, ONE ``analyze`` call timed, ``ops.wipe()`` (which flushes and
closes the recorder) and reading the file after it (:func:`_timing.read_binary_recorder`: full
precision, no text formatting inside ``analyze``)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from typing import Any

import _timing as tm


def recorder_side(ops, label: str, what: str, build: Callable[[str], Any],
                  analyze: Callable[[], int], read: Callable[[str, Any], Any]) -> tm.Side:
    """A :class:`_timing.Side` running openseespy.

    ``build(path) -> state`` builds the model and its ``-binary`` recorder writing to ``path``
    (a fresh temporary file; untimed); ``analyze() -> status`` is the timed call; ``read(path,
    state)`` returns the peer's result from the recorder file (untimed).  A non-zero status
    raises RuntimeError naming ``what`` failed; the file is removed either way.
    """

    def setup():
        fd, path = tempfile.mkstemp(suffix=".out")
        os.close(fd)
        return path, build(path)

    def finish(prepared, status):
        path, state = prepared
        ops.wipe()  # flushes and closes the recorder
        try:
            if status != 0:
                raise RuntimeError(f"openseespy {what} failed (status {status})")
            return read(path, state)
        finally:
            os.unlink(path)

    return tm.Side(label, lambda _s: analyze(), setup, finish)


def method(repeat: int, n: int, peer: str = "") -> str:
    """The RESULTS.md sentences that say how a :func:`recorder_side` comparison was timed:
    ``repeat`` interleaved runs, the peer's ``analyze(n)`` (``peer``: what it runs, e.g. "the
    3-D zero-length element, both horizontal DOFs imposed, ")."""
    return (f"**Per core**, both single-threaded, median of {repeat} interleaved runs after one "
            f"warm-up each. openseespy: {peer}one `analyze({n})` with a `-binary` element recorder "
            "(full precision, no text formatting inside `analyze`); building the model, "
            "`ops.wipe()` and reading the recorder file are outside its timer.")


def cold_start(cold: tm.ColdStart, what: str) -> str:
    """The RESULTS.md sentence of a :func:`_timing.cold_start` measurement of ``what`` (e.g.
    "`import rrfrei` + first `simulate_force`, bouc_wen")."""
    return (f"Cold start in a fresh interpreter ({what}; temporary `NUMBA_CACHE_DIR`): empty cache "
            f"{cold.cold['import']:.2f} s + {cold.cold['first']:.2f} s (compilation), warm cache "
            f"(filled by that run) {cold.warm['import']:.2f} s + {cold.warm['first']:.2f} s."
            + "".join(f" Note: {n}." for n in cold.notes))
