"""Speed of a full Bayesian calibration (bouc_wen on protocol 1) and of one likelihood evaluation
against the study's workflow, an openseespy forward model per evaluation, in the same run.

* one evaluation, **per core** (headline): the batched Numba log-likelihood of the public problem
  API (``rrfrei.calibration.setup_problem(...).log_likelihood``, 32 walkers per call) on ONE
  thread, per parameter set, against openseespy on one thread driving the same
  ``elastomericBearingBoucWen`` element along the same 2401 samples in one ``analyze`` call and
  the same Gaussian log-likelihood.  The peer's model building and recorder set-up (before) and
  ``ops.wipe()``, reading the recorder file and summing the log-likelihood (after) are outside
  its timer, so it is timed on ``analyze`` alone; warm-up excluded on both sides, the same
  interleaved repeats, medians, and the two log-likelihoods asserted equal in the same run;
* **multi-core throughput**: the same batched call on every Numba thread, evaluations per second;
* full posterior (multi-core, as a user runs it): ``rrfrei.calibrate(load_test("protocol1"),
  "bouc_wen", seed=s)`` with the defaults (CMA-ES optimum, then emcee until the convergence rule
  holds, capped at ``MAX_STEPS``) for each of ``SEEDS``: wall time, steps, convergence;
* the whole command ``rrfrei calibrate T.csv --law bouc_wen --out DIR`` (defaults: checkpoint,
  300 s budget, figures) on a 2401-sample test made with bouc_wen (eta = 1) on protocol 1 plus
  Gaussian noise of sd 0.1 kN (seed 42), in a fresh process: wall time (target <= 15 s);
* the dense real record ``../shared/data/hysteresis/clt_connection_tannert_spc1/SPC1.csv``
  (33,028 samples, a CLT connection) through the same command (target <= 180 s);
* cold start: a fresh interpreter importing rrfrei and evaluating the log posterior once, with an
  empty and with a warm temporary Numba cache.

Targets: full posterior <= 30 s on 2 cores; >= 100x per evaluation.  Section ``bench_calibration``.
Run: ``python benchmarks/bench_calibration.py [--quick] [--command-runs N]`` (``--quick``: one
seed capped at 300 steps, no whole commands, RESULTS.md unchanged; ``--command-runs N``: only the
2401-sample command, N times in fresh processes, each run's wall and CPU time, the medians and the
load average printed, RESULTS.md unchanged).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(HERE.parent))
sys.path.insert(2, str(HERE.parent / "tests"))

import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402
from bench_laws import opensees_side as law_force_side  # noqa: E402

import rrfrei  # noqa: E402
from rrfrei.calibration import ConvergenceWarning, calibrate, setup_problem  # noqa: E402

MAX_STEPS = 20000  # the package default cap: report the real time to convergence
SPC1 = HERE.parents[1] / "shared" / "data" / "hysteresis" / "clt_connection_tannert_spc1" / "SPC1.csv"
CMD_HEADER = ("| test | wall [s] | CPU [s] | stopped by | steps x walkers | max tau | R-hat max | ESS min "
              "| likelihood points | law path (samples; force error at the optimum) | NRMSE "
              "| posterior.nc [MB] | chain.h5 [MB] | converged |\n"
              "|---|---:|---:|---|---|---:|---:|---:|---|---|---:|---:|---:|---|")
CLI = [sys.executable, "-m", "rrfrei.app", "calibrate"]
WALKERS = 32
TOLERANCE = 1e-8  # relative difference of the two log-likelihoods
SEEDS = (0, 1, 2)
HEADER = ("| seed | wall [s] | optimum [s] | sampling [s] | steps x walkers | max tau | R-hat max "
          "| ESS min | converged | evaluations / s |")
# beta at the registry's calibration hold (0.5): the (qd, beta, gamma) scaling invariance means
# calibration samples gamma with beta held, so the openseespy model must use the same beta
P = dict(k_init=1130.0, qd=3.1, alpha1=0.45, alpha2=-0.7, mu=1.55, eta=1.37, beta=0.5, gamma=0.35)
SIGMA = 0.13  # kN

COLD = tm.COLD_PRELUDE + """
import numpy as np
import rrfrei
from rrfrei.calibration import setup_problem
t1 = time.perf_counter()
pb = setup_problem(rrfrei.load_test("protocol1"), "bouc_wen")
pb.log_prob(np.array([{theta!r}]))
print(json.dumps({{"import": t1 - _t0, "first": time.perf_counter() - t1}}))
"""


def opensees_side(ops, test) -> tm.Side:
    """openseespy forward model as in ``bench_laws`` (build + recorder untimed, ``analyze`` timed,
    wipe + read untimed), reduced to the Gaussian log-likelihood of ``test`` (untimed)."""
    side = law_force_side(ops, "bouc_wen", P, test.disp)

    def finish(state, status):
        r = test.force - side.finish(state, status)
        return -0.5 * np.sum((r / SIGMA) ** 2) - r.size * np.log(SIGMA * np.sqrt(2 * np.pi))

    return tm.Side(side.label, side.run, side.setup, finish)


def main() -> None:
    ap = tm.parser(__doc__)
    ap.add_argument("--command-runs", type=int, default=0, metavar="N",
                    help="only the 2401-sample command, N times; medians printed, RESULTS.md unchanged")
    args = ap.parse_args()
    if args.command_runs > 0:
        return command_runs(args.command_runs)
    import openseespy.opensees as ops

    repeat = 3 if args.quick else 15
    seeds = SEEDS[:1] if args.quick else SEEDS
    max_steps = 300 if args.quick else MAX_STEPS
    test = rrfrei.load_test("protocol1")
    pb = setup_problem(test, "bouc_wen")
    theta = np.array([[P[n] for n in pb.free] + [SIGMA]])
    # --- one evaluation, per core; row 0 is the peer's parameter set ------------------------------
    jitter = 1e-4 * np.random.default_rng(0).standard_normal((WALKERS, theta.shape[1]))
    jitter[0] = 0.0
    batch = np.repeat(theta, WALKERS, axis=0) * (1 + jitter)
    ours = tm.Side("rrfrei", lambda _s: pb.log_likelihood(batch), work=WALKERS)
    c = tm.compare(ours, opensees_side(ops, test), repeat=repeat, tolerance=TOLERANCE,
                   agree=lambda ll, ll_ops: abs(ll[0] - ll_ops) / abs(ll_ops), what="log-likelihood")
    if not np.all(np.isfinite(pb.log_likelihood(batch))):
        raise SystemExit("non-finite log-likelihood in the benchmark batch")
    rate, t_multi, _ = tm.throughput(ours, repeat=repeat)
    print(f"per core {c.ratio:.0f}x; {t_multi.threads} threads {rate:.0f} evaluations/s", flush=True)
    # --- full posterior, several seeds (the chain length to convergence varies with the seed) ----
    runs = []
    for seed in seeds:
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            cal = calibrate(test, "bouc_wen", seed=seed, progress=False, max_steps=max_steps)
        wall = time.perf_counter() - t0
        warn = "; ".join(str(w.message)[:200] for w in caught if issubclass(w.category, ConvergenceWarning))
        runs.append((seed, wall, cal, warn))
        print(f"seed {seed}: {wall:.1f} s, {cal.diagnostics['steps']} steps, converged {cal.converged}",
              flush=True)
    rows = []
    for seed, wall, cal, _ in runs:
        d = cal.diagnostics
        rows.append(
            f"| {seed} | {wall:.1f} | {d['seconds_optimum']:.1f} | {d['seconds_sampling']:.1f} "
            f"| {d['steps']} x {d['walkers']} | {max(d['tau'].values()):.0f} | {d['rhat_max']:.3f} "
            f"| {d['ess_min']:.0f} | {cal.converged} | {d['evaluations'] / d['seconds_sampling']:.0f} |"
        )
    walls = [w for _, w, _, _ in runs]
    warn = "; ".join(f"seed {s}: {w}" for s, _, _, w in runs if w)
    # --- whole commands: 2401-sample bouc_wen test and the dense SPC1 record ------------------
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())  # before the commands: 1, 5, 15 min
    cmd_rows, cmd_walls = [], []
    if not args.quick:
        cmd_rows.append(command_row("2401-sample bouc_wen (eta = 1, noise 0.1 kN)", bouc_wen_csv(), [],
                                    cmd_walls))
        if SPC1.exists():
            cmd_rows.append(command_row("SPC1 (33,028 samples, real CLT connection)", SPC1, [
                "--disp-col", "Lead Actuator Displacment:mm", "--force-col", "Lead Actuator Force:kN"]))
        else:
            cmd_rows.append(f"| SPC1 | missing: {SPC1.name} not found next to the repository |"
                            + " |" * 13)
    # --- cold start ------------------------------------------------------------------------------
    cold = tm.cold_start(COLD.format(theta=list(theta[0])))
    multi_row = (f"| multi-core throughput: rrfrei on {t_multi.threads} threads | {rate:.0f} evaluations/s "
                 f"({tm.fmt(t_multi.per_unit)} per evaluation) |")
    cold_rows = (f"| cold start (fresh interpreter: import + problem + first log posterior), empty cache "
                 f"| {cold.cold['import']:.2f} s + {cold.cold['first']:.2f} s |\n"
                 f"| cold start, warm cache (filled by the empty-cache run) "
                 f"| {cold.warm['import']:.2f} s + {cold.warm['first']:.2f} s |")
    md = f"""## bench_calibration

