"""The timing rules every benchmark follows (issue 13.4), in one place.

A ratio means something only if both sides get the same treatment:

* **warm-up excluded for both**: each side runs ``warmup`` times untimed first (Numba loads or
  compiles, openseespy loads its library, caches fill);
* **same repeats, same statistic**: both sides are timed ``repeat`` times, interleaved (ours,
  peer, ours, peer, ...) so that a change of the machine's load hits both alike, and compared by
  their **median**;
* **setup and teardown outside the timer**: a :class:`Side` has an untimed ``setup`` (e.g. build
  the OpenSees model) and an untimed ``finish`` (e.g. ``ops.wipe()`` and reading the recorder
  file); only ``run`` is timed;
* **agreement asserted in the same run**: :func:`compare` raises :class:`AgreementError` when
  the two outputs differ by more than the stated tolerance, so no ratio is ever printed for two
  codes that computed different things;
* **per core**: :func:`compare` runs both sides on one thread (Numba's ``set_num_threads(1)``;
  the BLAS/OpenMP pools are pinned to one thread below, before NumPy is imported), so the ratio is
  single-threaded against single-threaded.  Multi-core throughput is a separate figure
  (:func:`throughput`) and never divided by a single-threaded peer.

Cold starts (:func:`cold_start`) run a snippet in fresh interpreters with an explicit temporary
``NUMBA_CACHE_DIR`` (which ``rrfrei._jit_cache`` respects): first with the folder empty (*cold*:
everything compiles), then again with the folder the first run filled (*warm*), and check that
the warm run wrote no new cache entry, i.e. that it read the cache it claims to read.

Import this module before NumPy (``import _timing`` first in a benchmark script).
"""

from __future__ import annotations

import os

# one thread for BLAS/OpenMP pools (NumPy peers, LAPACK inside OpenSees): must precede numpy.
# Numba's own thread count does not follow these (it reads NUMBA_NUM_THREADS).
PINNED = tuple(v for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
               if v not in os.environ)  # the ones this module sets (user settings are kept)
for _var in PINNED:
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

__all__ = [
    "AgreementError",
    "ColdStart",
    "Comparison",
    "Side",
    "Timing",
    "cold_start",
    "compare",
    "fresh_interpreter",
    "cores",
    "fmt",
    "measure",
    "parser",
    "read_binary_recorder",
    "single_thread",
    "throughput",
    "threads",
    "children_cpu",
    "user_env",
]


class AgreementError(AssertionError):
    """Ours and the peer computed different results: the ratio would mean nothing."""


def _none() -> None:
    return None


def _identity(_state: Any, out: Any) -> Any:
    return out


@dataclass(frozen=True)
class Side:
    """One side of a comparison.

    Attributes
    ----------
    label
        Name in the tables.
    run
        The timed work: ``run(state) -> raw``.
    setup
        Untimed, before every call of ``run``: ``setup() -> state`` (default: None).
    finish
        Untimed, after every call of ``run``: ``finish(state, raw) -> output`` (teardown and
        read-back, e.g. ``ops.wipe()`` then loading the recorder file); the output of the last
        timed repeat is what the agreement check sees.  Default: ``raw``.
    work
        Units of work one ``run`` does (e.g. 32 likelihood evaluations in one batched call);
        ratios compare time per unit.
    """

    label: str
    run: Callable[[Any], Any]
    setup: Callable[[], Any] = _none
    finish: Callable[[Any, Any], Any] = _identity
    work: float = 1.0

    def once(self, clock: Callable[[], float] = time.perf_counter) -> tuple[float, Any]:
        """Setup (untimed), run (timed), finish (untimed): ``(seconds, output)``."""
        state = self.setup()
        t0 = clock()
        raw = self.run(state)
        seconds = clock() - t0
        return seconds, self.finish(state, raw)


@dataclass(frozen=True)
class Timing:
    """Repeated timings [s] of one side (warm-ups excluded)."""

    label: str
    times: tuple[float, ...]
    threads: int
    work: float = 1.0

    @property
    def median(self) -> float:
        """Median time [s] of one run: the statistic every ratio uses."""
        return statistics.median(self.times)

    @property
    def per_unit(self) -> float:
        """Median time [s] per unit of work (``median / work``)."""
        return self.median / self.work

    @property
    def spread(self) -> tuple[float, float]:
        """(min, max) time [s]."""
        return min(self.times), max(self.times)

    def describe(self, per: float = 1.0, unit: str = "") -> str:
        """``"1.23 ms (1.20-1.31, median of 5)"`` for the time divided by ``per``."""
        lo, hi = self.spread
        return f"{fmt(self.median / per)}{unit} ({fmt(lo / per, bare=True)}-{fmt(hi / per)}, " \
               f"median of {len(self.times)})"


