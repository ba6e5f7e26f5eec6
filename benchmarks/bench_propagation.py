"""Propagation throughput: 1,000 posterior draws x every bundled record on the 5-story example.

Measures, in one run on this machine:

* wall time of ``structures.propagate`` (local executor: Numba prange over all cores) for 1,000
  draws x all bundled records at scale 1, and analyses per second;
* the time of one openseespy analysis of the same building under the same records (the peer model
  of ``tests/opensees_dynamic.py``, whole record in one ``analyze`` call: openseespy's fastest
  path), averaged over the records, and the ratio (openseespy time per analysis) / (ours);
* cold start in a fresh interpreter: import + first ``propagate`` call (one draw, short record),
  with the Numba cache warm and with an empty cache (compilation).

The draws are the building's own isolator parameters perturbed lognormally (10 % log-sd), which
is what a posterior of a well-identified law looks like; the cost of an analysis does not depend
on where the draws come from.

Run: ``python benchmarks/bench_propagation.py [--samples N]``; records section ``bench_propagation``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests"))

from _results import write_section  # noqa: E402

COLD = """
import time
t0 = time.perf_counter()
import numpy as np, pandas as pd, ground_motions, structures
from structures.propagate import propagate
b = structures.load_building("five_story")
r = ground_motions.load("rinaldi")
r = ground_motions.Record(r.name, r.dt, r.accel[:200], r.meta)
df = pd.DataFrame([dict(b.isolator.params)]); df.attrs["law"] = b.isolator.law
t1 = time.perf_counter()
propagate(df, b, [r], n_samples=1, progress=False)
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def draws(building, n: int, seed: int = 0):
    import pandas as pd

    from rrfrei.laws import get

    spec = get(building.isolator.law)
    base = dict(building.isolator.params)
    rng = np.random.default_rng(seed)
    cols = {}
    for p in spec.params:
        x = float(base[p.name])
        if p.geometry or x == 0.0 or p.name in ("beta", "gamma", "eta"):
            cols[p.name] = np.full(n, x)
        else:
            cols[p.name] = np.clip(x * np.exp(rng.normal(0.0, 0.1, n)), p.lower, p.upper)
    df = pd.DataFrame(cols)
    df.attrs.update(law=spec.name, disp_min_m=-0.1, disp_max_m=0.1)
    return df


def cold_start(cache_dir: str) -> tuple[float, float]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    out = subprocess.run([sys.executable, "-c", COLD], capture_output=True, text=True, env=env, cwd=ROOT,
                         check=True)
    a, b = out.stdout.split()[-2:]
    return float(a), float(b)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=1000)
    args = ap.parse_args()

    import numba

    import ground_motions
    import structures
    from structures.propagate import propagate

    bld = structures.load_building("five_story")
    names = list(ground_motions.available())
    recs = [ground_motions.load(n) for n in names]
    post = draws(bld, 20 * args.samples)
    steps = sum(r.npts for r in recs)

    # warm-up (compilation) on a short piece, not timed
    short = ground_motions.Record("w", recs[0].dt, recs[0].accel[:100])
    propagate(post, bld, [short], n_samples=4, progress=False)

    t0 = time.perf_counter()
    rs = propagate(post, bld, recs, n_samples=args.samples, progress=False, seed=1)
    wall = time.perf_counter() - t0
    n_runs = len(rs.table)
    ours = wall / n_runs
    failed = int((~rs.table["converged"]).sum())

    # the peer: openseespy, same building (MAP-like parameters), same records
    import openseespy.opensees as ops
    from opensees_dynamic import shear_building_one_call

    t_os = []
    for r in recs:
        r0 = r.with_leading_zero()
        t1 = time.perf_counter()
        shear_building_one_call(ops, bld, r0.accel, r0.dt)
        t_os.append(time.perf_counter() - t1)
    peer = float(np.mean(t_os))

    warm_import, warm_first = cold_start(os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".numba-bench")))
    with tempfile.TemporaryDirectory() as empty:
        cold_import, cold_first = cold_start(empty)

    text = f"""## bench_propagation

{args.samples} posterior draws x {len(recs)} bundled records ({', '.join(names)}; {steps} record steps
in all) on the 5-story example (`five_story`, {bld.isolator.law} isolators), scale 1, local executor
(Numba prange, {numba.get_num_threads()} threads), default chunk size.

| quantity | value |
|---|---|
| analyses | {n_runs} ({failed} did not converge) |
| wall time, whole batch | {wall:.1f} s (target <= 60 s) |
| analyses per second | {n_runs / wall:.1f} |
| time steps per second (all runs) | {args.samples * steps / wall:.3g} |
| ours, per analysis (wall / analyses) | {1e3 * ours:.2f} ms |
| openseespy, per analysis (one `analyze` call, mean of {len(recs)} records) | {1e3 * peer:.1f} ms |
| **speed-up vs openseespy** | **{peer / ours:.0f}x** (target >= 50x) |
| cold start, warm Numba cache: import / first call | {warm_import:.2f} s / {warm_first:.2f} s |
| cold start, empty Numba cache: import / first call | {cold_import:.2f} s / {cold_first:.2f} s |

The openseespy time is single-threaded and ours uses every core, as each would be used; per core the
ratio is {peer / ours / numba.get_num_threads():.0f}x.
"""
    print(text)
    write_section("bench_propagation", text)


if __name__ == "__main__":
    main()