One likelihood evaluation (bouc_wen, 2401 samples of protocol 1, Gaussian noise). **Per core**:
both single-threaded, median of {repeat} interleaved runs after one warm-up each; rrfrei evaluates
{WALKERS} walkers per batched call (time per evaluation = call / {WALKERS}); openseespy is timed on
its `analyze(2401)` alone (model building, `ops.wipe()`, reading the recorder file and the
log-likelihood sum outside its timer). The two log-likelihoods are asserted equal in the same run.

| one likelihood evaluation | value |
|---|---|
| rrfrei, batched Numba, 1 thread, per evaluation | {tm.fmt(c.ours.per_unit)} |
| openseespy forward model (`analyze` over 2401 steps), 1 thread | {tm.fmt(c.peer.per_unit)} |
| **ratio per core** | **{c.ratio:.0f}x** (target >= 100x) |
| same log-likelihood (relative difference, asserted <= {TOLERANCE:g}) | {c.discrepancy:.1e} |
{multi_row}
{cold_rows}
{"".join(f"Note: {n}." for n in cold.notes)}

Full `bouc_wen` posterior on the bundled SYNTHETIC protocol 1 (2401 samples, 7 free parameters +
sigma, beta held; defaults: CMA-ES optimum and least-squares polish, walkers drawn from the
Laplace approximation, emcee until the convergence rule holds, cap {max_steps} steps), seeds
{", ".join(map(str, seeds))}; **multi-core** (every Numba thread, as a user runs it):

