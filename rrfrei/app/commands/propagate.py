"""``rrfrei propagate``: posterior draws x ground motions on a building -> demands, figures, tables."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

import ground_motions
from ground_motions.asce7 import SuiteSizeWarning
from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, add_json, add_no_progress, int_arg, paragraph
from structures.propagation.inputs import resolve_building, resolve_records
from structures.propagation.plan_design import (
    TorsionAmplification,
    check_plan_law,
    plan_design_answers,
    plot_orbit,
    resolve_pairs,
)
from structures.propagation.plan_propagate import design_distribution, propagate_pairs, suite_design
from structures.propagation.propagate import propagate
from structures.propagation.summaries import ALL

EXAMPLE = """\
Example:
  rrfrei propagate --posterior cal/posterior.nc --building five_story \\
      --records elcentro,kocaeli,chichi --samples 200 --scales 0.5,1,1.5 --out prop
  rrfrei propagate --posterior cal/posterior.nc --building my_building.toml --records all \\
      --samples 1000 --scheduler tcp://10.0.0.5:8786 --out prop --json

  rrfrei propagate --posterior cal/posterior.nc --building three_story \
      --records santamonica,ferndale,RSN1_H1.AT2+RSN1_H2.AT2 --bidirectional --bounds 0.85,1.15 \
      --samples 50 --out prop2

