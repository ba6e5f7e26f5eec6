"""Plan building (issue 14.2): rrfrei (Numba) against openseespy's 3-D model on the same pair.

* per core (headline): the five-story example building in plan on each coupled isolator law
  (``plasticity``, ``bouc_wen``, ``elastomeric_x``, ``hdr``; example parameters of
  ``tests/opensees_dynamic.py``), 4,000 Newmark steps of the bundled Ferndale pair (both
  horizontal components from 30 s, after a leading zero); ``structures.plan_time_history``
  (public API: full histories in x and y, energy, validation) against openseespy running the same
  3-D model (``tests/opensees_plan_building.py``: 3-D bearing element, X and Y free at every
  node) in ONE ``analyze(4000)`` call with a ``-binary`` node recorder (its fastest path: full
  precision, no text formatting inside ``analyze``).  Both
  single-threaded; building the OpenSees model (before) and ``ops.wipe()`` plus reading the
  recorder file (after) are outside its timer; warm-up excluded on both sides, the same
  interleaved repeats, medians, and the base displacement (X and Y) asserted equal in the same
  run;
* batch throughput: 200 parameter sets (lognormal draws around the ``bouc_wen`` parameters) on
  the same steps, ``structures.plan_time_history_batch`` on 1 thread and on every core.

Run ``python benchmarks/bench_plan_building.py [--quick]``; writes section
``bench_plan_building``.
"""

from __future__ import annotations

from dataclasses import replace

import _paths  # noqa: F401, E402  (first: this folder, the root and tests/ on sys.path)
import _peer as peer  # noqa: E402
import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402
from bench_time_history import batch_params  # noqa: E402  (the same draws)

import ground_motions  # noqa: E402
import structures  # noqa: E402
from rrfrei.laws import plan as plan_laws  # noqa: E402

N_STEPS = 4000
N_BATCH = 200
START = 30.0  # s: the Ferndale strong motion starts at about 33 s
TOLERANCE = 1e-8  # max |u_base - u_base,ops| / max |u_base,ops| over X and Y
LAWS = ("plasticity", "bouc_wen", "elastomeric_x", "hdr")


def pair(n_steps: int) -> tuple[np.ndarray, float]:
    """(n_steps + 1, 2) Ferndale pair (channels 1 and 2) from ``START``, a leading zero first."""
    x, y = (ground_motions.load("ferndale", channel=c) for c in (1, 2))
    i = int(round(START / x.dt))
    ag = np.column_stack((x.accel[i:i + n_steps], y.accel[i:i + n_steps]))
    return np.vstack((np.zeros((1, 2)), ag)), x.dt


def opensees_side(ops, bld, ag, dt) -> tm.Side:
    """openseespy: model + recorder (untimed), one ``analyze`` call (timed), wipe + read (untimed)."""
    from opensees_plan_building import build

    def model(path):
        build(ops, bld, ag, dt)
        ops.recorder("Node", "-binary", path, "-node", 2, "-dof", 1, 2, "disp")

    return peer.recorder_side(ops, "openseespy 3-D", "plan time history", model,
                              lambda: ops.analyze(ag.shape[0] - 1, dt),
                              lambda path, _: tm.read_binary_recorder(path, 2))


def agree(resp: structures.PlanResponse, u: np.ndarray) -> float:
    return float(np.max(np.abs(u - resp.isolator_disp[1:])) / np.max(np.abs(u)))


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    import openseespy.opensees as ops

    n_steps = 1000 if args.quick else N_STEPS
    n_batch = 20 if args.quick else N_BATCH
    repeat = 2 if args.quick else 5
    ag, dt = pair(n_steps)
    five = structures.load_building("five_story")
    from opensees_dynamic import SPECIMEN_PARAMS as PARAMS

    laws = [law for law in LAWS if law in plan_laws.names()]
    rows = []
    head = {}
    for law in laws:
        iso = structures.Isolator(law, PARAMS[law], five.isolator.count, five.isolator.length_scale)
        bld = replace(five, isolator=iso)
        ours = tm.Side("rrfrei", lambda _s, b=bld: structures.plan_time_history(b, None, None, ag, dt=dt))
        c = tm.compare(ours, opensees_side(ops, bld, ag, dt), repeat=repeat, tolerance=TOLERANCE,
                       agree=agree, what=f"five-story plan building on {law}")
        r = structures.plan_time_history(bld, None, None, ag, dt=dt)
        iters = r.newton_iterations[1:].mean()
        print(f"{law}: per core {c.ratio:.0f}x ({tm.fmt(c.peer.median)} / {tm.fmt(c.ours.median)}), "
              f"agreement {c.discrepancy:.1e}", flush=True)
        rows.append((law, c, iters, r.isolator_plan_disp_max))
        head[f"{law}_ratio"] = c.ratio
        head[f"{law}_ours_s"] = c.ours.per_unit
        head[f"{law}_peer_s"] = c.peer.per_unit

    # ---- batch throughput (bouc_wen, the example building's law), 1 thread and every core
    law = "bouc_wen"
    bld = replace(five, isolator=structures.Isolator(law, PARAMS[law], five.isolator.count,
                                                     five.isolator.length_scale))
    P = batch_params(bld, n_batch)
    batch = tm.Side("plan_time_history_batch",
                    lambda _s: structures.plan_time_history_batch(bld, None, P, ag, dt=dt), work=n_batch)
    rates = {}
    for n in sorted({1, tm.cores()}):
        rate, t, out = tm.throughput(batch, repeat=1 if args.quick else 3, n_threads=n)
        rates[t.threads] = rate
    conv = int(out["converged"].sum())
    multi = max(rates)
    peer_rate = 1.0 / next(c for name, c, *_ in rows if name == law).peer.median

    table = "\n".join(
        f"| `{law}` | {tm.fmt(c.peer.median)} | {tm.fmt(c.ours.median)} | **{c.ratio:.0f}x** | "
        f"{c.discrepancy:.1e} | {iters:.2f} | {peak * 1000:.0f} mm |"
        for law, c, iters, peak in rows
    )
    header = (f"| law | openseespy 3-D, one `analyze({n_steps})` + `-binary` node recorder | "
              "`structures.plan_time_history` | ratio per core | agreement | Newton iterations / step | "
              "peak plan isolator displacement |\n|---|---:|---:|---:|---:|---:|---:|")
    md = f"""## bench_plan_building (plan building against openseespy's 3-D model)

Five-story example building in plan (17 bearings, length_scale 3; the same stories in x and y, no
torsion) on the coupled isolator law, {n_steps} Newmark steps of the Ferndale pair (channels 1 and
2 from {START:g} s, dt = {dt:g} s), Newton + NormDispIncr 1e-12.  **Per core**: both
single-threaded, median of {repeat} interleaved runs after one warm-up each; openseespy's model
building, `ops.wipe()` and reading its recorder file are outside its timer.  Agreement: base
displacement X and Y against openseespy in the same run (asserted <= {TOLERANCE:g}).

{header}
{table}

**Batch throughput** (`plan_time_history_batch` on `{law}`, {n_batch} parameter sets, same
{n_steps} steps, {conv}/{n_batch} converged): {rates[1]:.0f} analyses/s on 1 thread
({rates[1] / peer_rate:.0f}x openseespy's single-threaded rate), **{rates[multi]:.0f} analyses/s on
{multi} threads** ({rates[multi] / rates[1]:.2f}x the 1-thread rate).
"""
    head.update(steps=n_steps, batch_rate_1=rates[1], batch_rate_multi=rates[multi], threads=multi)
    report("bench_plan_building", md, quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
