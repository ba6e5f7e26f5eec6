"""``rrfrei demo``: run every workflow on the bundled data and write one HTML page."""

from __future__ import annotations

import argparse
import sys

from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, add_no_progress, nonneg_int, paragraph
from rrfrei.app.demo import run_demo

EXAMPLE = """\
Example:
  rrfrei demo --out report --quick     # about 1 minute once compiled; open report/index.html
  rrfrei demo --out report --seed 3    # the full run (about 5 minutes on 2 cores once compiled)
"""


HELP = HELPS["demo"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Calibrate four isolator laws on the bundled SYNTHETIC RR-FREI test (protocol 1), compare them,
validate the best on protocols 2-4, diagnose the sim-to-real gap, propagate the posterior through
the bundled records on the 5-story example building, fit the polyurethane model, and write
DIR/index.html (self-contained), DIR/tables/*.csv and DIR/manifest.json. A step that fails is shown
in its section; the exit status is then 1.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "demo", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument("--out", default="rrfrei-report", metavar="DIR",
                   help="output folder (default: rrfrei-report)")
    p.add_argument("--quick", action="store_true",
                   help="two of the four laws, four gap effects, short chains, few samples, records "
                        "and stripes (goal: 90 s on a first run, compilation included)")
    p.add_argument("--seed", type=nonneg_int, default=0, metavar="N", help="seed of every stochastic step")
    add_no_progress(p)
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
