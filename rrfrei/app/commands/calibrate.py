"""``rrfrei calibrate``: Bayesian calibration of one law on a shear test, with held-out checks."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import (
    add_command,
    add_json,
    add_no_progress,
    add_time_budget,
    min_int,
    nonneg_int,
    paragraph,
)
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.calibration import (
    PATH_TOLERANCE,
    BoundWarning,
    ConvergenceWarning,
    advice,
    calibrate,
    plots,
    predict,
    run_stats,
)
from rrfrei.calibration.likelihood import DENSE_POINTS, HALF_CYCLE_POINTS, LIKELIHOOD_POINTS
from rrfrei.calibration.results import arviz_numpy
from rrfrei.calibration.sampler import CONVERGENCE_RULE, MAX_STEPS
from rrfrei.io import DISP_UNITS, FORCE_UNITS, bundled_tests, load_test, read_test
from rrfrei.laws import get
from rrfrei.notes import Note, as_dicts, label, ordered

EXAMPLE = """\
Example:
  rrfrei calibrate protocol1.csv --law bouc_wen --holdout protocol2.csv protocol3.csv --out cal
  rrfrei calibrate protocol1 --law plasticity --steps 2000 --out cal --json   # bundled test
  rrfrei calibrate SPC1.csv --law bouc_wen --disp-col 'Lead Actuator Displacment:mm' \\
      --force-col 'Lead Actuator Force:kN' --fix alpha2=0 --fix mu=2 --out spc1
