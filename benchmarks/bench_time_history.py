"""Shear-building time history: rrfrei (Numba) against openseespy on the same analysis.

* one analysis: the five-story example building on ``bouc_wen``, 8,000 Newmark steps of the
  Landers (Lucerne) record, against openseespy running the same model (``tests/opensees_dynamic.py``)
  in ONE ``analyze(8000)`` call with a node recorder (its fastest path), in the same run; the two
  agree to ~1e-11, checked here;
* batch throughput: 1,000 parameter sets (lognormal draws around the building's parameters) on
  the same 8,000 steps, ``time_history_batch`` on 1 and 2 Numba threads, in analyses per second;
* cold start: a fresh interpreter importing ``structures`` and running the first analysis with
  an empty Numba cache (compilation) and with a warm one.

Run ``python benchmarks/bench_time_history.py``; it writes the ``bench_time_history`` section of
``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numba  # noqa: E402
import openseespy.opensees as ops  # noqa: E402
from _results import write_section  # noqa: E402
from opensees_dynamic import shear_building_one_call  # noqa: E402

import ground_motions  # noqa: E402
import structures  # noqa: E402

N_STEPS = 8000
N_BATCH = 1000


def record() -> ground_motions.Record:
    r = ground_motions.load("landers").with_leading_zero()
    return ground_motions.Record(r.name, r.dt, r.accel[: N_STEPS + 1], r.meta)


def best(fn, repeat: int, clock=time.perf_counter) -> float:
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return min(times)


COLD = """
import time
t0 = time.perf_counter()
import ground_motions, structures
r = ground_motions.load("landers")
b = structures.load_building("five_story")
t1 = time.perf_counter()
structures.time_history(b, r)
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def cold_start(cache: str) -> tuple[float, float]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", COLD], env=env, capture_output=True, text=True, check=True)
    a, b = out.stdout.split()
    return float(a), float(b)


def main() -> None:
    rec = record()
    bld = structures.load_building("five_story")
    assert bld.isolator.law == "bouc_wen"

    # ---- one analysis, same run, same steps
    ours = structures.time_history(bld, rec)  # compile / load from cache
    t_ours = best(lambda: structures.time_history(bld, rec), 50)
    cpu_ours = best(lambda: structures.time_history(bld, rec), 50, time.process_time)
    peer = shear_building_one_call(ops, bld, rec.accel, rec.dt)
    err = np.max(np.abs(peer[:, 0] - ours.isolator_disp[1:])) / np.max(np.abs(peer[:, 0]))
    assert err < 1e-8, err

    def opensees_total():
        shear_building_one_call(ops, bld, rec.accel, rec.dt)

    t_os = best(opensees_total, 3)
    cpu_os = best(opensees_total, 3, time.process_time)

    # ---- batch throughput
    rng = np.random.default_rng(0)
    base = bld.isolator.packed()
    P = np.tile(base, (N_BATCH, 1))
    P[:, 0] *= np.exp(rng.normal(0, 0.1, N_BATCH))
    P[:, 1] *= np.exp(rng.normal(0, 0.1, N_BATCH))
    P[:, 2] = np.clip(P[:, 2] * np.exp(rng.normal(0, 0.1, N_BATCH)), 0.05, 0.9)
    structures.time_history_batch(bld, rec, P[:4])  # compile / load
    rates = {}
    for threads in (1, 2):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        t = best(lambda: structures.time_history_batch(bld, rec, P), 1)
        rates[threads] = N_BATCH / t
    out = structures.time_history_batch(bld, rec, P)
    conv = int(out["converged"].sum())

    # ---- cold start
    with tempfile.TemporaryDirectory() as cache:
        cold = cold_start(cache)
        warm = cold_start(cache)

    ratio = t_os / t_ours
    md = f"""
Five-story example building on `bouc_wen` (17 bearings, length_scale 3), {N_STEPS} Newmark steps of
Landers/Lucerne (dt = {rec.dt:g} s), Newton + NormDispIncr 1e-12, average
{ours.newton_iterations[1:].mean():.2f} Newton iterations per step.

| analysis | wall time | ratio | CPU time | ratio |
|---|---|---|---|---|
| openseespy, one `analyze({N_STEPS})` call + node recorder (build included) | {t_os * 1e3:.1f} ms | 1 \
| {cpu_os * 1e3:.1f} ms | 1 |
| `structures.time_history` (full histories, energy, validation) | {t_ours * 1e3:.2f} ms | \
**{ratio:.0f}x** | {cpu_ours * 1e3:.2f} ms | **{cpu_os / cpu_ours:.0f}x** |

(best of 3 openseespy and 50 rrfrei runs; CPU time = `time.process_time`, less sensitive to a
busy machine)

Agreement of the isolator displacement with openseespy in this run: {err:.1e} relative.

Batch (`time_history_batch`, {N_BATCH} parameter sets, same {N_STEPS} steps, {conv}/{N_BATCH} converged):
{rates[1]:.0f} analyses/s on 1 thread, **{rates[2]:.0f} analyses/s on 2 threads**
({rates[2] / rates[1]:.2f}x).

Cold start (fresh interpreter: import + first five-story analysis of the full Landers record):
empty Numba cache {cold[0]:.2f} s import + {cold[1]:.1f} s first call (compilation);
warm cache {warm[0]:.2f} s + {warm[1]:.2f} s.
"""
    print(md)
    write_section("bench_time_history", md)


if __name__ == "__main__":
    main()
