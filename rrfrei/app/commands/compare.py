"""``rrfrei compare``: calibrate several laws on one test and rank them (LOO, WAIC, by cycle)."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, paragraph
from rrfrei.app.commands.calibrate import add_column_args, add_common, load
from rrfrei.calibration import BoundWarning, ConvergenceWarning, calibrate, compare
from rrfrei.calibration.compare import runnable_laws, too_few_laws
from rrfrei.laws import OPENSEES_LAWS, get
from rrfrei.notes import Note, label, ordered

EXAMPLE = """\
Example:
  rrfrei compare protocol1.csv --laws all --out cmp           # the OpenSees laws the test can run
  rrfrei compare protocol1 --laws plasticity,bouc_wen --steps 1500 --out cmp --json
Writes DIR/compare.csv, DIR/pareto_k.csv, DIR/loco_cycles.csv, DIR/compare.png and
DIR/posterior_<law>.nc.
"""


HELP = HELPS["compare"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Calibrate each law on the test and compare their expected log predictive densities (PSIS-LOO with
Pareto-k diagnostics, WAIC, leave-one-cycle-out). A difference under 2 dse does not separate two
laws.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "compare", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument("test", metavar="TEST.csv", help="test file (or a bundled test name)")
    p.add_argument("--laws", default="all", help="comma-separated law names, or 'all' (default)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_common(p)
    add_column_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    asked = list(OPENSEES_LAWS) if args.laws.strip() == "all" else [
        s.strip() for s in args.laws.split(",") if s.strip()]
    for law in asked:
        get(law)
    if len(asked) < 2:
        raise ValueError(f"give at least two laws to compare, got {asked}")
    test = load(args.test, args)
    laws, skipped = runnable_laws(test, asked)  # before any work: what this test can run
    for law, why in skipped.items():
        print(f"rrfrei compare: warning: skipped {law}: {why}", file=sys.stderr)
    if len(laws) < 2:
        raise ValueError(too_few_laws(laws, skipped))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cals = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        warnings.simplefilter("always", BoundWarning)
        for law in laws:
            cals[law] = calibrate(test, law, noise=args.noise, seed=args.seed, walkers=args.walkers,
                                  steps=args.steps, priors=args.priors,
                                  progress=not args.no_progress and not args.json)
            cals[law].to_netcdf(out / f"posterior_{law.replace('+', '_')}.nc")
    notes = [Note(str(w.message), "critical" if issubclass(w.category, ConvergenceWarning) else "warning")
             for w in caught if issubclass(w.category, (ConvergenceWarning, BoundWarning))]
    for n in ordered(notes):  # critical first
        print(f"rrfrei compare: {label(n)}", file=sys.stderr)
    res = compare(cals)
    res.table.to_csv(out / "compare.csv")
    res.pareto_k.to_csv(out / "pareto_k.csv")
    res.loco_cycles.to_csv(out / "loco_cycles.csv", index=False)
    fig = res.figure()
    fig.savefig(out / "compare.png", dpi=110)
    plt.close(fig)
    result = {
        "best": res.best,
        "table": {law: {k: (v if isinstance(v, str) else float(v)) for k, v in row.items()}
                  for law, row in res.table.iterrows()},
        "converged": {law: bool(c.converged) for law, c in cals.items()},
        "skipped": skipped,
        "fit": {law: {"nrmse": float(r["nrmse"]), "systematic": float(r["systematic"]),
                      "coverage": float(r["coverage"]), "adequacy": str(r["adequacy"])}
                for law, r in res.table.iterrows()},
        "best_reading": res.best_line,
    }
    (out / "result.json").write_text(json.dumps(result, indent=2))
    if args.json:
        print(json.dumps(result))
    else:
        print(res.table.to_string(float_format=lambda x: f"{x:.4g}"))
        print(f"{res.best_line}; wrote {out}")
    return 0
