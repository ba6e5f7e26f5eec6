"""``rrfrei gap-validate``: the gap diagnosis on tests made with withheld effects."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rrfrei.gap.validate import validate

EXAMPLE = """\
Example:
  rrfrei gap-validate --seeds 5 --out gap-validation     # about 10 minutes on 2 cores
  rrfrei gap-validate --seeds 1 --reduced                 # the quick check of the test suite
"""


def _positive(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def register(sub) -> None:
    p = sub.add_parser(
        "gap-validate", help="validate the gap diagnosis on synthetic tests with withheld effects",
        description=(
            "For every catalogue effect and a no-effect control, make tests from the plasticity law "
            "plus that effect plus noise (protocol 1 to calibrate, 2-4 held out), withhold the "
            "effect from the model, diagnose, and report the confusion matrix, held-out shrink and "
            "false-alarm rate."),
        epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=_positive, default=1, help="seeds per case (default 1)")
    p.add_argument("--out", default=None, metavar="DIR", help="write cases.csv, confusion.csv, summary.json")
    p.add_argument("--reduced", action="store_true", help="10 Hz tests and 100 draws (faster)")
    p.set_defaults(func=run)


def run(args) -> int:
    def show(r: dict) -> None:
        print(f"  {r['case']:<12} seed {r['seed']}: {r['diagnosed']}", flush=True)

    res = validate(args.seeds, reduced=args.reduced, progress=show)
    print(res.confusion.to_string())
    named = res.cases[(res.cases.case == res.cases.diagnosed) & (res.cases.case != "control")]
    print(f"top-1 accuracy {100 * res.accuracy:.0f} %; false alarms {res.false_alarms} of "
          f"{int((res.cases.case == 'control').sum())} controls; held-out shrink of the named effect: "
          f"min {named.shrink_holdout.min():.2f}, median {named.shrink_holdout.median():.2f}")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        res.cases.to_csv(out / "cases.csv", index=False)
        res.confusion.to_csv(out / "confusion.csv")
        (out / "summary.json").write_text(json.dumps(res.as_dict(), indent=2, default=str), encoding="utf-8")
    return 0
