"""Propagation: posterior draws x every bundled record on the 5-story example, against openseespy.

Measures, in one run on this machine:

* **per core** (headline): for each bundled record, ``structures.propagate`` of ``PER_RECORD``
  draws on ONE Numba thread against openseespy on one thread analysing the same building under
  the same record (the peer model of ``tests/opensees_dynamic.py``, whole record in one
  ``analyze`` call: openseespy's fastest path; model building, ``ops.wipe()`` and reading the
  recorder file outside its timer).  The draws are all the building's own isolator parameters,
  so both sides do exactly the same analyses and every peak isolator displacement of ours is
  asserted equal to openseespy's in the same run.  Warm-up excluded on both sides, the same
  interleaved repeats, medians; the ratio is (sum over records of the peer's time per analysis)
  / (sum of ours), i.e. one analysis of every record;
* **multi-core throughput**: wall time of ``structures.propagate`` (local executor: threads
  over blocks of draws, every core) for 1,000 draws x all bundled records at scale 1, and analyses per
  second.  The draws are the building's parameters perturbed lognormally (10 % log-sd), which is
  what a posterior of a well-identified law looks like;
* cold start in a fresh interpreter: import + first ``propagate`` call (one draw, short record),
  with an empty and with a warm (filled by the first run) temporary Numba cache.

Run: ``python benchmarks/bench_propagation.py [--quick] [--samples N]``; section ``bench_propagation``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(1, str(ROOT))
sys.path.insert(2, str(ROOT / "tests"))

import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402
from bench_time_history import opensees_side as roof_history_side  # noqa: E402

PER_RECORD = 20  # draws per record in the per-core comparison
TOLERANCE = 1e-8  # relative difference of the peak isolator displacement

COLD = tm.COLD_PRELUDE + """
import numpy as np, pandas as pd, ground_motions, structures
b = structures.load_building("five_story")
r = ground_motions.load("rinaldi")
r = ground_motions.Record(r.name, r.dt, r.accel[:200], r.meta)
df = pd.DataFrame([dict(b.isolator.params)]); df.attrs["law"] = b.isolator.law
t1 = time.perf_counter()
structures.propagate(df, b, [r], n_samples=1, progress=False)
print(json.dumps({"import": t1 - _t0, "first": time.perf_counter() - t1}))
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


def same_draws(building, n: int):
    """n copies of the building's own isolator parameters (both sides do the same analyses)."""
    import pandas as pd

    df = pd.DataFrame([dict(building.isolator.params)] * n)
    df.attrs.update(law=building.isolator.law, disp_min_m=-0.1, disp_max_m=0.1)
    return df


def opensees_side(ops, bld, rec) -> tm.Side:
    """openseespy as in ``bench_time_history`` (model + recorder untimed, one ``analyze`` timed,
    wipe + read untimed), reduced to the peak isolator displacement [m]."""
    side = roof_history_side(ops, bld, rec)
    return tm.Side(side.label, side.run, side.setup,
                   lambda path, status: float(np.max(np.abs(side.finish(path, status)))))


def main() -> None:
    ap = tm.parser(__doc__)
    ap.add_argument("--samples", type=int, default=1000, help="draws per record of the multi-core batch")
    args = ap.parse_args()
    import openseespy.opensees as ops

    import ground_motions
    import structures

    bld = structures.load_building("five_story")
    names = list(ground_motions.available())[: 2 if args.quick else None]
    recs = [ground_motions.load(n).with_leading_zero() for n in names]
    steps = sum(r.npts for r in recs)
    samples = 20 if args.quick else args.samples
    per_record = 4 if args.quick else PER_RECORD
    repeat = 2 if args.quick else 5

    # ---- per core: record by record, identical analyses on both sides
    same = same_draws(bld, per_record)
    rows, ours_sum, peer_sum = [], 0.0, 0.0
    for rec in recs:
        ours = tm.Side("rrfrei", lambda _s, rec=rec: structures.propagate(
            same, bld, [rec], n_samples=per_record, progress=False).table, work=per_record)
        c = tm.compare(ours, opensees_side(ops, bld, rec), repeat=repeat, tolerance=TOLERANCE, what=rec.name,
                       agree=lambda t, peak: float(np.max(np.abs(t["iso_disp_peak_m"] - peak)) / peak))
        ours_sum += c.ours.per_unit
        peer_sum += c.peer.per_unit
        rows.append(f"| {rec.name} | {rec.npts} | {tm.fmt(c.peer.per_unit)} | {tm.fmt(c.ours.per_unit)} "
                    f"| {c.ratio:.0f}x | {c.discrepancy:.1e} |")
        print(rows[-1], flush=True)
    ratio = peer_sum / ours_sum

    # ---- multi-core throughput: the whole batch on every core (kernels warm from the above)
    post = draws(bld, 20 * samples)
    batch = tm.Side("propagate", lambda _s: structures.propagate(post, bld, recs, n_samples=samples,
                                                                 progress=False, seed=1),
                    work=samples * len(recs))
    rate, t_batch, rs = tm.throughput(batch, repeat=1, warmup=0)
    failed = int((~rs.table["converged"]).sum())
    n_runs = len(rs.table)

    cold = tm.cold_start(COLD)
    text = f"""## bench_propagation

5-story example (`five_story`, {bld.isolator.law} isolators) under {len(recs)} bundled records
({', '.join(names)}; {steps} record steps in all), scale 1.

**Per core** (both single-threaded; {per_record} draws per record, all equal to the building's own
isolator parameters, so both sides do the same analyses and every peak isolator displacement is
asserted equal to openseespy's, <= {TOLERANCE:g}; median of {repeat} interleaved runs after one
warm-up each; openseespy's model building, `ops.wipe()` and reading its recorder file outside its
timer):

| record | steps | openseespy per analysis | rrfrei per analysis | ratio | max rel. diff of peak |
|---|---:|---:|---:|---:|---:|
{chr(10).join(rows)}
| **one analysis of every record** | {steps} | {tm.fmt(peer_sum)} | {tm.fmt(ours_sum)} | **{ratio:.0f}x** | |

**Multi-core throughput** ({samples} posterior draws x {len(recs)} records, draws perturbed 10 %
lognormally around the building's parameters, local executor, blocks of draws on
{t_batch.threads} threads, default chunk size, one timed run):

| quantity | value |
|---|---|
| analyses | {n_runs} ({failed} did not converge) |
| wall time, whole batch | {t_batch.median:.1f} s (target <= 60 s) |
| analyses per second | {rate:.1f} |
| time steps per second (all runs) | {samples * steps / t_batch.median:.3g} |
| cold start (fresh interpreter, temporary `NUMBA_CACHE_DIR`): import + first call | {cold.describe()} |
"""
    head = dict(ours_s=ours_sum, peer_s=peer_sum, ratio=ratio, records=len(recs), samples=samples,
                batch_s=t_batch.median, batch_rate=rate, threads=t_batch.threads)
    report("bench_propagation", text, quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