Writes DIR/posterior.nc, DIR/summary.csv, DIR/cycles.csv, DIR/run.json (why sampling stopped,
steps, tau, R-hat, ESS) and figures (pair plot, predictive loop with band, energy per cycle,
cumulative energy, held-out predictions), and keeps the chain in DIR/chain.h5: a run stopped by
--time-budget (exit 0, with a warning) continues where it stopped when the same command is run
again.  Dense records (more than 5,000 samples): the likelihood uses a regular subsample
(--likelihood-points) and the law runs along a decimated path (--half-cycle-points), whose force
error at the optimum is checked against the whole record; both are stated in run.json.
"""

DEFAULT_TIME_BUDGET = 300.0
"""Default wall-clock budget [s] of the optimum search and the sampling of the command."""
CHECKPOINT_NAME = "chain.h5"
"""Default checkpoint file in the output folder."""


def _fix(text: str) -> tuple[str, float]:
    """argparse type of ``--fix``: ``NAME=VALUE`` (a law parameter held at VALUE, SI units)."""
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = None
    if not sep or not name.strip() or number is None or number != number:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (e.g. alpha2=0), got {text!r}")
    return name.strip(), number


def _likelihood_points(text: str) -> int | str:
    """argparse type of ``--likelihood-points``: ``auto``, ``all`` or an integer >= 2."""
    t = text.strip().lower()
    if t in ("auto", "all"):
        return t
    try:
        value = int(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto', 'all' or an integer >= 2, got {text!r}") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected 'auto', 'all' or an integer >= 2, got {text!r}")
    return value


def add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--noise", choices=("iid", "ar1"), default="iid",
                   help="residual model: independent Gaussian or AR(1) (default iid)")
    p.add_argument("--seed", type=nonneg_int, default=0, metavar="N", help="seed (default 0)")
    p.add_argument("--walkers", type=min_int(2), default=None, metavar="N",
                   help="ensemble size (default max(32, 4 x parameters))")
    p.add_argument("--steps", type=min_int(2), default=None, metavar="N",
                   help=f"MCMC steps (default: until the convergence rule holds: {CONVERGENCE_RULE})")
    p.add_argument("--priors", default=None, metavar="TOML",
                   help="prior overrides ([priors.NAME] kind, a, b)")
    add_json(p, "print the results as JSON on stdout")
    add_no_progress(p)


HELP = HELPS["calibrate"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Bayesian calibration of an isolator law on a cyclic shear test CSV (columns time_s, disp_mm,
force_kN, or any unit-suffixed names; bundled tests by name: protocol1..protocol4, SYNTHETIC).
Starts from a CMA-ES optimum and samples with emcee; checks the fit and held-out tests.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "calibrate", help=HELP, description=DESCRIPTION,
                    epilog=EXAMPLE + "\n" + GEOMETRY_HELP + "\n")
    p.add_argument("test", metavar="TEST.csv", help="test file (or a bundled test name)")
    p.add_argument("--law", required=True, help="law name (e.g. bouc_wen, or an augmented law bouc_wen+rate)")
    p.add_argument("--holdout", nargs="*", default=[], metavar="CSV", help="held-out test files to predict")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_column_args(p)
    p.add_argument("--checkpoint", default=None, metavar="H5|none",
                   help=f"HDF5 chain checkpoint, resumed if present (default DIR/{CHECKPOINT_NAME}, "
                        "restarted if it belongs to another run; none: no checkpoint)")
    p.add_argument("--max-steps", type=min_int(2), default=MAX_STEPS, metavar="N",
                   help=f"step cap of a run to convergence (default {MAX_STEPS})")
    add_time_budget(p, DEFAULT_TIME_BUDGET,
                    help=f"wall-clock limit of the optimum search and sampling (default "
                         f"{DEFAULT_TIME_BUDGET:.0f}); when reached, the chain so far is kept and "
                         "written, and the same command continues it")
    p.add_argument("--likelihood-points", type=_likelihood_points, default="auto", metavar="N|auto|all",
                   help=f"samples the likelihood uses (the law always runs along the whole record): "
                        f"auto = all up to {DENSE_POINTS}, else every k-th sample, at most "
                        f"{LIKELIHOOD_POINTS} (default auto)")
    p.add_argument("--half-cycle-points", type=_likelihood_points, default="auto", metavar="N|auto|all",
                   help=f"decimation of the law's input path: auto = on a record of more than "
                        f"{DENSE_POINTS} samples the law runs along every k-th sample of each "
                        f"half-cycle, k such that each keeps >= {HALF_CYCLE_POINTS} samples (plus the "
                        "reversals and the likelihood's samples), N doubled until the force along it "
                        f"is within {PATH_TOLERANCE:g} sigma (RMS) of the whole record's at the "
                        "optimum; all = every sample (no decimation); N = >= N samples per "
                        "half-cycle. Stated in run.json (path). Default auto")
    p.add_argument("--fix", type=_fix, action="append", default=[], metavar="NAME=VALUE",
                   help="hold a law parameter fixed (repeatable), e.g. --fix alpha2=0 --fix mu=2 "
                        "to drop bouc_wen's hardening term when the test shows none")
    p.add_argument("--quiet", action="store_true", help="no progress bars (same as --no-progress)")
    add_common(p)
    p.set_defaults(func=run)


GEOMETRY_HELP = (
    "bearing geometry (d2, tr, n, ... in m) for elastomeric_x comes from a sidecar TOML [geometry] "
    "table next to the test: <file>.toml (e.g. test.csv.toml), <stem>.toml (test.toml) or "
    "geometry.toml, searched in that order")


def add_column_args(p: argparse.ArgumentParser) -> None:
    """``--disp-col``, ``--force-col``, ``--time-col`` (NAME or NAME:UNIT) for raw lab files."""
    p.add_argument("--disp-col", default=None, metavar="NAME[:UNIT]",
                   help="displacement column and, if its name carries none, its unit (m, cm, mm, in); "
                        "e.g. --disp-col 'Lead Actuator Displacment:mm'")
    p.add_argument("--force-col", default=None, metavar="NAME[:UNIT]",
                   help="force column and unit (N, kN, MN, lbf, kip), e.g. --force-col 'Actuator:kN'")
    p.add_argument("--time-col", default=None, metavar="NAME",
                   help="time column (default: a time_* column; none: the sample index is used)")


def _column(text: str | None, units: dict, what: str) -> tuple[str | None, str | None]:
    if text is None:
        return None, None
    name, sep, unit = text.rpartition(":")
    if sep and unit.strip().lower() in units:
        return name, unit.strip()
    if sep and unit.strip():
        raise ValueError(f"--{what}-col {text!r}: unit {unit.strip()!r} is not one of "
                         f"{', '.join(units)}")
    return text, None


def load(path: str, args: argparse.Namespace | None = None):
    """A test from a path (columns named by ``args``' column options), or a bundled test by name."""
    if not Path(path).exists() and path.removesuffix(".csv") in bundled_tests():
        return load_test(path)
    if args is None or not any(getattr(args, k, None) for k in ("disp_col", "force_col", "time_col")):
        return read_test(path)
    disp_col, disp_unit = _column(args.disp_col, DISP_UNITS, "disp")
    force_col, force_unit = _column(args.force_col, FORCE_UNITS, "force")
    return read_test(path, disp_col=disp_col, disp_unit=disp_unit, force_col=force_col,
                     force_unit=force_unit, time_col=args.time_col)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")

    spec = get(args.law)  # resolved once: an unknown law is a user error before anything heavy
    test = load(args.test, args)
    holdouts = [load(h, args) for h in args.holdout]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    default_ck = args.checkpoint is None
    if default_ck:
        checkpoint = out / CHECKPOINT_NAME
    elif args.checkpoint.strip().lower() == "none":
        checkpoint = None
    else:
        checkpoint = Path(args.checkpoint)
    budget = TimeBudget(args.time_budget, what="calibrate", option="--time-budget")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        warnings.simplefilter("always", BoundWarning)
        try:
            cal = calibrate(test, spec, noise=args.noise, seed=args.seed, walkers=args.walkers,
                            steps=args.steps, priors=args.priors, checkpoint=checkpoint,
                            progress=not (args.no_progress or args.quiet or args.json),
                            max_steps=args.max_steps, time_budget=budget,
                            likelihood_points=args.likelihood_points, fixed=dict(args.fix) or None,
                            half_cycle_points=args.half_cycle_points,
                            checkpoint_mismatch="restart" if default_ck else "error")
        except BudgetExceeded as exc:
            print(f"rrfrei {exc}", file=sys.stderr)  # "rrfrei calibrate: time budget of ..."
            return 2
    notes: list[Note] = []  # printed on stderr, critical first, once the fit is judged
    for w in caught:
        if issubclass(w.category, BoundWarning):
            notes.append(Note(str(w.message), "warning"))
        elif not issubclass(w.category, ConvergenceWarning) and "time budget" not in str(w.message):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    d = cal.diagnostics
    if cal.stopped_by == "time_budget":
        where = f"the same command (checkpoint {checkpoint})" if checkpoint is not None else (
            "with --checkpoint H5")
        state = "converged" if cal.converged else "NOT converged"
        notes.append(Note(
            f"time budget of {budget.seconds:.0f} s reached after {d['seconds']:.0f} s: kept "
            f"{d['steps']} steps x {d['walkers']} walkers ({state}; {run_stats(d)}); run {where} "
            "again to continue, or raise --time-budget (none: no limit)",
            "warning" if cal.converged else "critical"))
    elif not cal.converged:
        notes.append(Note(f"NOT converged: {advice(d, cli=True)}", "critical"))
    pred = predict(cal, test, seed=args.seed)
    held = [(path, h, predict(cal, h, seed=args.seed)) for path, h in zip(args.holdout, holdouts)]
    notes += fit_notes(pred, "calibration test") + [
        n for _, h, hp in held for n in fit_notes(hp, "held-out test")]
    # the figures (pure matplotlib, ~2 s) are drawn by a forked process on the other core while
    # this one writes the posterior and the tables and computes LOO
    with _in_parallel(_write_figures, cal, pred, held, out, args.seed):
        cal.to_netcdf(out / "posterior.nc")
        cal.summary.to_csv(out / "summary.csv")
        pred.cycles.to_csv(out / "cycles.csv", index=False)
        pred.asce.to_csv(out / "asce_7_22.csv", index=False)
        with warnings.catch_warnings(), arviz_numpy() as az:
            warnings.simplefilter("ignore")
            loo = az.loo(cal.idata, var_name="force")
        hold = {}
        for path, h, hp in held:
            hold[path] = {"nrmse": hp.nrmse, "coverage": hp.coverage,
                          "systematic": hp.adequacy.systematic, "adequacy": hp.adequacy.level,
                          "extrapolation": [e.as_dict() for e in hp.extrapolation]}
            hp.cycles.assign(test=h.name).to_csv(out / f"holdout_{h.name}_cycles.csv", index=False)
    s = cal.summary
    result = {
        "law": cal.law,
        "map": {k: float(v) for k, v in cal.map.items()},
        "mean": {k: float(v) for k, v in s["mean"].items()},
        "ci95": {k: [float(s.loc[k, "2.5%"]), float(s.loc[k, "97.5%"])] for k in s.index},
        "sigma": float(cal.sigma),
        "elpd_loo": float(loo.elpd_loo),
        "nrmse": pred.nrmse,
        "coverage": pred.coverage,
        "converged": bool(cal.converged),
        "holdout": hold,
        "adequacy": pred.adequacy.as_dict(),
        "at_bounds": d.get("at_bounds", []),
        "notes": as_dicts(notes),
    }
    (out / "result.json").write_text(json.dumps(result, indent=2))
    run_info = {  # how the run went (result.json and --json keep their documented keys)
        "stopped_by": cal.stopped_by, "converged": bool(cal.converged), "steps": int(d["steps"]),
        "walkers": int(d["walkers"]), "max_steps": int(d["max_steps"]), "time_budget_s": d["time_budget"],
        "seconds": float(d["seconds"]), "tau_max": max(d["tau"].values()), "rhat_max": float(d["rhat_max"]),
        "ess_min": float(d["ess_min"]), "ess_tail_min": float(d.get("ess_tail_min", float("nan"))),
        "rule": CONVERGENCE_RULE, "at_bounds": d.get("at_bounds", []),
        "likelihood_points": int(d["likelihood_points"]),
        "points": int(d["points"]), "stored_draws": int(d["stored_draws"]),
        "sampling_coordinates": d.get("sampling_coordinates", "law parameters"),
        "restarted_walkers": int(d.get("restarted_walkers", 0)),
        "path": d.get("path"),
        "checkpoint": None if checkpoint is None else str(checkpoint),
    }
    (out / "run.json").write_text(json.dumps(run_info, indent=2))
    for n in ordered(notes):
        print(f"rrfrei calibrate: {label(n)}", file=sys.stderr)
    if args.json:
        print(json.dumps(result))
    else:
        print(s.to_string(float_format=lambda x: f"{x:.4g}"))
        print(run_line(d))
        print(f"fit: {pred.adequacy.sentence}; converged: {cal.converged}; wrote {out}")
    return 0


def fit_notes(pred, what: str) -> list[Note]:
    """The notes a prediction earns: its adequacy when not adequate (critical when inadequate),
    and posterior draws that failed along the test (critical when more than half did)."""
    out = []
    a = pred.adequacy
    if a is not None and a.level != "adequate":
        out.append(Note(f"{pred.law} on {what} {pred.test.name!r}: {a.sentence}",
                        "critical" if a.level == "inadequate" else "warning"))
    total = pred.n_draws + pred.failed_draws
    if pred.failed_draws:
        out.append(Note(f"{pred.failed_draws} of {total} posterior draws of {pred.law} failed on "
                        f"{what} {pred.test.name!r}: its band comes from {pred.n_draws} draw"
                        f"{'s' if pred.n_draws != 1 else ''}",
                        "critical" if 2 * pred.n_draws < total else "warning"))
    return out


def _write_figures(cal, pred, held, out: Path, seed: int) -> None:
    """DIR/pair.png, loop.png, energy_per_cycle.png, cumulative_energy.png (and holdout.png)."""
    import matplotlib.pyplot as plt  # deferred: start-up speed (the CLI's --help needs none)

    figs = {
        "pair": plots.pair_plot(cal, seed=seed),
        "loop": plots.loop_plot(pred),
        "energy_per_cycle": plots.energy_plot(pred),
        "cumulative_energy": plots.cumulative_plot(pred),
    }
    if held:
        fig, axes = plt.subplots(1, len(held), figsize=(4.2 * len(held), 3.6), squeeze=False,
                                 constrained_layout=True)
        for ax, (_, _, hp) in zip(axes[0], held):
            plots.loop_plot(hp, ax=ax)
        figs["holdout"] = fig
    for name, fig in figs.items():
        fig.savefig(out / f"{name}.png", dpi=110)
        plt.close(fig)


class _in_parallel:
    """Run ``func(*args)`` in a forked process during the ``with`` block and wait for it at the
    end (a failure there is a RuntimeError); where processes cannot be forked, or the block
    raised, it runs in this process instead."""

    def __init__(self, func, *args) -> None:
        import multiprocessing

        self.func, self.args, self.proc = func, args, None
        if "fork" in multiprocessing.get_all_start_methods():
            self.proc = multiprocessing.get_context("fork").Process(target=func, args=args, daemon=True)

    def __enter__(self):
        if self.proc is not None:
            self.proc.start()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self.proc is None:
            if exc_type is None:
                self.func(*self.args)
            return
        self.proc.join()
        if exc_type is None and self.proc.exitcode != 0:
            raise RuntimeError(f"{self.func.__name__} failed in its worker process "
                               f"(exit code {self.proc.exitcode}); see the message above")


def run_line(d: dict) -> str:
    """The summary line of the run: why it stopped, steps of the cap, time, likelihood points."""
    why = {"converged": "converged", "steps": "fixed --steps done", "max_steps": "step cap reached",
           "time_budget": "time budget reached"}.get(d.get("stopped_by"), str(d.get("stopped_by")))
    budget = "none" if d.get("time_budget") is None else f"{d['time_budget']:.0f} s"
    lik = (f"likelihood on {d['likelihood_points']} of {d['points']} samples (every "
           f"{d['likelihood_stride']}th)" if d["likelihood_points"] < d["points"]
           else f"likelihood on all {d['points']} samples")
    path = d.get("path") or {}
    law_path = (f"; law run along {path['samples']} of {d['points']} samples (>= "
                f"{path['half_cycle_points']} per half-cycle; force within {path['error_rms_kN']:.3g} kN "
                f"RMS = {path['error_rms_sigma']:.3g} sigma of the whole record's at the optimum; "
                "--half-cycle-points all: no decimation)" if path.get("decimated") else "")
    return (f"stopped: {why} after {d['steps']} steps x {d['walkers']} walkers (--max-steps "
            f"{d['max_steps']}, --time-budget {budget}, {d['seconds']:.0f} s; {run_stats(d)}); "
            f"{lik}{law_path}; {d['stored_draws']} draws stored")
