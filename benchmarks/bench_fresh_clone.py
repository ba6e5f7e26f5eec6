"""The times the README states, measured from a fresh clone (issue 13.4).

Clones the committed ``HEAD`` of this repository into a temporary folder (no ``.numba_cache``,
so nothing is compiled yet) and runs there, each in a fresh process with the clone first on
``PYTHONPATH`` (what ``pip install -e .`` in a fresh venv gives; the other packages are this
interpreter's):

1. ``rrfrei demo --quick`` (the first run after installing: includes every compilation);
2. ``rrfrei demo --quick`` again (warm Numba cache);
3. ``rrfrei demo`` (full, warm cache);
4. ``rrfrei calibrate rrfrei/data/isolator_synthetic/protocol1.csv --law bouc_wen`` (warm cache);
5. ``python -m pytest -q`` (the default tier; the cache as the runs above left it).

Each line gives the wall time, the exit status and the 1-minute load average before it; the
machine's load changes these times, so regenerate on a quiet machine.  Section ``fresh_clone``.

Run: ``python benchmarks/bench_fresh_clone.py [--quick]`` (``--quick``: clone and import only,
RESULTS.md unchanged).  Long: about 15-25 minutes on 2 cores.
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


def timed(label: str, argv: list[str], cwd: Path) -> tuple[str, float, int, float]:
    """Run ``argv`` in ``cwd`` (a fresh process, the clone first on the path): the table row data."""
    env = tm.user_env()  # as the user runs it: no BLAS pins, the clone's own Numba cache
    env.pop("NUMBA_CACHE_DIR", None)
    env["PYTHONPATH"] = str(cwd)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    run = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    print(f"{label}: {wall:.1f} s, exit {run.returncode}", run.stdout[-800:], run.stderr[-1500:], sep="\n",
          flush=True)
    return label, wall, run.returncode, load


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory(prefix="rrfrei-clone-") as tmp:
        src = Path(tmp) / "rrfrei"
        sha = clone(src)
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
        rows = [timed(label, argv, src) for label, argv in steps]
    lines = [
        "## fresh_clone", "",
        f"The README's times from a fresh clone of commit `{sha}` (no Numba cache yet), each command in a "
        "fresh process with the clone first on `PYTHONPATH` (as `pip install -e .` in a fresh venv), "
        f"in this order, on {os.cpu_count()} cores:", "",
        "| command | wall time | exit | load average before |", "|---|---:|---:|---:|",
        *(f"| {label} | {wall:.0f} s | {code} | {load:.1f} |" for label, wall, code, load in rows),
    ]
    keys = ("demo_quick_first_s", "demo_quick_warm_s", "demo_full_s", "calibrate_s", "tests_s")
    head = {k: wall for k, (_, wall, _, _) in zip(keys, rows)}
    report("fresh_clone", "\n".join(lines), quick=args.quick, headline=head)
    if any(code != 0 for _, _, code, _ in rows):
        raise SystemExit("a command failed in the fresh clone (see above)")


if __name__ == "__main__":
    main()
