"""``rrfrei gap``: where a calibrated law misses a test, which effect closes the gap, how far."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import ground_motions
from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, add_report_options, positive_int
from rrfrei.app.commands.calibrate import add_column_args, load
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.errors import NUMERICAL_ERRORS
from rrfrei.gap import diagnose_gap
from rrfrei.gap.catalogue import catalogue
from rrfrei.gap.parallel import default_workers
from rrfrei.gap.report import design_summary, write_report
from rrfrei.io import ShearTest
from rrfrei.laws import get as get_law
from rrfrei.notes import label, ordered
from structures.propagation.consequences import building_consequences, plot_consequences

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


HELP = HELPS["gap"]
"""One-line help of the command in ``rrfrei --help``."""


def register(sub) -> None:
    description = (
        "Calibrate LAW on TEST, find where its residuals exceed the noise, refit the law with "
        f"each catalogue effect ({', '.join(catalogue())}), decide "
        "on block tests over half-cycles (calibration and held-out) and a block bootstrap of the "
        "held-out systematic gap, give a verdict (an effect, none, unexplained, incomplete) with "
        "its evidence, and write a Markdown report with figures to DIR."
    )
    p = add_command(sub, "gap", help=HELP, description=description, epilog=EXAMPLE)
    p.add_argument("test", help="calibration test CSV (or a bundled name: protocol1..protocol4)")
    p.add_argument("--law", default="bouc_wen", help="base law (default: bouc_wen)")
    p.add_argument("--holdout", nargs="*", default=[], metavar="CSV", help="held-out tests")
    p.add_argument("--effects", nargs="*", default=None, metavar="EFFECT",
                   help=f"effects to try (default: every catalogue effect: {', '.join(catalogue())})")
    p.add_argument("--carry", action="store_true",
                   help="the tests are runs of ONE specimen in the order given (TEST, then each held-out "
                        "test): each held-out test is simulated after the ones before it, so scragging, "
                        "degradation and the law's own state carry over (ShearTest.after)")
    p.add_argument("--every", type=int, default=1, metavar="K",
                   help="keep every K-th sample of every test (a stated decimation for dense records; "
                        "default 1: all)")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="processes for the candidates' refits (default 2 on a machine with two or more "
                        "cores, else 1; the result is the same for any number)")
    p.add_argument("--building-records", type=int, default=11, metavar="N",
                   help="bundled records (first N of the eleven) for the building consequences of the "
                        "named effect at lower/nominal/upper bound (default 11; 0: no building section)")
    add_report_options(p, out="gap-report", budget=DEFAULT_BUDGET,
                       budget_help=f"wall-clock limit (default {DEFAULT_BUDGET:.0f} s): when reached, report "
                                   "the effects evaluated so far and list the others as not evaluated; "
                                   "'none': no limit",
                       progress_help="no progress bar on stderr")
    add_column_args(p)
    p.set_defaults(func=run)


def _every(test: ShearTest, k: int) -> ShearTest:
    """Every k-th sample of ``test`` (the name says so)."""
    if k == 1:
        return test
    return ShearTest(f"{test.name}[::{k}]", test.time[::k], test.disp[::k], test.force[::k],
                     has_time=test.has_time, vertical_load=test.vertical_load,
                     geometry=dict(test.geometry), source=test.source, meta=dict(test.meta))


def _building(rep, design, n_records: int, out: Path):
    """The five-story building at lower/nominal/upper bound with and without the named effects,
    from the lambdas the effect implies (measured ones without a named effect); None when not
    asked for or not formed (a note is printed)."""
    pm = design.lambdas_model or design.lambdas_measured
    if n_records == 0 or pm is None:
        return None
    fit = rep.fits[design.final_law]
    base = get_law(rep.law)
    params = dict(fit.params)
    base_params = {k: v for k, v in params.items() if k in base.param_names}
    effect_params = {k: v for k, v in params.items() if k not in base.param_names} or None
    try:
        df = building_consequences(design.final_law, base_params, pm, effect_params=effect_params,
                                   records=list(ground_motions.available())[:n_records])
    except NUMERICAL_ERRORS as exc:
        print(f"rrfrei gap: building consequences skipped: {type(exc).__name__}: {exc}", file=sys.stderr)
        return None
    fig = plot_consequences(df, title=f"five-story building: {design.final_law} at its bounds")
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "consequences.png")
    return df


def _building_json(df) -> list[dict]:
    med = df[df["record"] == "median"]
    return [{"law": r.law, "effect": r.effect, "bound": r.bound, "lambda": float(r._4),
             "iso_disp_peak_m": float(r.iso_disp_peak), "base_shear_peak_kN": float(r.base_shear_peak)}
            for r in med.itertuples()]


def run(args) -> int:
    budget = TimeBudget(args.time_budget, what="rrfrei gap", option="--time-budget")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if args.every < 1:
        raise ValueError(f"--every must be an integer >= 1, got {args.every}")
    if not 0 <= args.building_records <= 11:
        raise ValueError(f"--building-records must be in 0..11, got {args.building_records}")
    test = _every(load(args.test, args), args.every)
    holdout = [_every(load(h, args), args.every) for h in args.holdout]
    if args.carry:
        holdout = [h.after(test, *holdout[:i]) for i, h in enumerate(holdout)]
    try:
        rep = diagnose_gap(test, args.law, holdout=holdout, effects=args.effects, seed=args.seed,
                           progress=not args.no_progress, time_budget=budget,
                           checkpoint=Path(args.out) / "checkpoint",
                           workers=args.workers or default_workers())
    except BudgetExceeded as exc:
        print(str(exc), file=sys.stderr)
        return 1
    for n in ordered(rep.notes):  # critical first; routine notes stay in the report
        if n.severity != "info":
            print(f"rrfrei gap: {label(n)}", file=sys.stderr)
    design = design_summary(rep)
    building = _building(rep, design, args.building_records, Path(args.out))
    md = write_report(rep, args.out, design=design, building=building)
    if args.json:
        out = rep.as_dict()
        out["design"] = design.as_dict()
        out["building"] = None if building is None else _building_json(building)
        if args.every > 1:
            out["decimation"] = f"every {args.every}th sample"
        json.dump(out, sys.stdout, indent=2)
        print()
    else:
        print(f"verdict: {rep.verdict}; combination: {'+'.join(rep.combination) or 'none'}; report {md}")
    return 0