Writes DIR/responses.parquet and DIR/responses.csv (one row per sample x record x scale),
DIR/summary.csv, DIR/variance_split.csv, DIR/exceedance.csv, DIR/fragility.csv and the figures
DIR/*.png.  Results are stored chunk by chunk in DIR/store: rerun the same command to resume an
interrupted run.

With --bidirectional the records are pairs of horizontal components (bundled pair names:
santamonica, ferndale, ridgecrest; or two files joined by '+'), both applied at once to the plan
building (coupled plan isolator law); the tables gain per-direction and plan columns (and a
'bound' column with --bounds), and the code's answers (ASCE 7-22 Chapter 17) are written too:
DIR/design_answers.csv (per pair and over the suite, per bound, for the posterior draw whose suite
design displacement is the median; at the first scale),
DIR/design_draws.csv and DIR/design_distribution.csv (the suite design values per posterior draw
and their percentiles) and DIR/orbit_<pair>.png (isolator y vs x with the design-displacement
circle).  With --asce7 the pairs are first scaled per ASCE 7-22 17.3.3 (DIR/asce7_scaling.csv,
.txt, .png).  Stores: DIR/store-plan/<bound>.
"""


def _scales(text: str) -> tuple[float, ...]:
    msg = f"scales must be comma-separated numbers > 0, got {text!r}"
    try:
        vals = tuple(float(s) for s in text.split(",") if s.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(msg) from None
    if not vals or any(not (0 < v < float("inf")) for v in vals):
        raise argparse.ArgumentTypeError(msg)
    return vals


def _bounds(text: str) -> tuple[float, float]:
    msg = f"bounds must be LMIN,LMAX with 0 < LMIN <= 1 <= LMAX (e.g. 0.85,1.15), got {text!r}"
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(msg) from None
    if not (0.0 < lo <= 1.0 <= hi < float("inf")):
        raise argparse.ArgumentTypeError(msg)
    return lo, hi


def _torsion(text: str) -> TorsionAmplification:
    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) not in (4, 5):
            raise ValueError("expected 4 or 5 numbers")
        return TorsionAmplification(*vals)
    except (TypeError, ValueError) as exc:
        raise argparse.ArgumentTypeError(
            f"torsion must be Y,B,D,E[,PT] (bearing offset, plan dimensions, eccentricity [m], period "
            f"ratio), got {text!r}: {exc}") from None


def _asce7(text: str) -> tuple[float, ...]:
    msg = (f"asce7 must be SDS,SD1,TL,T_UPPER,T_LOWER (design spectrum [g, g, s], T_M with upper- and "
           f"lower-bound properties [s]), got {text!r}")
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(msg) from None
    if len(vals) != 5 or not all(0.0 < v < float("inf") for v in vals) or vals[3] > vals[4]:
        raise argparse.ArgumentTypeError(msg)
    return vals


HELP = HELPS["propagate"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Draw --samples full parameter sets from a calibrated posterior, run each on the building under every
record at every scale (Numba, all cores; or a Dask cluster with --scheduler), and summarise the
demands: percentiles, the share of variance due to the isolator parameters vs. the records,
exceedance probabilities and lognormal fragility curves.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "propagate", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument("--posterior", required=True, metavar="FILE",
                   help="posterior.nc written by `rrfrei calibrate`")
    p.add_argument("--building", required=True, metavar="B",
                   help="building TOML file or example name (three_story, five_story)")
    p.add_argument("--records", required=True, metavar="R1,R2,...",
                   help="bundled record names or file paths, comma-separated; 'all' for every bundled record")
    p.add_argument("--samples", type=int_arg(1, "a positive integer", name="samples"), default=200,
                   metavar="N", help="posterior draws (default 200)")
    p.add_argument("--scales", type=_scales, default=(1.0,), metavar="S1,S2,...",
                   help="intensity multipliers (default 1); two or more give fragility curves")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (tcp://host:8786); default: all local cores")
    p.add_argument("--seed", type=int_arg(0, "a non-negative integer", name="seed"), default=0,
                   metavar="N", help="seed of the posterior draws")
    p.add_argument("--chunk-size", type=int_arg(1, "a positive integer", name="chunk-size"), default=50,
                   metavar="N", help="draws per chunk (default 50)")
    p.add_argument("--bidirectional", action="store_true",
                   help="records are pairs of horizontal components (bundled pair names or A.AT2+B.AT2), "
                        "run together on the plan building; adds the ASCE 7-22 Chapter 17 answers and "
                        "isolator orbit plots")
    p.add_argument("--bounds", type=_bounds, default=None, metavar="LMIN,LMAX",
                   help="with --bidirectional: property modification factors of the lower- and upper-bound "
                        "analyses (ASCE 7-22 17.2.8.4), e.g. 0.85,1.15; default: nominal properties only")
    p.add_argument("--torsion", type=_torsion, default=None, metavar="Y,B,D,E[,PT]",
                   help="with --bidirectional: amplify the total maximum displacement for a bearing at "
                        "Y m from the centre of a B x D m plan with eccentricity E m (period ratio PT, "
                        "default 1); default: no torsion (the plan building has none)")
    p.add_argument("--asce7", type=_asce7, default=None, metavar="SDS,SD1,TL,T_UPPER,T_LOWER",
                   help="with --bidirectional: first scale the pairs per ASCE 7-22 17.3.3 (one factor per "
                        "pair, suite-average RotD100 >= the MCE_R spectrum, 1.5 x the design spectrum, over "
                        "0.75 T_UPPER to 1.25 T_LOWER); --scales then multiply the scaled pairs")
    add_json(p, "print the summary as JSON instead of a table")
    add_no_progress(p, "no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import matplotlib  # deferred: only a run draws figures (and --help stays quick)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    # validate cheap inputs first, in the order a user reads the command line
    building = resolve_building(args.building)
    names = [s.strip() for s in args.records.split(",") if s.strip()]
    if not args.bidirectional and (args.bounds is not None or args.torsion is not None or args.asce7):
        raise ValueError("--bounds, --torsion and --asce7 need --bidirectional (the code's answers of record "
                         "pairs)")
    if args.bidirectional:
        check_plan_law(building.isolator.law)
        if names == ["all"]:
            names = list(ground_motions.available_pairs())
        records = resolve_pairs(names)
        if args.asce7 is not None:
            sds, sd1, tl, t_upper, t_lower = args.asce7
            with warnings.catch_warnings():  # fewer than 7 pairs: said in suite.summary() below
                warnings.simplefilter("ignore", SuiteSizeWarning)
                suite = ground_motions.scale_pairs_asce7(records, ground_motions.mcer_target(sds, sd1, tl),
                                                         t_upper, t_lower)
            records = list(suite.pairs)
    else:
        if names == ["all"]:
            names = list(ground_motions.available())
        records = resolve_records(names)
    post = Path(args.posterior)
    if not post.exists():
        raise FileNotFoundError(2, "No such file or directory", str(post))

    client = None
    if args.scheduler:
        try:
            from distributed import Client  # optional dependency (rrfrei[dask]), only with --scheduler
        except ImportError:
            raise ValueError("--scheduler needs dask.distributed: pip install 'rrfrei[dask]'") from None
        try:
            client = Client(args.scheduler, timeout=30)
        except OSError as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {args.scheduler!r}: {exc}") from None
    sets = {}
    try:
        if args.bidirectional:
            lams = {"nominal": 1.0}
            if args.bounds is not None:
                lams.update(lower=args.bounds[0], upper=args.bounds[1])
            for bound, lam in lams.items():
                sets[bound] = propagate_pairs(
                    post, building, records, n_samples=args.samples, scales=args.scales, seed=args.seed,
                    executor=client, store=out / "store-plan" / bound, progress=not args.no_progress,
                    chunk_size=args.chunk_size, lam=lam, torsion=args.torsion)
            rs = sets["nominal"]
        else:
            rs = propagate(post, building, records, n_samples=args.samples, scales=args.scales,
                           seed=args.seed, executor=client, store=out / "store",
                           progress=not args.no_progress, chunk_size=args.chunk_size)
    finally:
        if client is not None:
            client.close()

    out.mkdir(parents=True, exist_ok=True)
    table = rs.table
    if sets:
        table = pd.concat([r.table.assign(bound=b) for b, r in sets.items()], ignore_index=True)
        table = table[["bound", *rs.table.columns]]
    table.to_parquet(out / "responses.parquet", index=False)
    table.to_csv(out / "responses.csv", index=False)
    summary = rs.summary()
    summary.to_csv(out / "summary.csv", index=False)
    split = rs.variance_split()
    split.to_csv(out / "variance_split.csv", index=False)
    exc = rs.exceedance()
    exc.to_csv(out / "exceedance.csv", index=False)
    frag = rs.fragility() if len(rs.scales) > 1 else []
    pd.DataFrame([{"demand": f.demand, "limit": f.limit, "theta": f.theta, "beta": f.beta, "note": f.note}
                  for f in frag]).to_csv(out / "fragility.csv", index=False)
    figures = []
    for d in ("iso_disp_peak_m", "drift_ratio_max", "floor_acc_max_ms2"):
        for kind, fn in (("distribution", rs.plot_distributions), ("exceedance", rs.plot_exceedance)):
            fig = fn(d)
            path = out / f"{kind}_{d}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            figures.append(path.name)
    if frag:
        fig = rs.plot_fragility()
        fig.savefig(out / "fragility.png", dpi=120)
        plt.close(fig)
        figures.append("fragility.png")

    plan = _bidirectional(args, out, building, records, sets, plt) if sets else None
    if sets and args.asce7 is not None:
        pd.DataFrame({"pair": [p.name for p in suite.pairs], "factor": suite.factors}).to_csv(
            out / "asce7_scaling.csv", index=False)
        (out / "asce7_scaling.txt").write_text(suite.summary() + "\n")
        fig, ax = plt.subplots(figsize=(7.0, 4.2), layout="constrained")
        ground_motions.plot_scaled_suite(suite, ax=ax)
        fig.savefig(out / "asce7_scaling.png", dpi=120)
        plt.close(fig)
        figures.append("asce7_scaling.png")
    figures += plan["figures"] if plan else []

    pooled = summary[summary["record"] == ALL]
    if args.json:
        body = {
            "law": rs.law, "building": rs.building, "records": list(rs.records), "scales": list(rs.scales),
            "samples": int(len(rs.draws)), "seed": rs.seed, "limits": rs.limits,
            "extrapolated_share": rs.extrapolated_share(),
            "summary": pooled.to_dict(orient="records"),
            "variance_split": split.to_dict(orient="records"),
            "exceedance": exc[exc["record"] == ALL].to_dict(orient="records"),
            "fragility": [{"demand": f.demand, "limit": f.limit, "theta": f.theta, "beta": f.beta,
                           "note": f.note} for f in frag],
            "notes": list(rs.notes), "out": str(out), "figures": figures,
        }
        if plan:
            if args.asce7 is not None:
                body["asce7_scaling"] = {"factors": dict(zip([p.name for p in suite.pairs],
                                                             map(float, suite.factors))),
                                         "governing_period_s": float(suite.governing_period),
                                         "min_ratio": float(suite.min_ratio)}
            body["bidirectional"] = {"design_answers": plan["answers"].to_dict(),
                                     "design_distribution": plan["distribution"].to_dict(orient="records")}
        print(json.dumps(body, indent=2, default=float))
        return 0
    print(f"{rs.law} on {rs.building or 'building'}: {len(rs.draws)} draws x {len(rs.records)} records x "
          f"{len(rs.scales)} scales = {len(rs.table)} analyses")
    show = pooled.merge(split[["demand", "scale", "share_params", "share_records"]], on=["demand", "scale"])
    with pd.option_context("display.width", 160, "display.max_columns", 20, "display.precision", 4):
        print(show.drop(columns=["record"]).to_string(index=False))
        print()
        print(exc[exc["record"] == ALL].drop(columns=["record"]).to_string(index=False))
    for f in frag:
        extra = f" ({f.note})" if f.note else ""
        print(f"fragility {f.demand} > {f.limit:g}: theta = {f.theta:.4g}, beta = {f.beta:.3f}{extra}")
    if plan:
        if args.asce7 is not None:
            print()
            print(suite.summary())
        ans = plan["answers"]
        with pd.option_context("display.width", 160, "display.max_columns", 20, "display.precision", 4):
            print()
            print(f"ASCE 7-22 Chapter 17 answers of the median posterior draw ({ans.rule} over "
                  f"{len(ans.pairs)} pairs; governing = the largest of the analyses):")
            print(ans.design().to_string())
            print()
            print("suite design values over the posterior draws:")
            print(plan["distribution"].to_string(index=False))
        for note in ans.notes:
            print(f"note: {note}", file=sys.stderr)
    share = rs.extrapolated_share()
    if share == share:
        print(f"runs beyond the calibrated isolator displacement: {100 * share:.1f} %")
    for note in rs.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"wrote {out}/responses.parquet, responses.csv, summary tables and {len(figures)} figures")
    return 0


def _bidirectional(args, out: Path, building, pairs, sets: dict, plt) -> dict:
    """The code's answers of a bidirectional run: tables and orbit plots (see EXAMPLE)."""
    draws = pd.concat([suite_design(r).assign(bound=b) for b, r in sets.items()], ignore_index=True)
    draws = draws[["bound", *[c for c in draws.columns if c != "bound"]]]
    draws.to_csv(out / "design_draws.csv", index=False)
    dist = pd.concat([design_distribution(r).assign(bound=b) for b, r in sets.items()], ignore_index=True)
    dist = dist[["bound", *[c for c in dist.columns if c != "bound"]]]
    dist.to_csv(out / "design_distribution.csv", index=False)
    # the answers and orbits of one posterior draw: the one whose nominal suite design displacement
    # is the median over the draws (a real draw, so its parameters satisfy every law constraint)
    rs = sets["nominal"]
    nominal = draws[(draws["bound"] == "nominal") & (draws["scale"] == rs.scales[0])]
    x = nominal["plan_disp_max_m"].to_numpy(float)
    if not np.isfinite(x).any():
        raise RuntimeError("no posterior draw converged on every pair: no design answers to report")
    sample = int(nominal["sample"].to_numpy()[np.nanargmin(np.abs(x - np.nanmedian(x)))])
    median = rs.draws.loc[sample].to_dict()
    answers = plan_design_answers(building, pairs, params=median, bounds=args.bounds, torsion=args.torsion,
                                  scale=rs.scales[0])
    answers.table().to_csv(out / "design_answers.csv", index=False)
    figures = []
    radius = answers.design_displacement
    for pair in answers.pairs:
        others = {f"{b} bound" if b != "nominal" else b: answers.orbits[(b, pair)]
                  for b in ("lower", "upper") if (b, pair) in answers.orbits}
        fig = plot_orbit(answers.orbits[("nominal", pair)], radius, others=others,
                         title=f"{pair}: isolator orbit, median posterior draw")
        name = f"orbit_{''.join(c if c.isalnum() or c in '-_' else '_' for c in pair)}.png"
        fig.savefig(out / name, dpi=120)
        plt.close(fig)
        figures.append(name)
    return {"answers": answers, "distribution": dist, "figures": figures}
