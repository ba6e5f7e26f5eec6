"""Time of a whole gap diagnosis (every catalogue effect) of one test; records section ``bench_gap``.

Cases: the bundled synthetic protocol 1 (2401 samples) with ``plasticity`` and ``bouc_wen``,
protocols 2-4 held out, 200 draws per fit.  "cold" is a fresh process with an empty Numba cache
(import + compilation + run); "warm" a second run in the same process.  Reference: one baseline
``rrfrei.calibrate`` (CMA-ES optimum + 300 emcee steps) in the same process, the cost unit of the
calibration workflow; "resumed": a rerun whose fits all come from a checkpoint folder (scoring
only).  Target (issue 12): a whole diagnosis with three held out in at most 60 s warm on 2
cores.  There is no peer, so there is no ratio; every figure is multi-core (the fits use every Numba thread).

Run: ``python benchmarks/bench_gap.py [--quick]`` (``--quick``: plasticity only, RESULTS.md unchanged).
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
from _results import report  # noqa: E402

CHILD = r"""
import json, sys, tempfile, time, warnings
t0 = time.perf_counter()
import rrfrei
from rrfrei.gap import diagnose_gap
law = {law!r}
tests = [rrfrei.load_test(f"protocol{k}") for k in (1, 2, 3, 4)]
t1 = time.perf_counter()
rep = diagnose_gap(tests[0], law, holdout=tests[1:], progress=False)
t2 = time.perf_counter()
rep2 = diagnose_gap(tests[0], law, holdout=tests[1:], progress=False)
t3 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    rrfrei.calibrate(tests[0], law, steps=300, progress=False)
t4 = time.perf_counter()
with tempfile.TemporaryDirectory() as ck:
    diagnose_gap(tests[0], law, holdout=tests[1:], progress=False, checkpoint=ck)
    t5 = time.perf_counter()
    diagnose_gap(tests[0], law, holdout=tests[1:], progress=False, checkpoint=ck)
    t6 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "cold": t2 - t0, "warm": t3 - t2, "calibrate": t4 - t3,
                  "resumed": t6 - t5, "diagnosis": rep2.diagnosis, "same": rep.diagnosis == rep2.diagnosis}))
"""


def run(law: str) -> dict:
    """The child in a fresh interpreter with an empty temporary Numba cache."""
    with tempfile.TemporaryDirectory(prefix="rrfrei-gap-") as cache:
        return tm.fresh_interpreter(CHILD.replace("{law!r}", repr(law)), Path(cache))


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    warnings.simplefilter("ignore")
    rows = []
    for law in ("plasticity",) if args.quick else ("plasticity", "bouc_wen"):
        t = time.perf_counter()
        r = run(law)
        print(law, r, f"{time.perf_counter() - t:.0f} s", flush=True)
        rows.append((law, r))
    lines = [
        "## bench_gap", "",
        "Whole gap diagnosis of the bundled synthetic protocol 1 (2401 samples), every catalogue "
        "effect (nine), "
        "protocols 2-4 held out, 200 draws per fit. Cold = fresh process, empty temporary Numba cache. "
        "No peer, so no ratio; every time is multi-core (the fits use every Numba thread).", "",
        "| law | cold (import + compile + run) [s] | warm run [s] | resumed from checkpoint [s] | "
        "one calibrate (300 steps) [s] | warm / calibrate | diagnosis |", "|---|---|---|---|---|---|---|"]
    for law, r in rows:
        lines.append(f"| {law} | {r['cold']:.1f} | {r['warm']:.1f} | {r['resumed']:.1f} | "
                     f"{r['calibrate']:.1f} | {r['warm'] / r['calibrate']:.2f} | {r['diagnosis']} |")
    lines += ["", "Target (issue 12): at most 60 s for a whole diagnosis with three held out, warm, "
              "on 2 cores."]
    head = {law: dict(cold_s=r["cold"], warm_s=r["warm"]) for law, r in rows}
    report("bench_gap", "\n".join(lines), quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
