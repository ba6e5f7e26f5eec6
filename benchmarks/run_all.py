"""Regenerate ``benchmarks/RESULTS.md``: every benchmark script, one after the other, each in a
fresh process (so no benchmark inherits another's threads, caches or imports).

Run on a quiet machine: ``python benchmarks/run_all.py`` (about an hour on 2 cores, most of it
the fresh-clone demo and test suite, the calibration commands and the gap diagnosis).
``--quick`` smoke-runs every script (RESULTS.md unchanged); ``--only NAME ...`` runs a subset
(names without ``bench_`` and ``.py``, e.g. ``--only spectra laws``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: Order: the cheap per-core comparisons first, the long multi-core and whole-command runs last.
SCRIPTS = ("spectra", "laws", "plan_laws", "time_history", "plan_building", "rubber", "calibration",
           "convergence",
           "propagation", "gap",
           "shake_table", "rubber_multirate", "fresh_clone")
#: Sections written by a mode of another script (no --quick mode: skipped by a smoke run).
MODES = {"rubber_multirate": ("rubber", "--multirate")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run of every script; RESULTS.md unchanged")
    ap.add_argument("--only", nargs="+", choices=SCRIPTS, metavar="NAME", help=f"subset of {SCRIPTS}")
    args = ap.parse_args()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE.parent), os.environ.get("PYTHONPATH", "")]))
    failed = []
    for name in args.only or SCRIPTS:
        script, *extra = MODES.get(name, (name,))
        if extra and args.quick:
            continue
        quick = ["--quick"] if args.quick else []
        argv = [sys.executable, str(HERE / f"bench_{script}.py"), *extra, *quick]
        print(f"==> bench_{name} (load average {os.getloadavg()[0]:.1f})", flush=True)
        t0 = time.perf_counter()
        code = subprocess.run(argv, cwd=HERE.parent, env=env).returncode
        print(f"<== bench_{name}: exit {code}, {time.perf_counter() - t0:.0f} s", flush=True)
        if code != 0:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
