"""The summary table of ``benchmarks/RESULTS.md`` (the headline speed figures, one row per
benchmark) and the fresh-clone times, from ``benchmarks/headline.json``.

Every figure comes from the last full run of a benchmark script (``python benchmarks/run_all.py``
writes RESULTS.md's sections and headline.json together), so the summary quotes exactly what the
sections show.  A benchmark not yet run prints as ``(not measured)``.

Run: ``python benchmarks/readme_table.py`` (prints), ``python benchmarks/readme_table.py --write``
(replaces the ``summary`` block at the top of RESULTS.md).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import HEADLINE, RESULTS  # noqa: E402

MISSING = "(not measured)"


def ms(seconds: float | None) -> str:
    """Seconds as a readable time (ms below 1 s)."""
    if seconds is None:
        return MISSING
    if seconds >= 1.0:
        return f"{seconds:.1f} s"
    value = 1e3 * seconds
    return f"{value:.2f} ms" if value < 10 else f"{value:.0f} ms"


def x(ratio: float | None) -> str:
    return MISSING if ratio is None else f"{ratio:,.0f}x"


def table(h: dict) -> str:
    """The markdown of README's speed section from the headline figures ``h``."""
    laws, th, cal = h.get("bench_laws", {}), h.get("bench_time_history", {}), h.get("bench_calibration", {})
    prop, sp, rub = h.get("bench_propagation", {}), h.get("spectra", {}), h.get("bench_rubber", {})
    gap = h.get("bench_gap", {})
    st = h.get("bench_shake_table", {}).get("shake_table", {})
    rows = []

    def row(what, ours, peer, ratio, multi="", target=""):
        rows.append(f"| {what} | {ours} | {peer} | {ratio} | {multi} | {target} |")

    steps = laws.get("steps", 10000)
    for label in ("plasticity", "bouc_wen (eta=1)", "bouc_wen (eta=1.37)", "elastomeric_x", "hdr"):
        f = laws.get(label, {})
        row(f"{label} law, {steps:,} steps", ms(f.get("ours_s")),
            f"openseespy `analyze({steps})` {ms(f.get('peer_s'))}", x(f.get("ratio")), "sequential",
            ">= 100x" if label == "bouc_wen (eta=1.37)" else "")
    pl = h.get("bench_plan_laws", {})
    for label in ("plasticity", "bouc_wen", "elastomeric_x", "hdr"):
        f = pl.get(label, {})
        row(f"{label} in plan (coupled, (n, 2) path), {pl.get('steps', 5000):,} steps",
            ms(f.get("ours_s")), f"openseespy 3-D element `analyze` {ms(f.get('peer_s'))}",
            x(f.get("ratio")), "sequential", ">= 50x")
    n = th.get("threads", "all")
    row(f"5-story building on bouc_wen, {th.get('steps', 8000):,} Newmark steps", ms(th.get("ours_s")),
        f"openseespy `analyze({th.get('steps', 8000)})` {ms(th.get('peer_s'))}", f"**{x(th.get('ratio'))}**",
        f"batch of 1,000: {th.get('batch_rate_multi', 0):.0f} analyses/s on {n} threads "
        f"({th.get('batch_rate_1', 0):.0f} on 1)" if th else MISSING, ">= 100x per core")
    pb = h.get("bench_plan_building", {})
    for label in ("plasticity", "bouc_wen", "elastomeric_x", "hdr"):
        row(f"5-story plan building (x and y) on {label}, Ferndale pair, "
            f"{pb.get('steps', 4000):,} Newmark steps",
            ms(pb.get(f"{label}_ours_s")), f"openseespy 3-D model {ms(pb.get(f'{label}_peer_s'))}",
            x(pb.get(f"{label}_ratio")), "", ">= 50x")
    row("one likelihood evaluation (bouc_wen, 2,401 points; batched over 32 walkers)", ms(cal.get("ours_s")),
        f"openseespy forward model {ms(cal.get('peer_s'))}", f"**{x(cal.get('ratio'))}**",
        f"{cal.get('multi_rate', 0):,.0f} evaluations/s on {cal.get('threads', 'all')} threads"
        if cal else MISSING, ">= 100x")
    on = f" on {cal.get('threads', 'all')} threads"
    row("full bouc_wen posterior on protocol 1, `calibrate()` (median of 3 seeds)", "", "", "",
        ms(cal.get("posterior_median_s")) + on, "<= 30 s")
    row("whole `rrfrei calibrate` command, 2,401 points", "", "", "", ms(cal.get("command_s")) + on,
        "<= 15 s")
    row("propagation, 5-story: one analysis of each of the 11 records", ms(prop.get("ours_s")),
        f"openseespy {ms(prop.get('peer_s'))}", f"**{x(prop.get('ratio'))}**",
        f"1,000 draws x 11 records in {ms(prop.get('batch_s'))} ({prop.get('batch_rate', 0):.0f} analyses/s "
        f"on {prop.get('threads', 'all')} threads)" if prop else MISSING, ">= 50x; batch <= 60 s")
    ec = sp.get("elcentro", {})
    row("response spectrum, 100 periods, El Centro", ms(ec.get("ours_s")),
        f"the same recurrence vectorised in NumPy {ms(ec.get('peer_s'))}; as a C IIR filter "
        f"(scipy `lfilter`) {ms(ec.get('lfilter_s'))}",
        f"{x(ec.get('ratio'))}; {MISSING if not ec else format(ec['lfilter_ratio'], '.1f') + 'x'}",
        f"{ms(ec.get('multi_s'))} on {ec.get('threads', 'all')} threads" if ec else MISSING, "")
    r6 = rub.get("rtol 1e-06", {})
    row(f"polyurethane model, one protocol-1 evaluation (error {r6.get('ours_err', float('nan')):.0e})",
        ms(r6.get("ours_s")),
        f"scipy Radau at the same error (rtol {r6.get('radau_rtol', float('nan')):.2g}) "
        f"{ms(r6.get('peer_s'))}",
        x(r6.get("ratio")), "sequential", ">= 50x")
    row("polyurethane fit, 11 parameters with restarts", "", "", "", ms(rub.get("fit_s")) + " on 2 processes",
        "< 2 min")
    if gap:
        warm = [v["warm_s"] for v in gap.values() if isinstance(v, dict) and "warm_s" in v]
        cold = [v["cold_s"] for v in gap.values() if isinstance(v, dict) and "cold_s" in v]
        gap_text = (f"{min(warm):.0f}-{max(warm):.0f} s warm, {min(cold):.0f}-{max(cold):.0f} s with "
                    "an empty Numba cache")
    else:
        gap_text = MISSING
    row("whole gap diagnosis (every catalogue effect, 3 held-out tests)", "", "", "",
        gap_text + " on every core", "<= 60 s warm")
    st_text = (f"{st['warm_s']:.0f} s warm, {st['cold_s']:.0f} s with an empty Numba cache"
               if "warm_s" in st and "cold_s" in st else MISSING)
    row("whole `rrfrei shake-table` command, four BNCS runs", "", "", "", st_text + " on 2 cores",
        "<= 3 min warm")
    head = [
        "## Summary (ratios against the peer, measured in the same run)",
        "",
        "The headline figure of each section below, on this project's 2-core machine (the sections "
        "have the parameters, the agreement with the peer asserted in the same run, cold-start "
        "times and the date of each run; `python benchmarks/readme_table.py --write` rebuilds this "
        "table from `headline.json`). **Ratio per core** is rrfrei on one thread against the peer "
        "on one thread (warm-up excluded for both, median of the same interleaved repeats, the "
        "peer's model building and teardown outside its timer); **multi-core** is rrfrei's own "
        "throughput on every core, never divided by a single-threaded peer.",
        "",
        "| what | rrfrei, 1 thread | peer, 1 thread (same run) | ratio per core | multi-core | target |",
        "|---|---|---|---|---|---|",
    ]
    tail = ["", "Regenerate every section with `python benchmarks/run_all.py` (one script: "
            "`python benchmarks/bench_<name>.py`)."]
    return "\n".join(head + rows + tail)


