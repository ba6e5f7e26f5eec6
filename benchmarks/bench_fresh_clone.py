"""The times the README states, measured from a fresh clone (issues 13.4 and 28.9).

Clones the committed ``HEAD`` of this repository into a temporary folder and runs there, each in
a fresh process with the clone first on ``PYTHONPATH`` (what ``pip install -e .`` in a fresh venv
gives, the install itself excluded; the other packages are this interpreter's), with a Numba
cache that starts EMPTY: ``NUMBA_CACHE_DIR`` and ``XDG_CACHE_HOME`` point at new folders inside
the temporary one (so neither the repository's nor the user's kernel cache is read):

1. ``rrfrei demo --quick`` (a newcomer's first run: every import and compilation; goal 90 s);
2. ``rrfrei demo --quick`` again (warm cache);
3. ``rrfrei demo`` (full, warm cache);
4. ``rrfrei calibrate rrfrei/data/isolator_synthetic/protocol1.csv --law bouc_wen`` (warm cache);
5. ``python -m pytest -q`` (the default tier; the cache as the runs above left it).

Each line gives the wall time, the CPU time (user + system of the whole process tree: the
command and every child it waited for, from ``getrusage(RUSAGE_CHILDREN)``), the exit status and
the 1-minute load average before it.  On a shared machine the wall time grows with the load and
the CPU time much less, so both are reported; regenerate on a quiet machine.  Section
``fresh_clone``.

Run: ``python benchmarks/bench_fresh_clone.py`` (long: about 15-25 minutes on 2 cores);
``--demo-only``: rows 1 and 2 only (RESULTS.md unchanged, figures printed); ``--quick``: clone
and import only (RESULTS.md unchanged).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import _timing as tm  # noqa: E402
from _results import report  # noqa: E402

CLI = "import sys\nfrom rrfrei.app.cli import main\nsys.exit(main())"


def clone(dest: Path) -> str:
    """Clone the committed HEAD (not the working tree) into ``dest``; return its short hash."""
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                         check=True).stdout.strip()
    subprocess.run(["git", "clone", "-q", "--no-checkout", str(ROOT), str(dest)], check=True)
    subprocess.run(["git", "-C", str(dest), "checkout", "-q", "--detach", sha], check=True)
    return sha[:10]


def timed(label: str, argv: list[str], cwd: Path, cache: Path) -> tuple[str, float, float, int, float]:
    """Run ``argv`` in ``cwd`` (a fresh process, the clone first on the path, the kernel cache in
    ``cache``): ``(label, wall [s], CPU [s], exit status, load average before)``."""
    env = tm.user_env()  # as the user runs it: no BLAS pins
    env["PYTHONPATH"] = str(cwd)
    env["NUMBA_CACHE_DIR"] = str(cache / "numba")  # starts empty: nothing compiled yet
    env["XDG_CACHE_HOME"] = str(cache / "xdg")  # the per-user cache folder, empty too
    env["MPLBACKEND"] = "Agg"
    load = os.getloadavg()[0]
    c0 = tm.children_cpu()
    t0 = time.perf_counter()
    run = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu = tm.children_cpu() - c0
    print(f"{label}: {wall:.1f} s wall, {cpu:.1f} s CPU, exit {run.returncode}", run.stdout[-800:],
          run.stderr[-1500:], sep="\n", flush=True)
    return label, wall, cpu, run.returncode, load


def main() -> None:
    ap = tm.parser(__doc__)
    ap.add_argument("--demo-only", action="store_true",
                    help="only `rrfrei demo --quick` cold and warm; prints, does not write RESULTS.md")
    args = ap.parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory(prefix="rrfrei-clone-") as tmp:
        src = Path(tmp) / "rrfrei"
        sha = clone(src)
        cache = Path(tmp) / "cache"
        cache.mkdir()
        shared = ROOT.parent / "shared"
        if shared.is_dir():  # the tests read the real data at ../shared, as in a checkout
            (Path(tmp) / "shared").symlink_to(shared, target_is_directory=True)
        out = Path(tmp) / "out"
        if args.quick:
            steps = [("import every package",
                      [py, "-c", "import rrfrei, structures, rubber, ground_motions"]),
                     ("CLI --help", [py, "-c", CLI, "--help"])]
        else:
            csv = "rrfrei/data/isolator_synthetic/protocol1.csv"
            steps = [
                ("`rrfrei demo --quick`, first run (empty Numba cache: compiles)",
                 [py, "-c", CLI, "demo", "--quick", "--out", str(out / "q1")]),
                ("`rrfrei demo --quick`, second run (warm cache)",
                 [py, "-c", CLI, "demo", "--quick", "--out", str(out / "q2")]),
                ("`rrfrei demo` (full, warm cache)", [py, "-c", CLI, "demo", "--out", str(out / "full")]),
                ("`rrfrei calibrate protocol1.csv --law bouc_wen` (warm cache)",
                 [py, "-c", CLI, "calibrate", csv, "--law", "bouc_wen", "--out", str(out / "cal"),
                  "--quiet"]),
                ("`python -m pytest -q` (default tier)",
                 [py, "-m", "pytest", "-q", "-p", "no:cacheprovider"]),
            ]
            if args.demo_only:
                steps = steps[:2]
        rows = [timed(label, argv, src, cache) for label, argv in steps]
    lines = [
        "## fresh_clone", "",
        f"The README's times from a fresh clone of commit `{sha}`, each command in a fresh process with "
        "the clone first on `PYTHONPATH` (as `pip install -e .` in a fresh venv, the install excluded) "
        "and a kernel cache that starts empty (`NUMBA_CACHE_DIR`, `XDG_CACHE_HOME` in new folders), in "
        f"this order, on {os.cpu_count()} cores. CPU = user + system time of the process tree.", "",
        "| command | wall time | CPU time | exit | load average before |", "|---|---:|---:|---:|---:|",
        *(f"| {label} | {wall:.0f} s | {cpu:.0f} s | {code} | {load:.1f} |"
          for label, wall, cpu, code, load in rows),
        "", "Goal (issue 28.9): the first `rrfrei demo --quick` at most 90 s.",
    ]
    keys = ("demo_quick_first_s", "demo_quick_warm_s", "demo_full_s", "calibrate_s", "tests_s")
    head = {k: wall for k, (_, wall, _, _, _) in zip(keys, rows)}
    head.update({k.removesuffix("_s") + "_cpu_s": cpu for k, (_, _, cpu, _, _) in zip(keys, rows)})
    report("fresh_clone", "\n".join(lines), quick=args.quick or args.demo_only, headline=head)
    if any(code != 0 for _, _, _, code, _ in rows):
        raise SystemExit("a command failed in the fresh clone (see above)")


if __name__ == "__main__":
    main()
