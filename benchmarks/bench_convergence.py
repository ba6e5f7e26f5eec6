"""Convergence that agrees with itself, on a dense real record, seed after seed (issue 28.7).

The whole command ``rrfrei calibrate SPC1.csv --law bouc_wen`` with every default (checkpoint,
300 s budget, automatic decimation of the law path, predictive checks and figures) on the real
33,028-sample CLT connection test ``../shared/data/hysteresis/clt_connection_tannert_spc1/SPC1.csv``,
for seeds 0-4, each in a fresh process with the project's own (warm) Numba cache.  Each row: wall
time, CPU time (user + system of the process and its children, ``getrusage(RUSAGE_CHILDREN)``),
what stopped the sampler, the final check (R-hat on the stored thinned draws, ESS) and
``converged`` from ``run.json``.  Goal: converged in 5 of 5 seeds, each at most 3 minutes on 2
cores.  No peer: the figure is a time to an answer, not a ratio.  Section ``bench_convergence``.

Run: ``python benchmarks/bench_convergence.py [--seeds 0 1 2 3 4] [--quick]`` (``--quick``: seed 0
only, RESULTS.md unchanged).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import _timing as tm  # noqa: E402
from _results import report  # noqa: E402

SPC1 = HERE.parents[1] / "shared" / "data" / "hysteresis" / "clt_connection_tannert_spc1" / "SPC1.csv"
COLUMNS = ["--disp-col", "Lead Actuator Displacment:mm", "--force-col", "Lead Actuator Force:kN"]
CLI = [sys.executable, "-m", "rrfrei.app", "calibrate"]
GOAL_S = 180.0
HEADER = ("| seed | wall [s] | CPU [s] | exit | stopped by | steps x walkers | max tau | R-hat max "
          "| ESS min | converged |\n|---:|---:|---:|---:|---|---|---:|---:|---:|---|")


def run_seed(seed: int) -> tuple[str, bool, float]:
    """One whole command; its table row, whether it converged and its wall time [s]."""
    out = Path(tempfile.mkdtemp(prefix=f"bench_conv_{seed}_"))
    cpu0, t0 = tm.children_cpu(), time.perf_counter()
    run = subprocess.run([*CLI, str(SPC1), "--law", "bouc_wen", "--out", str(out), "--quiet",
                          "--seed", str(seed), *COLUMNS],
                         capture_output=True, text=True, cwd=HERE.parent, env=tm.user_env())
    wall, cpu = time.perf_counter() - t0, tm.children_cpu() - cpu0
    print(f"seed {seed}: {wall:.1f} s wall, {cpu:.1f} s CPU, exit {run.returncode}\n{run.stderr[-800:]}",
          flush=True)
    if run.returncode != 0 or not (out / "run.json").exists():
        return (f"| {seed} | {wall:.1f} | {cpu:.1f} | {run.returncode} | failed |  |  |  |  | False |",
                False, wall)
    r = {**json.loads((out / "result.json").read_text()), **json.loads((out / "run.json").read_text())}
    ok = bool(r["converged"])
    return (f"| {seed} | {wall:.1f} | {cpu:.1f} | {run.returncode} | {r['stopped_by']} "
            f"| {r['steps']} x {r.get('walkers', '')} | {r['tau_max']:.0f} | {r['rhat_max']:.3f} "
            f"| {r['ess_min']:.0f} | {ok} |", ok, wall)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--quick", action="store_true", help="seed 0 only; RESULTS.md unchanged")
    args = ap.parse_args()
    if not SPC1.exists():
        raise SystemExit(f"bench_convergence: {SPC1} not found (../shared beside the repository)")
    seeds = [0] if args.quick else args.seeds
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    rows = [run_seed(s) for s in seeds]
    n_ok = sum(ok for _, ok, _ in rows)
    worst = max(w for _, _, w in rows)
    md = f"""## bench_convergence

`rrfrei calibrate SPC1.csv --law bouc_wen` with every default (real CLT connection test, 33,028
samples; 300 s budget; the sampler stops only when the final check passes: R-hat < 1.05 on the
stored thinned draws and ESS >= 400), one fresh process per seed, warm Numba cache; load average
before the runs {load}:

{HEADER}
{chr(10).join(r for r, _, _ in rows)}

Converged in {n_ok} of {len(rows)} seeds; worst wall time {worst:.0f} s (goal: {len(rows)} of
{len(rows)}, each <= {GOAL_S:.0f} s on 2 cores).
"""
    report("bench_convergence", md, quick=args.quick,
           headline=dict(converged=n_ok, seeds=len(rows), worst_s=worst))


if __name__ == "__main__":
    main()
