"""``rrfrei gap``: where a calibrated law misses a test, which effect closes the gap, how far."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rrfrei.app.commands.calibrate import add_column_args, load
from rrfrei.budget import BudgetExceeded, TimeBudget, seconds_arg
from rrfrei.gap import diagnose_gap
from rrfrei.gap.report import write_report

EXAMPLE = """\
Example:
  rrfrei gap P1.csv --law bouc_wen --holdout P2.csv P3.csv P4.csv --out gap-report --json
  rrfrei gap protocol1 --law plasticity --holdout protocol2 --out gap   # bundled synthetic tests
  rrfrei gap loop.csv --law bouc_wen --time-budget 1800 --out gap   # rerun with the same --out resumes

Verdicts (first line of the report, "verdict" in the JSON):
  EFFECT        an effect is named: its leave-one-block-out gains on TEST and its squared-error
                reductions on the held-out blocks (half-cycles; time windows for monotonic or
                earthquake-like tests) pass a sign or Wilcoxon signed-rank test, and the
                block-bootstrap interval of the held-out systematic-gap shrink lies above 10 %
  none          what is left is noise: the systematic gap is within the noise (MSE / sigma^2 - 1
                <= 0.25) or below 1 % NRMSE, and no effect passes the rule
  unexplained   a systematic gap that no catalogued effect closes: where it lies, its size and
                the candidate that came closest (with its shrink and why it was rejected)
  incomplete    effects were skipped or not evaluated (time budget) and none of the others passed

JSON (--json): verdict, diagnosis (the named effect, else none/incomplete), combination,
evidence (the rule; baseline residual: systematic gap, excess over noise, lag-1
autocorrelation; for a named effect its block tests, shrink interval and what is left; for none
the reasons; for unexplained where/size/closest), ranking (per effect: elpd gain, shrinks,
passes_rule, named, block tests, shrink interval, why), where, gap_before, gap_after,
complete, skipped, not_evaluated, time_budget, notes.  Band coverage is never adequacy: a band
widened by the noise sd covers a model that misses.

Exit status: 0 a report was written (possibly an incomplete diagnosis: see its first lines);
1 the baseline could not be fitted (numerical failure, or the time budget ran out during it);
2 a user error (file, column, law, effect, option).
"""

DEFAULT_BUDGET = 600.0
"""Default wall-clock budget of ``rrfrei gap`` [s]."""


def register(sub) -> None:
    p = sub.add_parser(
        "gap", help="diagnose the sim-to-real gap of a calibrated law (which unmodelled effect)",
        description=(
            "Calibrate LAW on TEST, find where its residuals exceed the noise, refit the law with "
            "each catalogue effect (degradation, mullins, rollover, rate, asymmetry, slip), decide "
            "on block tests over half-cycles (calibration and held-out) and a block bootstrap of the "
            "held-out systematic gap, give a verdict (an effect, none, unexplained, incomplete) with "
            "its evidence, and write a Markdown report with figures to DIR."),
        epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("test", help="calibration test CSV (or a bundled name: protocol1..protocol4)")
    p.add_argument("--law", default="bouc_wen", help="base law (default: bouc_wen)")
    p.add_argument("--holdout", nargs="*", default=[], metavar="CSV", help="held-out tests")
    p.add_argument("--effects", nargs="*", default=None, metavar="EFFECT",
                   help="effects to try (default: all six)")
    p.add_argument("--out", default="gap-report", metavar="DIR", help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of fits and draws (default 0)")
    p.add_argument("--json", action="store_true", help="print the JSON summary on stdout")
    p.add_argument("--time-budget", type=seconds_arg, default=DEFAULT_BUDGET, metavar="SECONDS|none",
                   help=f"wall-clock limit (default {DEFAULT_BUDGET:.0f} s): when reached, report the "
                        "effects evaluated so far and list the others as not evaluated; 'none': no limit")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    add_column_args(p)
    p.set_defaults(func=run)


def run(args) -> int:
    budget = TimeBudget(args.time_budget, what="rrfrei gap", option="--time-budget")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    test = load(args.test, args)
    holdout = [load(h, args) for h in args.holdout]
    try:
        rep = diagnose_gap(test, args.law, holdout=holdout, effects=args.effects, seed=args.seed,
                           progress=not args.no_progress, time_budget=budget,
                           checkpoint=Path(args.out) / "checkpoint")
    except BudgetExceeded as exc:
        print(str(exc), file=sys.stderr)
        return 1
    for e, why in rep.skipped.items():
        print(f"rrfrei gap: effect {e} skipped: {why}", file=sys.stderr)
    if rep.budget_message:
        print(rep.budget_message, file=sys.stderr)
    md = write_report(rep, args.out)
    if args.json:
        json.dump(rep.as_dict(), sys.stdout, indent=2)
        print()
    else:
        print(f"verdict: {rep.verdict}; combination: {'+'.join(rep.combination) or 'none'}; report {md}")
    return 0