@dataclass(frozen=True)
class Comparison:
    """Ours against the peer on the same work, single-threaded, agreement checked.

    Attributes
    ----------
    ours, peer
        The two timings (same repeats, warm-ups excluded).
    discrepancy
        The agreement measure returned by the check (e.g. max relative difference).
    tolerance
        The largest discrepancy accepted.
    """

    ours: Timing
    peer: Timing
    discrepancy: float
    tolerance: float

    @property
    def ratio(self) -> float:
        """Peer median time per unit of work / ours (per core: both on one thread)."""
        return self.peer.per_unit / self.ours.per_unit


@dataclass(frozen=True)
class ColdStart:
    """Marks [s] printed by a snippet run in a fresh interpreter, cold then warm.

    Attributes
    ----------
    cold
        Empty temporary ``NUMBA_CACHE_DIR`` (everything compiles).
    warm
        The same folder, as the cold run left it (everything should load from it).
    new_in_warm
        Cache files the warm run added (0 when it read everything from the cache).
    """

    cold: dict[str, float]
    warm: dict[str, float]
    new_in_warm: int = 0
    notes: tuple[str, ...] = field(default=())

    def describe(self) -> str:
        """``"empty cache 1.20 s + 9.31 s (compiles), warm cache 0.80 s + 0.20 s"`` (marks in order)."""
        def marks(d: dict[str, float]) -> str:
            return " + ".join(f"{v:.2f} s" for v in d.values())

        note = "".join(f"; note: {n}" for n in self.notes)
        return (f"empty cache {marks(self.cold)} (compiles), warm cache (filled by that run) "
                f"{marks(self.warm)}{note}")


def read_binary_recorder(path: str | Path, ncols: int) -> Any:
    """(rows, ncols) float64 array of an OpenSees ``-binary`` recorder file.

    The fairest way to take openseespy's results out of one ``analyze(n)`` call: a ``-binary``
    recorder writes each record as its ``ncols`` doubles in native byte order plus one newline
    byte (openseespy 3.7.1.2; checked against the ``-file ... -precision 17`` text of the same
    run, equal bit for bit), where the text recorder formats 17 digits per value inside
    ``analyze``: on the 5,000-step plan bouc_wen history of ``bench_plan_laws`` that formatting
    was 29 % of openseespy's timed run (62 ms against 48 ms).  Raises ValueError when the file
    is not that layout.
    """
    import numpy as np

    raw = np.fromfile(path, dtype=np.uint8)
    width = 8 * ncols + 1
    if raw.size == 0 or raw.size % width:
        raise ValueError(f"{path}: {raw.size} bytes is not a whole number of {ncols}-double records")
    rows = raw.reshape(-1, width)
    if not np.all(rows[:, -1] == ord("\n")):
        raise ValueError(f"{path}: records of {ncols} doubles do not end in a newline byte")
    return np.ascontiguousarray(rows[:, :-1]).view(np.float64).reshape(-1, ncols)


def fmt(seconds: float, bare: bool = False) -> str:
    """Seconds in a readable unit (``bare``: the number only, in the unit ``fmt`` would pick)."""
    for scale, unit in ((1.0, "s"), (1e-3, "ms"), (1e-6, "us")):
        if seconds >= scale or unit == "us":
            value = seconds / scale
            digits = 2 if value < 10 else (1 if value < 100 else 0)
            text = f"{value:.{digits}f}"
            return text if bare else f"{text} {unit}"
    raise AssertionError("unreachable")


