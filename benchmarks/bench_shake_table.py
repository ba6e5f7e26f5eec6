"""Time of the whole ``rrfrei shake-table`` command on the four bundled BNCS runs; records section
``bench_shake_table``.

Case: ``rrfrei shake-table --law auto --json`` with the defaults (runs CNP100, LAC100, ICA50,
ICA100 in that order; calibrate on the first three, hold out ICA100; law chosen among
plasticity, bouc_wen and hdr on the isolation loops at 25 Hz, the start of the building's
output-error calibration; every catalogue effect and both system effects, each fitted by output
error on the building at 50 Hz; 30 posterior draws per fit), run as a user runs it: a fresh
interpreter each time.  Wall and CPU time (the process's own, from the JSON's ``cpu_s``) are both
recorded: on a shared machine the wall time is inflated by the other processes, the CPU time is not.
"cold" starts with an empty temporary Numba cache (import + compilation + run),
"warm" is a second fresh process that reads the cache the first one filled.  Target (issue 15):
at most 3 minutes warm on 2 cores.  There is no peer, so there is no ratio; every time is
multi-core.

Run: ``python benchmarks/bench_shake_table.py [--quick]`` (``--quick``: a reduced split, ICA50 ->
ICA100 with one effect at 10 Hz; RESULTS.md unchanged).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
from _results import report  # noqa: E402

FULL = ["--law", "auto"]
QUICK = ["ICA50", "ICA100", "--calibrate", "ICA50", "--holdout", "ICA100", "--law", "plasticity",
         "--effects", "rollover", "--rate", "10", "--draws", "8"]


def run(argv: list[str], cache: Path, out: Path) -> dict:
    """The command in a fresh interpreter with ``NUMBA_CACHE_DIR=cache``: wall time and its JSON."""
    env = tm.user_env()
    env["NUMBA_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "rrfrei.app", "shake-table", *argv, "--out", str(out), "--json",
           "--no-progress"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=tm.ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"rrfrei shake-table exited {proc.returncode}:\n{proc.stderr[-3000:]}")
    res = json.loads(proc.stdout)
    return {"wall": wall, "cpu": float(res.get("cpu_s") or float("nan")), "result": res}


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    warnings.simplefilter("ignore")
    argv = QUICK if args.quick else FULL
    with tempfile.TemporaryDirectory(prefix="rrfrei-shake-") as d:
        cache = Path(d) / "cache"
        cold = run(argv, cache, Path(d) / "cold")
        print(f"cold {cold['wall']:.0f} s (CPU {cold['cpu']:.0f} s)", flush=True)
        warm = run(argv, cache, Path(d) / "warm")  # a new --out: no checkpointed fit is reused
        print(f"warm {warm['wall']:.0f} s (CPU {warm['cpu']:.0f} s)", flush=True)
    r = warm["result"]
    hb, ha = r["gap_before"]["holdout"], r["gap_after"]["holdout"]
    steps = ", ".join(f"{k} {v:.0f} s" for k, v in r["seconds"].items())
    lines = [
        "## bench_shake_table", "",
        "The whole `rrfrei shake-table` command on the four bundled BNCS runs (calibrate CNP100, LAC100, "
        "ICA50; hold out ICA100; `--law auto` on the isolation loops as the start; the building calibrated "
        "by output error at 50 Hz; every catalogue effect and both system effects fitted by output error), "
        "each run a fresh process. Cold = empty temporary Numba cache. No peer, so no ratio; wall and "
        "the process's CPU time.", "",
        "| cold wall (CPU) [s] | warm wall (CPU) [s] | warm steps | law | verdict | complete | "
        "held-out isolator-disp NRMSE before -> after | coverage | band width |",
        "|---|---|---|---|---|---|---|---|---|",
        f"| {cold['wall']:.0f} ({cold['cpu']:.0f}) | {warm['wall']:.0f} ({warm['cpu']:.0f}) | {steps} | "
        f"{r['law']} | {r['verdict']} | "
        f"{r['complete']} | {100 * hb['isolator_disp']:.0f} % -> {100 * ha['isolator_disp']:.0f} % | "
        f"{100 * r['coverage']['isolator_disp']:.0f} % | {r['band_width']['isolator_disp']:.2f} |", "",
        "Target: at most 180 s warm on 2 cores."]
    report("bench_shake_table", "\n".join(lines), quick=args.quick,
           headline={"shake_table": dict(cold_s=cold["wall"], warm_s=warm["wall"], warm_cpu_s=warm["cpu"])})


if __name__ == "__main__":
    main()
