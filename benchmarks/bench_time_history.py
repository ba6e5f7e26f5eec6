"""Shear-building time history: rrfrei (Numba) against openseespy on the same analysis.

* per core (headline): the five-story example building on ``bouc_wen``, 8,000 Newmark steps of
  the Landers (Lucerne) record; ``structures.time_history`` (public API: full histories, energy,
  validation) against openseespy running the same model (``tests/opensees_dynamic.py``) in ONE
  ``analyze(8000)`` call with a ``-binary`` node recorder (its fastest path: full precision, no
  text formatting inside ``analyze``).  Both single-threaded; building
  the OpenSees model (before) and ``ops.wipe()`` plus reading the recorder file (after) are
  outside its timer; warm-up excluded on both sides, the same interleaved repeats, medians, and
  the isolator displacement asserted equal in the same run;
* batch throughput: 1,000 parameter sets (lognormal draws around the building's parameters) on
  the same 8,000 steps, ``structures.time_history_batch`` on 1 thread and on every core;
* cold start: a fresh interpreter importing ``structures`` and running the first analysis with an
  empty and with a warm temporary Numba cache.

Run ``python benchmarks/bench_time_history.py [--quick]``; writes section ``bench_time_history``.
"""

from __future__ import annotations

import _paths  # noqa: F401, E402  (first: this folder, the root and tests/ on sys.path)
import _peer as peer  # noqa: E402
import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402

import ground_motions  # noqa: E402
import structures  # noqa: E402

N_STEPS = 8000
N_BATCH = 1000
TOLERANCE = 1e-8  # max |u_iso - u_iso,ops| / max |u_iso,ops|


def record(n_steps: int) -> ground_motions.Record:
    r = ground_motions.load("landers").with_leading_zero()
    return ground_motions.Record(r.name, r.dt, r.accel[: n_steps + 1], r.meta)


def opensees_side(ops, bld, rec) -> tm.Side:
    """openseespy: model + recorder (untimed), one ``analyze`` call (timed), wipe + read (untimed)."""
    from opensees_dynamic import build

    def model(path):
        roof = build(ops, bld, rec.accel, rec.dt)
        ops.recorder("Node", "-binary", path, "-node", 2, roof, "-dof", 1, "disp")

    return peer.recorder_side(ops, "openseespy", "time history", model,
                              lambda: ops.analyze(rec.npts - 1, rec.dt),
                              lambda path, _: tm.read_binary_recorder(path, 2)[:, 0])


def batch_params(bld, n: int) -> np.ndarray:
    """``n`` isolator parameter rows around ``bld``'s: k_init and qd times lognormal factors
    (sd 0.1 in log), alpha1 likewise, clipped to [0.05, 0.9] (seed 0)."""
    rng = np.random.default_rng(0)
    P = np.tile(bld.isolator.packed(), (n, 1))
    P[:, 0] *= np.exp(rng.normal(0, 0.1, n))
    P[:, 1] *= np.exp(rng.normal(0, 0.1, n))
    P[:, 2] = np.clip(P[:, 2] * np.exp(rng.normal(0, 0.1, n)), 0.05, 0.9)
    return P


COLD = tm.COLD_PRELUDE + """
import ground_motions, structures
r = ground_motions.load("landers")
b = structures.load_building("five_story")
t1 = time.perf_counter()
structures.time_history(b, r)
print(json.dumps({"import": t1 - _t0, "first": time.perf_counter() - t1}))
"""


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    import openseespy.opensees as ops

    n_steps = 2000 if args.quick else N_STEPS
    n_batch = 50 if args.quick else N_BATCH
    repeat = 2 if args.quick else 7
    rec = record(n_steps)
    bld = structures.load_building("five_story")
    assert bld.isolator.law == "bouc_wen"

    # ---- one analysis, per core
    ours = tm.Side("rrfrei", lambda _s: structures.time_history(bld, rec))
    c = tm.compare(ours, opensees_side(ops, bld, rec), repeat=repeat, tolerance=TOLERANCE,
                   agree=lambda r, u: float(np.max(np.abs(u - r.isolator_disp[1:])) / np.max(np.abs(u))),
                   what="five-story time history")
    iters = structures.time_history(bld, rec).newton_iterations[1:].mean()
    print(f"per core: {c.ratio:.0f}x ({tm.fmt(c.peer.median)} / {tm.fmt(c.ours.median)})", flush=True)

    # ---- batch throughput, 1 thread and every core
    P = batch_params(bld, n_batch)
    batch = tm.Side("time_history_batch", lambda _s: structures.time_history_batch(bld, rec, P), work=n_batch)
    rates = {}
    for n in sorted({1, tm.cores()}):
        rate, t, out = tm.throughput(batch, repeat=1 if args.quick else 3, n_threads=n)
        rates[t.threads] = rate
    conv = int(out["converged"].sum())
    per_core_batch = rates[1] * c.peer.median
    multi = max(rates)

    cold = tm.cold_start(COLD)
    md = f"""## bench_time_history (shear building against openseespy)

Five-story example building on `bouc_wen` (17 bearings, length_scale 3), {n_steps} Newmark steps of
Landers/Lucerne (dt = {rec.dt:g} s), Newton + NormDispIncr 1e-12, average {iters:.2f} Newton
iterations per step. **Per core**: both single-threaded, median of {repeat} interleaved runs after
one warm-up each; openseespy's model building, `ops.wipe()` and reading its recorder file are
outside its timer.

| analysis | 1 thread | ratio per core |
|---|---:|---:|
| openseespy, one `analyze({n_steps})` call + `-binary` node recorder | {tm.fmt(c.peer.median)} | 1 |
| `structures.time_history` (histories, energy, validation) | {tm.fmt(c.ours.median)} | **{c.ratio:.0f}x** |

Agreement of the isolator displacement with openseespy in this run: {c.discrepancy:.1e} relative
(asserted <= {TOLERANCE:g}).

**Batch throughput** (`time_history_batch`, {n_batch} parameter sets, same {n_steps} steps,
{conv}/{n_batch} converged; median of {1 if args.quick else 3} after one warm-up):
{rates[1]:.0f} analyses/s on 1 thread ({per_core_batch:.0f}x openseespy's single-threaded rate),
**{rates[multi]:.0f} analyses/s on {multi} threads** (multi-core; {rates[multi] / rates[1]:.2f}x the
1-thread rate).

Cold start (fresh interpreter: import + first five-story analysis of the full Landers record;
temporary `NUMBA_CACHE_DIR`): empty cache {cold.cold['import']:.2f} s import + {cold.cold['first']:.1f} s
first call (compilation); warm cache (filled by that run) {cold.warm['import']:.2f} s +
{cold.warm['first']:.2f} s.{"".join(f" Note: {n}." for n in cold.notes)}
"""
    head = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio, steps=n_steps,
                batch_rate_1=rates[1], batch_rate_multi=rates[multi], threads=multi)
    report("bench_time_history", md, quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
