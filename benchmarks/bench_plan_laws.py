"""Speed of the coupled bidirectional (plan) laws against openseespy's 3-D bearing elements on
the same two-component displacement history.

For each plan law with an OpenSees element (``rrfrei.laws.plan.names()``), per core (both
single-threaded): openseespy's fastest path, ONE ``analyze(n)`` call with a ``-binary`` element
recorder writing to a file (full precision, without the text formatting that cost openseespy
29 % here: ``_timing.read_binary_recorder``; the 3-D zero-length element of
``tests/opensees_plan.py``, both horizontal DOFs imposed), against ``rrfrei.simulate_force``
on the (n, 2) path (public API, validation and output arrays included).  The peer's model
building and recorder set-up (before) and ``ops.wipe()`` plus reading the recorder file (after)
are outside its timer; warm-up excluded on both sides, the same interleaved repeats, medians,
and the forces asserted equal in the same run.  A law history is sequential, so there is no
multi-core figure.  Cold start: a fresh
interpreter (``import rrfrei`` + first plan ``simulate_force``) with an empty and with a warm
temporary Numba cache.  Writes section ``bench_plan_laws``.

Run: ``python benchmarks/bench_plan_laws.py [--quick]``.
"""

from __future__ import annotations

import _paths  # noqa: F401, E402  (first: this folder, the root and tests/ on sys.path)
import _peer as peer  # noqa: E402
import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402

import rrfrei  # noqa: E402
from rrfrei.laws import plan  # noqa: E402

N = 5_000
TOLERANCE = 1e-10  # max |f - f_ops| / max |f_ops| over both components

PARAMS = {
    "plasticity": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0),
    "bouc_wen": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.37, beta=0.6,
                     gamma=0.4),
    "elastomeric_x": dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0),
    "hdr": dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4,
                c4=5e3),
}
"""Parameters per plan law (those of ``bench_laws.py``); a law missing here is skipped."""


def history(n: int = N) -> np.ndarray:
    """(n, 2) samples [m]: a figure-eight-like orbit, x cycles of 200 steps, y of 150 steps
    (phase-shifted), amplitude growing 2 -> 40 mm."""
    k = np.arange(1, n + 1)
    amp = 0.002 + 0.038 * k / n
    return np.c_[amp * np.sin(2 * np.pi * k / 200), 0.8 * amp * np.sin(2 * np.pi * k / 150 + 0.7)]


def opensees_side(ops, law: str, p: dict, u: np.ndarray) -> tm.Side:
    """openseespy: build + recorder (untimed), ``analyze(n)`` (timed), wipe + read file (untimed)."""
    import opensees_plan as h

    def build(path):
        h._build(ops, law, p, u)
        ops.recorder("Element", "-binary", path, "-ele", 1, "force")

    return peer.recorder_side(ops, "openseespy", f"analysis of {law}", build,
                              lambda: ops.analyze(u.shape[0]),
                              lambda path, _: tm.read_binary_recorder(path, 12)[-u.shape[0]:, 6:8])


def max_rel(f: np.ndarray, f_os: np.ndarray) -> float:
    return float(np.max(np.abs(f - f_os)) / np.max(np.abs(f_os)))


COLD = tm.COLD_PRELUDE + """
import numpy as np
import rrfrei
t1 = time.perf_counter()
s = np.linspace(0.0, 0.02, 100)
rrfrei.simulate_force("bouc_wen", {params!r}, np.c_[s, 0.5 * s])
print(json.dumps({{"import": t1 - _t0, "first": time.perf_counter() - t1}}))
"""


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    import opensees_plan
    import openseespy.opensees as ops

    repeat = 2 if args.quick else 7
    u = history(1000 if args.quick else N)
    laws = [n for n in plan.names() if plan.get(n).opensees_element and n in opensees_plan.PLAN_LAWS]
    rows, skipped, head = [], [], {"steps": int(u.shape[0])}
    for law in laws:
        if law not in PARAMS:
            skipped.append(law)
            continue
        p = PARAMS[law]
        ours = tm.Side("rrfrei", lambda _s, law=law, p=p: rrfrei.simulate_force(law, p, u))
        c = tm.compare(ours, opensees_side(ops, law, p, u), repeat=repeat, agree=max_rel,
                       tolerance=TOLERANCE, what=law)
        ps = ", ".join(f"{k}={v:g}" for k, v in p.items())
        rows.append(f"| {law} | `{plan.get(law).opensees_element}` | {ps} | {tm.fmt(c.peer.median)} "
                    f"| {tm.fmt(c.ours.median)} | **{c.ratio:.0f}x** | {c.discrepancy:.1e} |")
        print(rows[-1], flush=True)
        head[law] = {"ours_s": c.ours.median, "peer_s": c.peer.median, "ratio": c.ratio}
    cold = tm.cold_start(COLD.format(params=PARAMS["bouc_wen"]))
    lines = [
        "## bench_plan_laws (coupled bidirectional laws against openseespy's 3-D elements)",
        "",
        f"Each plan law over the same {u.shape[0]:,}-step two-component history (x: sine cycles "
        "of 200 steps, y: 0.8 x that amplitude, cycles of 150 steps, phase 0.7; amplitude "
        "2 -> 40 mm). "
        + peer.method(repeat, u.shape[0], "the 3-D zero-length element, both horizontal DOFs imposed, ")
        + " rrfrei: `simulate_force` on the (n, 2) path (validation and output included). "
        "Ratio = openseespy median / rrfrei median; the forces (both components) are asserted "
        f"equal (<= {TOLERANCE:g} of the peak) in the same run.",
        "",
        "| law | OpenSees element (3-D) | parameters | openseespy, 1 thread | rrfrei, 1 thread "
        "| ratio per core | max rel. diff |",
        "|---|---|---|---:|---:|---:|---:|",
        *rows,
        "",
        "A law history is sequential: no multi-core figure."
        + (f" Not benchmarked (no parameters in this script): {', '.join(skipped)}." if skipped else ""),
        "",
        peer.cold_start(cold, "`import rrfrei` + first plan `simulate_force`, bouc_wen"),
    ]
    report("bench_plan_laws", "\n".join(lines), quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
