"""Speed of a full Bayesian calibration (bouc_wen on protocol 1) and of one likelihood evaluation
against the study's workflow, an openseespy forward model per evaluation, in the same run.

* full posterior: ``rrfrei.calibrate(load_test("protocol1"), "bouc_wen", seed=s)`` with the
  defaults (CMA-ES optimum, then emcee until >= 50 autocorrelation times, capped at
  ``MAX_STEPS``) for each of ``SEEDS``, since the chain length to convergence varies with the
  seed: wall time, steps, convergence, evaluations per second;
* one evaluation: the batched Numba log-likelihood (32 walkers, ``prange``) per parameter set,
  against openseespy driving the same ``elastomericBearingBoucWen`` element along the same 2401
  samples and the same Gaussian log-likelihood (model build included, as a per-evaluation
  forward model in the study's loop);
* cold start: a fresh process importing rrfrei and evaluating the log posterior once (warm Numba
  cache).

Targets: full posterior <= 30 s on 2 cores; >= 100x per evaluation.  Section ``bench_calibration``.
Run: ``python benchmarks/bench_calibration.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
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
    # --- cold start ------------------------------------------------------------------------------
    env = dict(os.environ)
    out = subprocess.run([sys.executable, "-c", COLD.format(theta=list(theta[0]))], env=env,
                         capture_output=True, text=True, check=True)
    cold = float(out.stdout.strip().splitlines()[-1])
    md = f"""## bench_calibration

Full `bouc_wen` posterior on the bundled SYNTHETIC protocol 1 (2401 samples, 7 free parameters +
sigma, beta held; defaults: CMA-ES optimum and least-squares polish, walkers drawn from the
Laplace approximation, emcee until >= 50 tau with tau stable and R-hat < 1.04, cap {MAX_STEPS}
steps), seeds {", ".join(map(str, SEEDS))}:

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
"""
    print(md)
    write_section("bench_calibration", md)


if __name__ == "__main__":
    main()
