"""Speed of the isolator laws against openseespy on the same 10,000-step displacement history.

For each OpenSees law, per core (both single-threaded): openseespy's fastest path, ONE
``analyze(10000)`` call with a ``-binary`` element recorder writing to a file (full precision,
without the text formatting that cost openseespy up to 29 %: ``_timing.read_binary_recorder``),
against
``rrfrei.simulate_force`` (public API, validation and output arrays included).  The peer's model
building and recorder set-up (before) and ``ops.wipe()`` plus reading the recorder file (after)
are outside its timer; warm-up excluded on both sides, the same interleaved repeats, medians, and
the forces asserted equal in the same run.  A law history is sequential, so there is no
multi-core figure.  Cold start: a fresh interpreter (``import rrfrei`` + first ``simulate_force``)
with an empty and with a warm temporary Numba cache.  Writes section ``bench_laws``.

Run: ``python benchmarks/bench_laws.py [--quick]``.
"""

from __future__ import annotations

import _paths  # noqa: F401, E402  (first: this folder, the root and tests/ on sys.path)
import _peer as peer  # noqa: E402
import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
from _results import report  # noqa: E402

import rrfrei  # noqa: E402

N = 10_000
TOLERANCE = 1e-10  # max |f - f_ops| / max |f_ops|

PARAMS = {
    "plasticity": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0),
    "bouc_wen (eta=1)": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.0,
                             beta=0.5, gamma=0.5),
    "bouc_wen (eta=1.37)": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.37,
                                beta=0.6, gamma=0.4),
    "elastomeric_x": dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0),
    "hdr": dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4,
                c4=5e3),
}


def history(n: int = N) -> np.ndarray:
    """n samples [m]: sine cycles of 200 steps, amplitude growing 2 -> 40 mm."""
    k = np.arange(1, n + 1)
    return (0.002 + 0.038 * k / n) * np.sin(2 * np.pi * k / 200)


def opensees_side(ops, law: str, p: dict, u: np.ndarray) -> tm.Side:
    """openseespy: build + recorder (untimed), ``analyze(n)`` (timed), wipe + read file (untimed)."""
    import opensees_harness as h

    def build(path):
        idx, sign = h._build(ops, law, p, u)
        ops.recorder("Element", "-binary", path, "-ele", 1, "force")
        return idx, sign

    def read(path, built):
        idx, sign = built
        return sign * tm.read_binary_recorder(path, 6 if law in h.TWO_D else 12)[-u.size:, idx]

    return peer.recorder_side(ops, "openseespy", f"analysis of {law}", build,
                              lambda: ops.analyze(u.size), read)


def max_rel(f: np.ndarray, f_os: np.ndarray) -> float:
    return float(np.max(np.abs(f - f_os)) / np.max(np.abs(f_os)))


COLD = tm.COLD_PRELUDE + """
import numpy as np
import rrfrei
t1 = time.perf_counter()
rrfrei.simulate_force("bouc_wen", {params!r}, np.linspace(0.0, 0.02, 100))
print(json.dumps({{"import": t1 - _t0, "first": time.perf_counter() - t1}}))
"""


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    import openseespy.opensees as ops

    repeat = 2 if args.quick else 7
    u = history(2000 if args.quick else N)
    labels = list(PARAMS)[:2] if args.quick else list(PARAMS)
    rows, head = [], {}
    for label in labels:
        p = PARAMS[label]
        law = label.split(" ")[0]
        ours = tm.Side("rrfrei", lambda _s, law=law, p=p: rrfrei.simulate_force(law, p, u))
        c = tm.compare(ours, opensees_side(ops, law, p, u), repeat=repeat, agree=max_rel,
                       tolerance=TOLERANCE, what=label)
        head[label] = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio)
        ps = ", ".join(f"{k}={v:g}" for k, v in p.items())
        rows.append(f"| {label} | {ps} | {tm.fmt(c.peer.median)} | {tm.fmt(c.ours.median)} "
                    f"| **{c.ratio:.0f}x** | {c.discrepancy:.1e} |")
        print(rows[-1], flush=True)
    cold = tm.cold_start(COLD.format(params=PARAMS["bouc_wen (eta=1)"]))
    lines = [
        "## bench_laws (isolator laws against openseespy)",
        "",
        f"Each law over the same {u.size:,}-step history (sine cycles of 200 steps, amplitude "
        f"2 -> 40 mm). {peer.method(repeat, u.size)} "
        "rrfrei: `simulate_force` (validation and output included). "
        "Ratio = openseespy median / rrfrei median; the forces are asserted equal "
        f"(<= {TOLERANCE:g} of the peak) in the same run.",
        "",
        "| law | parameters | openseespy, 1 thread | rrfrei, 1 thread | ratio per core | max rel. diff |",
        "|---|---|---:|---:|---:|---:|",
        *rows,
        "",
        "A law history is sequential: no multi-core figure (calibration and propagation batch many).",
        "",
        peer.cold_start(cold, "`import rrfrei` + first `simulate_force`, bouc_wen"),
    ]
    head["steps"] = int(u.size)
    report("bench_laws", "\n".join(lines), quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
