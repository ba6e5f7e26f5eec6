"""``rrfrei gap-validate``: the gap diagnosis on tests made with withheld effects (issue 12.4)."""

from __future__ import annotations

from pathlib import Path

from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, add_no_progress, add_time_budget, paragraph, positive_int
from rrfrei.budget import seconds_arg
from rrfrei.gap.validation import CONTROLS, FULL, Settings, cases, run_table
from rrfrei.gap.validation.report import percent, write

EXAMPLE = """\
Example:
  python -m rrfrei.app gap-validate --seeds 10 --out docs/gap    # the table of docs/gap/validation.md
  rrfrei gap-validate --seeds 1 --reduced --out gv-quick         # a quick look: one form per effect
  rrfrei gap-validate --seeds 10 --out docs/gap --effects degradation slip   # some effects only

The table: every catalogue effect by each of its three generator forms x SEEDS seeds, plus four
controls x SEEDS.  10 seeds of six effects (220 cases) took 8 minutes on a shared 2-core machine;
with the nine effects of issue 12 (310 cases, each diagnosis a third longer) expect 15-30 minutes.
Finished cases are appended to DIR/validation_cases.jsonl: a rerun with the same --out and
settings resumes.  Writes DIR/validation.md, validation.json and validation_confusion.png.
Exit status 0 when the report was written, also when goals were missed (the report says where);
2 a user error.
"""


HELP = HELPS["gap_validate"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
For every catalogue effect, three generator forms that are not the catalogue's kernels, and four
no-effect controls (Gaussian, heavy-tailed and AR(1) noise), make protocols 1-4 from a base law
(plasticity or bouc_wen, alternating with the seed) plus that effect plus noise, calibrate on
protocol 1 with the effect withheld, hold out 2-4, diagnose, and report the confusion matrix, miss
rates per effect and per form, false alarms and held-out shrink against issue 12's goals.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "gap-validate", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument(
        "--seeds", type=positive_int, default=1, help="seeds per (effect, form) and control (default 1)"
    )
    p.add_argument(
        "--out",
        default="gap-validation",
        metavar="DIR",
        help="folder of validation.md, validation.json, validation_confusion.png and the "
        "checkpoint validation_cases.jsonl (default gap-validation)",
    )
    p.add_argument(
        "--effects",
        nargs="*",
        default=None,
        metavar="EFFECT",
        help="effects to include (default: every catalogue effect)",
    )
    p.add_argument("--no-controls", action="store_true", help="leave the controls out")
    p.add_argument(
        "--reduced",
        action="store_true",
        help="one generator form per effect and seed (rotating with the seed) instead of all "
        f"three: a third of the cases (settings as the table's: {FULL.rate:g} Hz, {FULL.draws} draws)",
    )
    p.add_argument("--workers", type=positive_int, default=2, help="processes (default 2)")
    add_time_budget(
        p,
        None,
        help="wall-clock limit of the whole table (default none): cases not started in "
        "time are reported as not run, and a rerun resumes",
    )
    p.add_argument(
        "--case-budget",
        type=seconds_arg,
        default=FULL.case_budget,
        metavar="SECONDS|none",
        help=f"wall-clock limit of one diagnosis (default {FULL.case_budget:.0f} s): "
        "a diagnosis cut short is 'incomplete'",
    )
    add_no_progress(p, "no progress bar on stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    settings = Settings(rate=FULL.rate, draws=FULL.draws, combine=False, case_budget=args.case_budget)
    controls = () if args.no_controls else tuple(CONTROLS)
    case_list = cases(args.seeds, effects=args.effects, controls=controls,
                      forms="rotate" if args.reduced else "all")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {args.out!r} is a file; expected a folder")
    res = run_table(
        case_list,
        settings,
        workers=args.workers,
        time_budget=args.time_budget,
        checkpoint=out / "validation_cases.jsonl",
        progress=not args.no_progress,
    )
    cmd = f"python -m rrfrei.app gap-validate --seeds {args.seeds}" + (" --reduced" if args.reduced else "")
    if args.effects:
        cmd += " --effects " + " ".join(args.effects)
    paths = write(res, out, command=cmd + f" --out {args.out}")
    print(res.confusion.to_string())
    g = res.goals()
    s = res.shrink_named.dropna()
    top = g["top1_per_effect_ge_95"]
    print(
        f"top-1 {percent(res.accuracy)} (goal >= 95 % per effect: "
        f"{'met' if top['met'] else 'missed by ' + ', '.join(top['missed_by'])}); "
        f"false alarms {res.false_alarms} of {len(res.control_cases)} controls; held-out shrink when named: "
        + (f"median {s.median():.2f}, min {s.min():.2f}" if len(s) else "no effect named")
    )
    if res.not_run:
        print(f"{res.not_run} cases not run (time budget): rerun the same command to resume")
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0
