"""``rrfrei shake-table``: calibrate, diagnose and predict a base-isolated building on shake-table runs."""

from __future__ import annotations

import json
import sys
import warnings
from dataclasses import replace
from pathlib import Path

from rrfrei.app.commands import HELPS, shake_table_meta
from rrfrei.app.commands.args import add_command, add_report_options, paragraph, positive_int
from rrfrei.laws import get
from rrfrei.notes import Note
from structures.shake_table import ConsistencyWarning
from structures.shake_table.gap import BNCS_ORDER, shake_table_gap
from structures.shake_table.report import write_report

EXAMPLE = """\
Example:
  rrfrei shake-table --out st --json            # the bundled BNCS runs: CNP100, LAC100, ICA50 -> ICA100
  rrfrei shake-table CNP100 LAC100 ICA50 ICA100 --calibrate ICA50 --holdout ICA100 --law bouc_wen --out st
  rrfrei shake-table run1/ run2.csv --calibrate run1 --holdout run2 --building bldg.toml --out st
  rrfrei shake-table raw/ICA50 raw/ICA100 --rate-hz 200 --level-order roof-first \\
      --weights 593.3,1078.1,1036.3,703,674,2275.1 --weight-unit kN --out st   # raw BNCS folders

A rerun with the same --out reuses the finished isolator fits (DIR/checkpoint).
RUNs are given in chronological order (the isolators' state is carried from each run to the
next); a RUN is a bundled name (CNP100, LAC100, ICA50, ICA100), a folder (a1..aN, d1..dN, u, du)
or a CSV with its TOML sidecar.  A raw folder needs its sampling rate and level masses: the
options below or its run.toml (docs/shake_table_data.md).  The reader's checks (a_i = d_i'' + a_g,
levels upside down, masses in the opposite order) print warnings on stderr and in the report's
notes; channels that contradict the stated rate stop the command (exit 2).
Writes DIR/shake_table.md and its figures.

Exit status: 0 a report was written (possibly an incomplete diagnosis: see its notes);
1 a numerical failure (the baseline cannot be fitted, every analysis failed), with what and where;
2 a user error (run, law, effect, option, building file).
"""

DEFAULT_BUDGET = 900.0
"""Default wall-clock budget of ``rrfrei shake-table`` [s]: the bundled runs need about 5 minutes of CPU
(every effect fitted by output error); the margin is for a loaded machine."""


HELP = HELPS["shake_table"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Calibrate the building by output error: the identified superstructure on the isolator law, driven by
every run's measured table acceleration in chronological order (isolator state carried), its
simulated isolator displacement, isolation-layer force and roof acceleration fitted to the measured
ones (the loop fit of the isolation-system loops is the start and a comparison row); diagnose which
isolator or system effect closes the gap to the held-out runs' simulated responses; report NRMSE,
peak error, 95 % band coverage and width per run and channel, and where the gap lies.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "shake-table", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument("runs", nargs="*", metavar="RUN",
                   help="runs in chronological order (default: the bundled CNP100 LAC100 ICA50 ICA100)")
    p.add_argument("--calibrate", nargs="+", default=None, metavar="RUN[,RUN]",
                   help="runs to calibrate on (default: every run but the last)")
    p.add_argument("--holdout", nargs="+", default=None, metavar="RUN[,RUN]",
                   help="runs to hold out (default: the last run)")
    p.add_argument("--law", default="auto",
                   help="base isolator law, or 'auto' (default): the best leave-one-cycle-out elpd of "
                        "plasticity, bouc_wen and hdr on the calibration runs")
    p.add_argument("--building", default=None, metavar="TOML",
                   help="building whose superstructure replaces the identified one (its isolator is "
                        "replaced by the calibrated law)")
    p.add_argument("--effects", nargs="*", default=None, metavar="EFFECT",
                   help="effects to try (default: all)")
    p.add_argument("--rate", type=float, default=25.0, metavar="HZ",
                   help="rate of the isolation tests the law is fitted on (default 25 Hz; the runs' rate "
                        "divided by an integer)")
    p.add_argument("--draws", type=positive_int, default=30, metavar="N",
                   help="posterior draws of each building fit, each a simulation of the runs (default 30)")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="processes for the candidates' refits (default 2 on a machine with two or more "
                        "cores, else 1; the result is the same for any number)")
    add_report_options(p, out="shake-table-report", budget=DEFAULT_BUDGET,
                       budget_help=f"wall-clock limit (default {DEFAULT_BUDGET:.0f} s): the diagnosis stops "
                                   "with the effects it has evaluated; 'none': no limit",
                       progress_help="no progress bars on stderr")
    shake_table_meta.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import matplotlib

    matplotlib.use("Agg")

    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if args.law != "auto":
        spec = get(args.law)  # an unknown law is a user error before anything heavy
        if spec.effects:
            raise ValueError(f"--law must be a base law, got the augmented law {spec.name!r}")
    if not args.rate > 0:
        raise ValueError(f"--rate must be > 0 Hz, got {args.rate}")
    if args.draws < 4:
        raise ValueError(f"--draws must be >= 4, got {args.draws}")
    runs, reader_notes = shake_table_meta.read_runs(args.runs or BNCS_ORDER, args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = shake_table_gap(runs, calibrate=args.calibrate, holdout=args.holdout, law=args.law,
                              building=args.building, rate_hz=args.rate, effects=args.effects,
                              draws=args.draws, seed=args.seed, time_budget=args.time_budget,
                              progress=not args.no_progress, checkpoint=Path(args.out) / "checkpoint",
                              workers=args.workers)
    for w in caught:
        if issubclass(w.category, ConsistencyWarning):
            print(f"rrfrei shake-table: warning: {w.message}", file=sys.stderr)
    if reader_notes:  # the reader's warnings bear on every number: first in the notes
        res = replace(res, notes=(*(Note(f"reading: {n}", "warning") for n in reader_notes), *res.notes))
    rep = res.report
    for e, why in rep.skipped.items():
        print(f"rrfrei shake-table: effect {e} skipped: {why}", file=sys.stderr)
    if rep.budget_message:
        print(rep.budget_message, file=sys.stderr)
    md = write_report(res, args.out)
    if args.json:
        json.dump(res.as_dict(), sys.stdout, indent=2)
        print()
    else:
        hb, ha = res.gap_before["holdout"], res.gap_after["holdout"]
        gap = (f"; held-out isolator displacement NRMSE {100 * hb['isolator_disp']:.0f} % -> "
               f"{100 * ha['isolator_disp']:.0f} %, coverage {100 * res.coverage['isolator_disp']:.0f} %, "
               f"band width {res.band_width['isolator_disp']:.2f} x RMS" if hb else "")
        print(f"law {res.law} (building fitted by output error); verdict: {res.verdict}{gap}; report {md}")
    return 0
