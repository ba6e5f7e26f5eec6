"""Speed of a full Bayesian calibration (bouc_wen on protocol 1) and of one likelihood evaluation
against the study's workflow, an openseespy forward model per evaluation, in the same run.

* full posterior: ``rrfrei.calibrate(load_test("protocol1"), "bouc_wen", seed=s)`` with the
  defaults (CMA-ES optimum, then emcee until the convergence rule of
  ``rrfrei.calibration.sampler`` holds, capped at ``MAX_STEPS``) for each of ``SEEDS``, since the
  chain length to convergence varies with the seed: wall time, steps, convergence, evaluations
  per second;
* the whole command ``rrfrei calibrate T.csv --law bouc_wen --out DIR`` (defaults: checkpoint,
  300 s budget, figures) on a 2401-sample test made with bouc_wen (eta = 1) on protocol 1 plus
  Gaussian noise of sd 0.1 kN (seed 42), in a fresh process: wall time (target <= 15 s);
* the dense real record ``../shared/data/hysteresis/clt_connection_tannert_spc1/SPC1.csv``
  (33,028 samples, a CLT connection) through the same command: wall time (target <= 180 s),
  why it stopped, steps, tau, R-hat, ESS, NRMSE and the size of posterior.nc (target <= 10 MB);
* one evaluation: the batched Numba log-likelihood (32 walkers, ``prange``) per parameter set,
  against openseespy driving the same ``elastomericBearingBoucWen`` element along the same 2401
  samples and the same Gaussian log-likelihood (model build included, as a per-evaluation
  forward model in the study's loop);
* cold start: a fresh process importing rrfrei and evaluating the log posterior once (warm Numba
  cache).

Targets: full posterior <= 30 s on 2 cores; >= 100x per evaluation.  Section ``bench_calibration``.
Times depend on the machine's load (printed with the results); nothing is asserted.
Run: ``python benchmarks/bench_calibration.py``.
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

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

from _results import write_section  # noqa: E402

import rrfrei  # noqa: E402
from rrfrei.calibration import ConvergenceWarning, calibrate, setup_problem  # noqa: E402

MAX_STEPS = 20000  # the package default cap: report the real time to convergence
SPC1 = HERE.parents[1] / "shared" / "data" / "hysteresis" / "clt_connection_tannert_spc1" / "SPC1.csv"
CMD_HEADER = ("| test | wall [s] | stopped by | steps x walkers | max tau | R-hat max | ESS min "
              "| likelihood points | NRMSE | posterior.nc [MB] | chain.h5 [MB] | converged |\n"
              "|---|---:|---|---|---:|---:|---:|---|---:|---:|---:|---|")
CLI = [sys.executable, "-c", "import sys; from rrfrei.app.cli import main; sys.exit(main())", "calibrate"]
N_OPS = 20  # openseespy evaluations timed
SEEDS = (0, 1, 2)
HEADER = ("| seed | wall [s] | optimum [s] | sampling [s] | steps x walkers | max tau | R-hat max "
          "| ESS min | converged | evaluations / s |")
# beta at the registry's calibration hold (0.5): the (qd, beta, gamma) scaling invariance means
# calibration samples gamma with beta held, so the openseespy model must use the same beta
P = dict(k_init=1130.0, qd=3.1, alpha1=0.45, alpha2=-0.7, mu=1.55, eta=1.37, beta=0.5, gamma=0.35)

COLD = """
import time
t0 = time.perf_counter()
import numpy as np
import rrfrei
from rrfrei.calibration import setup_problem
pb = setup_problem(rrfrei.load_test("protocol1"), "bouc_wen")
pb.log_prob(np.array([{theta!r}]))
print(time.perf_counter() - t0)
"""


def main() -> None:
    import opensees_harness as h
    import openseespy.opensees as ops

    test = rrfrei.load_test("protocol1")
    pb = setup_problem(test, "bouc_wen")
    theta = np.array([[P[n] for n in pb.free] + [0.13]])
    pb.log_prob(theta)  # compile / load cache
    # --- one evaluation, batched -------------------------------------------------------------
    jitter = 1e-4 * np.random.default_rng(0).standard_normal((32, theta.shape[1]))
    batch = np.repeat(theta, 32, axis=0) * (1 + jitter)
    reps = 20
    t0 = time.perf_counter()
    for _ in range(reps):
        ll = pb.log_likelihood(batch)
    ours = (time.perf_counter() - t0) / (reps * 32)
    assert np.all(np.isfinite(ll))
    # --- openseespy forward model ----------------------------------------------------------------
    t0 = time.perf_counter()
    for _ in range(N_OPS):
        f_ops = h.element_force_recorder(ops, "bouc_wen", P, test.disp)
        r = test.force - f_ops
        ll_ops = -0.5 * np.sum((r / 0.13) ** 2) - test.force.size * np.log(0.13 * np.sqrt(2 * np.pi))
    theirs = (time.perf_counter() - t0) / N_OPS
    ll_ours = pb.log_likelihood(theta)[0]
    agree = abs(ll_ops - ll_ours) / abs(ll_ours)
    if not agree < 1e-8:  # the ratio means nothing unless both compute the same number
        raise SystemExit(f"openseespy and rrfrei log-likelihoods differ: {ll_ops} vs {ll_ours}")
    # --- full posterior, several seeds (the chain length to convergence varies with the seed) ----
    runs = []
    for seed in SEEDS:
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            cal = calibrate(test, "bouc_wen", seed=seed, progress=False, max_steps=MAX_STEPS)
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
    cmd_rows = [command_row("2401-sample bouc_wen (eta = 1, noise 0.1 kN)", bouc_wen_csv(), [])]
    if SPC1.exists():
        cmd_rows.append(command_row("SPC1 (33,028 samples, real CLT connection)", SPC1, [
            "--disp-col", "Lead Actuator Displacment:mm", "--force-col", "Lead Actuator Force:kN"]))
    else:
        cmd_rows.append(f"| SPC1 | missing: {SPC1.name} not found next to the repository |"
                        + " |" * 11)
    # --- cold start ------------------------------------------------------------------------------
    env = dict(os.environ)
    out = subprocess.run([sys.executable, "-c", COLD.format(theta=list(theta[0]))], env=env,
                         capture_output=True, text=True, check=True)
    cold = float(out.stdout.strip().splitlines()[-1])
    md = f"""## bench_calibration