{HEADER}
|---|---:|---:|---:|---|---:|---:|---:|---|---:|
{chr(10).join(rows)}

Full posterior wall time: median {np.median(walls):.1f} s, worst {max(walls):.1f} s
(target <= 30 s on 2 cores).
{("Warning: " + warn) if warn else ""}
"""
    if cmd_rows:
        md += f"""
Whole `rrfrei calibrate --law bouc_wen` commands (defaults: checkpoint in the output folder,
300 s budget, predictive checks and figures; fresh process, the project's own Numba cache (warm
after the runs above); load average {load}):

{CMD_HEADER}
{chr(10).join(cmd_rows)}

Targets: 2401 samples <= 15 s; SPC1 converged in <= 180 s with posterior.nc <= 10 MB.
"""
    head = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio, multi_rate=rate,
                threads=t_multi.threads, posterior_median_s=float(np.median(walls)),
                posterior_worst_s=max(walls), command_s=cmd_walls[0] if cmd_walls else None)
    report("bench_calibration", md, quick=args.quick, headline=head)


def command_runs(n: int) -> None:
    """The 2401-sample command ``n`` times (fresh processes, warm cache): wall and CPU per run,
    their medians and the load average before and after (the machine may be shared)."""
    csv = bouc_wen_csv()
    before = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    runs = []
    for i in range(n):
        out = Path(tempfile.mkdtemp(prefix="bench_cal_out_"))
        cpu0, t0 = tm.children_cpu(), time.perf_counter()
        run = subprocess.run([*CLI, str(csv), "--law", "bouc_wen", "--out", str(out), "--quiet"],
                             capture_output=True, text=True, cwd=HERE.parent, env=tm.user_env())
        wall, cpu = time.perf_counter() - t0, tm.children_cpu() - cpu0
        steps = json.loads((out / "run.json").read_text())["steps"] if run.returncode == 0 else None
        runs.append((wall, cpu))
        print(f"run {i + 1}: {wall:.1f} s wall, {cpu:.1f} s CPU, exit {run.returncode}, {steps} steps",
              flush=True)
    after = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"median {np.median([w for w, _ in runs]):.1f} s wall, {np.median([c for _, c in runs]):.1f} s "
          f"CPU over {n} runs; load average before {before}, after {after}")


def bouc_wen_csv() -> Path:
    """The 2401-sample test of the command benchmark, written to a temporary CSV."""
    import pandas as pd

    from rrfrei.protocols import protocol1

    t, u = protocol1()
    p = dict(P, eta=1.0)
    f = rrfrei.simulate_force("bouc_wen", p, u, time=t)
    f = f + 0.1 * np.random.default_rng(42).standard_normal(u.size)
    path = Path(tempfile.mkdtemp(prefix="bench_cal_")) / "bouc_wen_2401.csv"
    pd.DataFrame({"time_s": t, "disp_mm": 1e3 * u, "force_kN": f}).to_csv(path, index=False)
    return path


def command_row(label: str, csv: Path, extra: list[str], walls: list | None = None) -> str:
    """Run the command in a fresh process on ``csv`` and return its table row."""
    out = Path(tempfile.mkdtemp(prefix="bench_cal_out_"))
    env = tm.user_env()  # as the user runs it: no BLAS pins, the project's own Numba cache
    cpu0, t0 = tm.children_cpu(), time.perf_counter()
    run = subprocess.run([*CLI, str(csv), "--law", "bouc_wen", "--out", str(out), "--quiet", *extra],
                         capture_output=True, text=True, cwd=HERE.parent, env=env)
    wall, cpu = time.perf_counter() - t0, tm.children_cpu() - cpu0
    if walls is not None and run.returncode == 0:
        walls.append(wall)
    print(f"{label}: {wall:.1f} s wall, {cpu:.1f} s CPU, exit {run.returncode}\n{run.stderr[-1500:]}",
          flush=True)
    if run.returncode != 0:
        return f"| {label} | {wall:.1f} | {cpu:.1f} | failed (exit {run.returncode}) |" + " |" * 10
    r = {**json.loads((out / "result.json").read_text()), **json.loads((out / "run.json").read_text())}
    mb = (out / "posterior.nc").stat().st_size / 1e6
    ck = out / "chain.h5"
    ck_mb = ck.stat().st_size / 1e6 if ck.exists() else float("nan")
    lik = f"{r['likelihood_points']} of {r['points']}"
    p = r.get("path") or {}
    path = (f"{p['samples']} (>= {p['half_cycle_points']} per half-cycle; {p['error_rms_kN']:.3g} kN "
            f"RMS = {p['error_rms_sigma']:.3f} sigma)" if p.get("decimated") else "every sample")
    return (f"| {label} | {wall:.1f} | {cpu:.1f} | {r['stopped_by']} | {r['steps']} x {r.get('walkers', '')} "
            f"| {r['tau_max']:.0f} | {r['rhat_max']:.3f} | {r['ess_min']:.0f} | {lik} | {path} "
            f"| {100 * r['nrmse']:.2f} % | {mb:.1f} | {ck_mb:.1f} | {r['converged']} |")


if __name__ == "__main__":
    main()