def cores() -> int:
    """Numba threads available (``NUMBA_NUM_THREADS``, default the machine's cores)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


@contextlib.contextmanager
def threads(n: int) -> Iterator[int]:
    """Run the block with ``n`` Numba threads (clamped to :func:`cores`); restore afterwards."""
    import numba

    old = numba.get_num_threads()
    n = max(1, min(int(n), cores()))
    numba.set_num_threads(n)
    try:
        yield n
    finally:
        numba.set_num_threads(old)


def single_thread() -> contextlib.AbstractContextManager[int]:
    """One Numba thread (BLAS/OpenMP pools are single-threaded for the whole benchmark)."""
    return threads(1)


def measure(side: Side, *, repeat: int, warmup: int = 1,
            clock: Callable[[], float] = time.perf_counter) -> tuple[Timing, Any]:
    """Time ``side`` alone with the current thread count: ``(Timing, last output)``."""
    import numba

    if repeat < 1 or warmup < 0:
        raise ValueError(f"repeat must be >= 1 and warmup >= 0, got repeat={repeat}, warmup={warmup}")
    out = None
    for _ in range(warmup):
        _, out = side.once(clock)
    times = []
    for _ in range(repeat):
        seconds, out = side.once(clock)
        times.append(seconds)
    return Timing(side.label, tuple(times), numba.get_num_threads(), side.work), out


def compare(ours: Side, peer: Side, *, repeat: int, agree: Callable[[Any, Any], float],
            tolerance: float, warmup: int = 1, what: str = "",
            clock: Callable[[], float] = time.perf_counter) -> Comparison:
    """Per-core comparison: both sides single-threaded, interleaved, medians, agreement asserted.

    Parameters
    ----------
    ours, peer
        The two sides (each with its own untimed setup and finish).
    repeat
        Timed runs per side (the same for both).
    agree
        ``agree(ours_output, peer_output) -> float``, a discrepancy such as the max relative
        difference; checked against ``tolerance`` in this run.
    tolerance
        Largest accepted discrepancy; a larger one (or NaN) raises :class:`AgreementError`.
    warmup
        Untimed runs per side before timing (the same for both).
    what
        Name of the benchmark case, for the error message.
    clock
        The timer (``time.perf_counter``).

    Returns
    -------
    Comparison
    """
    if repeat < 1 or warmup < 0:
        raise ValueError(f"repeat must be >= 1 and warmup >= 0, got repeat={repeat}, warmup={warmup}")
    with single_thread() as n:
        out_o = out_p = None
        for _ in range(warmup):
            _, out_o = ours.once(clock)
            _, out_p = peer.once(clock)
        t_o, t_p = [], []
        for _ in range(repeat):
            s, out_o = ours.once(clock)
            t_o.append(s)
            s, out_p = peer.once(clock)
            t_p.append(s)
    disc = float(agree(out_o, out_p))
    if not disc <= tolerance:
        raise AgreementError(
            f"{what or ours.label}: {ours.label} and {peer.label} disagree by {disc:.3g} "
            f"(tolerance {tolerance:.3g}); no ratio is reported for different results"
        )
    return Comparison(Timing(ours.label, tuple(t_o), n, ours.work),
                      Timing(peer.label, tuple(t_p), n, peer.work), disc, tolerance)


def throughput(side: Side, *, repeat: int, warmup: int = 1,
               n_threads: int | None = None) -> tuple[float, Timing, Any]:
    """Throughput on ``n_threads`` (default every core, :func:`cores`): ``(side.work per second
    at the median, Timing, output)``."""
    with threads(n_threads or cores()):
        timing, out = measure(side, repeat=repeat, warmup=warmup)
    return side.work / timing.median, timing, out


# ---------------------------------------------------------------------------------------------
# cold start

def _cache_files(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if p.suffix in (".nbi", ".nbc", ".py")}


def children_cpu() -> float:
    """User + system CPU seconds of every terminated child (and its waited-for descendants)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def user_env() -> dict[str, str]:
    """This process's environment as the user set it: without the BLAS pins of this module and
    without ``rrfrei._jit_cache``'s own ``NUMBA_CACHE_DIR`` (so a child chooses its cache itself),
    the repository first on ``PYTHONPATH``."""
    env = dict(os.environ)
    for var in PINNED:
        env.pop(var, None)
    if env.pop("_RRFREI_NUMBA_CACHE", None) is not None:
        env.pop("NUMBA_CACHE_DIR", None)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def fresh_interpreter(code: str, cache: Path) -> dict:
    """Run ``code`` in a fresh interpreter with ``NUMBA_CACHE_DIR=cache`` (the repository first on
    ``PYTHONPATH`` and as working directory); return the JSON object of its last stdout line."""
    env = user_env()
    env["NUMBA_CACHE_DIR"] = str(cache)
    run = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f"cold-start snippet failed (exit {run.returncode}):\n{run.stderr[-3000:]}")
    return json.loads(run.stdout.strip().splitlines()[-1])


def cold_start(code: str) -> ColdStart:
    """Run ``code`` in a fresh interpreter twice: empty Numba cache, then the cache it filled.

    ``code`` must print, as its last stdout line, a JSON object of named times [s] (e.g.
    ``{"import": ..., "first call": ...}``), measured from its own first line.  Both runs use the
    same explicit temporary ``NUMBA_CACHE_DIR`` (respected by ``rrfrei._jit_cache``; the
    generated per-law kernels of ``rrfrei.laws.specialise`` live inside it too), with the
    repository first on ``PYTHONPATH`` and as working directory.
    """
    with tempfile.TemporaryDirectory(prefix="rrfrei-cold-") as d:
        cache = Path(d)
        cold = fresh_interpreter(code, cache)
        before = _cache_files(cache)
        warm = fresh_interpreter(code, cache)
        new = _cache_files(cache) - before
    notes = () if not new else (f"the warm run still wrote {len(new)} cache files, e.g. {sorted(new)[:3]}",)
    return ColdStart(cold, warm, len(new), notes)


COLD_PRELUDE = "import json, time\n_t0 = time.perf_counter()\n"
"""Start of a cold-start snippet: ``_t0`` is the interpreter's first timed instant."""


def parser(doc: str | None) -> argparse.ArgumentParser:
    """The common command line: ``--quick`` (smoke run: few repeats, small sizes, RESULTS.md
    left unchanged); a script adds its own options."""
    ap = argparse.ArgumentParser(description=(doc or "").split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: short repeats and sizes; prints, does not write RESULTS.md")
    return ap