def claims(h: dict) -> str:
    """The times README's prose states, from the fresh-clone run."""
    fc = h.get("fresh_clone")
    if not fc:
        return "README prose times: (not measured: run `python benchmarks/bench_fresh_clone.py`)"
    return "\n".join([
        "README prose times (fresh clone, 2 cores; " + fc.get("machine", "") + "):",
        f"- `rrfrei demo --quick`, first run after install (compiles): {fc['demo_quick_first_s']:.0f} s; "
        f"second run {fc['demo_quick_warm_s']:.0f} s",
        f"- `rrfrei demo` (full): {fc['demo_full_s']:.0f} s",
        f"- `rrfrei calibrate protocol1.csv --law bouc_wen`: {fc['calibrate_s']:.0f} s",
        f"- `python -m pytest` (default tier): {fc['tests_s']:.0f} s",
    ])


def write_summary(markdown: str, path: Path = RESULTS) -> None:
    """Replace the ``summary`` block of RESULTS.md (inserted before the first section if absent)."""
    block = f"<!-- summary:start -->\n{markdown.strip()}\n<!-- summary:end -->"
    text = path.read_text()
    start, end = text.find("<!-- summary:start -->"), text.find("<!-- summary:end -->")
    if start >= 0 and end > start:
        text = text[:start] + block + text[end + len("<!-- summary:end -->"):]
    else:
        first = text.find("<!-- ")
        first = len(text) if first < 0 else first
        text = text[:first] + block + "\n\n" + text[first:]
    path.write_text(text)


def main() -> None:
    h = json.loads(HEADLINE.read_text()) if HEADLINE.exists() else {}
    if "--write" in sys.argv[1:]:
        write_summary(table(h))
        print(f"wrote the summary block of {RESULTS}")
        return
    print(table(h))
    print()
    print(claims(h))


if __name__ == "__main__":
    main()