Full `bouc_wen` posterior on the bundled SYNTHETIC protocol 1 (2401 samples, 7 free parameters +
sigma, beta held; defaults: CMA-ES optimum and least-squares polish, walkers drawn from the
Laplace approximation, emcee until bulk and tail ESS >= 400, R-hat < 1.04 and >= 10 stable tau,
cap {MAX_STEPS} steps), seeds {", ".join(map(str, SEEDS))}:

{HEADER}
|---|---:|---:|---:|---|---:|---:|---:|---|---:|
{chr(10).join(rows)}

Full posterior wall time: median {np.median(walls):.1f} s, worst {max(walls):.1f} s
(target <= 30 s on 2 cores).

| one likelihood evaluation | value |
|---|---|
| batched Numba (32 walkers, 2 threads) | {1e3 * ours:.3f} ms |
| openseespy forward model (build + 2401 steps + log-likelihood) | {1e3 * theirs:.2f} ms |
| **ratio openseespy / rrfrei per evaluation** | **{theirs / ours:.0f}x** (target >= 100x) |
| same log-likelihood (relative difference) | {agree:.1e} |
| cold start (fresh process: import + first log posterior, warm cache) | {cold:.2f} s |
{("Warning: " + warn) if warn else ""}

Whole `rrfrei calibrate --law bouc_wen` commands (defaults: checkpoint in the output folder,
300 s budget, predictive checks and figures; fresh process, warm Numba cache; load average
{load}):

{CMD_HEADER}
{chr(10).join(cmd_rows)}

Targets: 2401 samples <= 15 s; SPC1 converged in <= 180 s with posterior.nc <= 10 MB.
"""
    print(md)
    write_section("bench_calibration", md)


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


def command_row(label: str, csv: Path, extra: list[str]) -> str:
    """Run the command in a fresh process on ``csv`` and return its table row."""
    out = Path(tempfile.mkdtemp(prefix="bench_cal_out_"))
    t0 = time.perf_counter()
    run = subprocess.run([*CLI, str(csv), "--law", "bouc_wen", "--out", str(out), "--quiet", *extra],
                         capture_output=True, text=True)
    wall = time.perf_counter() - t0
    print(f"{label}: {wall:.1f} s, exit {run.returncode}\n{run.stderr[-1500:]}", flush=True)
    if run.returncode != 0:
        return f"| {label} | {wall:.1f} | failed (exit {run.returncode}) |" + " |" * 9
    r = {**json.loads((out / "result.json").read_text()), **json.loads((out / "run.json").read_text())}
    mb = (out / "posterior.nc").stat().st_size / 1e6
    ck = out / "chain.h5"
    ck_mb = ck.stat().st_size / 1e6 if ck.exists() else float("nan")
    lik = f"{r['likelihood_points']} of {r['points']}"
    return (f"| {label} | {wall:.1f} | {r['stopped_by']} | {r['steps']} x {r.get('walkers', '')} "
            f"| {r['tau_max']:.0f} | {r['rhat_max']:.3f} | {r['ess_min']:.0f} | {lik} "
            f"| {100 * r['nrmse']:.2f} % | {mb:.1f} | {ck_mb:.1f} | {r['converged']} |")


if __name__ == "__main__":
    main()
