"""``rrfrei demo``: run every workflow on the bundled data and write one HTML page."""

from __future__ import annotations

import argparse
import sys

from rrfrei.app.demo import run_demo

EXAMPLE = """\
Example:
  rrfrei demo --out report --quick     # about 1 minute once compiled; open report/index.html
  rrfrei demo --out report --seed 3    # the full run (about 5 minutes on 2 cores once compiled)
"""


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value


def register(sub) -> None:
    p = sub.add_parser(
        "demo",
        help="run the whole pipeline on the bundled data and write an HTML report",
        description=(
            "Calibrate four isolator laws on the bundled SYNTHETIC RR-FREI test (protocol 1), compare "
            "them, validate the best on protocols 2-4, diagnose the sim-to-real gap, propagate the "
            "posterior through the bundled records on the 5-story example building, fit the "
            "polyurethane model, and write DIR/index.html (self-contained), DIR/tables/*.csv and "
            "DIR/manifest.json. A step that fails is shown in its section; the exit status is then 1."
        ),
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", default="rrfrei-report", metavar="DIR",
                   help="output folder (default: rrfrei-report)")
    p.add_argument("--quick", action="store_true",
                   help="two of the four laws, four gap effects, short chains, few samples, records "
                        "and stripes (goal: 90 s on a first run, compilation included)")
    p.add_argument("--seed", type=_seed, default=0, metavar="N", help="seed of every stochastic step")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")  # no display needed: every figure is embedded in the page
    result = run_demo(args.out, quick=args.quick, seed=args.seed, progress=not args.no_progress)
    print(f"wrote {result.page} ({result.seconds:.0f} s)")
    if not result.ok:
        for sec in result.report.sections:
            if sec.status != "ok":
                first = (sec.error or sec.reading).strip().splitlines()[0]
                print(f"rrfrei demo: step '{sec.key}' {sec.status}: {first}", file=sys.stderr)
        return 1
    return 0
