"""Command line: ``python -m rubber fit|predict|cases|cards|gap`` (user errors: one line on stderr,
exit 2; numerical failures (``rrfrei.errors.NUMERICAL_ERRORS``): one line naming what failed, exit 1)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rrfrei._text import plain_numbers
from rrfrei.budget import seconds_arg
from rrfrei.errors import NUMERICAL_ERRORS, is_numerical
from rrfrei.extrapolation import by_source

DEFAULT_FIT_BUDGET = 1200.0
"""Default wall-clock budget of ``python -m rubber fit`` [s] (a 12-test fit takes 85-99 s)."""

EXAMPLES = {
    "fit": "example: python -m rubber fit p1.csv p2.csv --out fitdir --bounds auto --json",
    "predict": "example: python -m rubber predict --params fitdir/params.json p1.csv --json",
    "cases": "example: python -m rubber cases p1.csv p2.csv --out study",
    "cards": "example: python -m rubber cards --params fitdir/params.json --out cards",
    "gap": "example: python -m rubber gap p1.csv --holdout p2.csv --out gapdir --bounds auto --json",
}


class UserError(Exception):
    pass


def _add_search(p: argparse.ArgumentParser, max_evals: int = 6000,
                max_evals_help: str = "CMA-ES evaluations of the objective per run (default 6000)") -> None:
    """The CMA-ES options of ``fit``, ``cases`` and ``gap``: ``--seed``, ``--restarts``, ``--max-evals``."""
    p.add_argument("--seed", type=int, default=0, help="seed of the CMA-ES starts (default 0)")
    p.add_argument("--restarts", type=int, default=2,
                   help="CMA-ES restarts from new random starts (default 2)")
    p.add_argument("--max-evals", type=int, default=max_evals, metavar="N", help=max_evals_help)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m rubber", description="PRF (Yeoh + Bergstrom-Boyce) model: "
                                "fit, predict, cross-protocol study, material cards, gap diagnosis (MPa, s).",
                                epilog="\n".join(EXAMPLES.values()),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fit", help="fit tests (CSV/.mat) with CMA-ES", epilog=EXAMPLES["fit"])
    f.add_argument("tests", nargs="+", help="tests: CSV (time_s, stretch, stress_MPa) or .mat files")
    f.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: params.json (the fit), fit.png (data and model)")
    f.add_argument("--bounds", default=None, help="'auto' or a JSON file {name: [lo, hi]}")
    _add_search(f)
    f.add_argument("--json", action="store_true", help="print the fit as JSON on stdout")
    f.add_argument("--time-budget", type=seconds_arg, default=DEFAULT_FIT_BUDGET, metavar="SECONDS|none",
                   help=f"wall-clock limit of the search [s] (default {DEFAULT_FIT_BUDGET:.0f}; 'none': no "
                        "limit); when reached, the best fit so far is written, with a warning")
    f.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    q = sub.add_parser("predict", help="error f of a parameter set on tests", epilog=EXAMPLES["predict"])
    q.add_argument("--params", required=True, metavar="JSON", help="params.json of a fit")
    q.add_argument("tests", nargs="+", help="tests: CSV (time_s, stretch, stress_MPa) or .mat files")
    q.add_argument("--json", action="store_true", help="print the errors as JSON on stdout")
    c = sub.add_parser("cases", help="cross-prediction study (cases A, B, C)", epilog=EXAMPLES["cases"])
    c.add_argument("p1", help="tests of protocol 1 (a CSV/.mat file)")
    c.add_argument("p2", help="tests of protocol 2 (a CSV/.mat file)")
    c.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    _add_search(c)
    k = sub.add_parser("cards", help="Marc/Abaqus cards, curves, equivalent linear", epilog=EXAMPLES["cards"])
    k.add_argument("--params", required=True, metavar="JSON", help="params.json of a fit")
    k.add_argument("--out", required=True, metavar="DIR", help="output folder for the cards and curves")
    g = sub.add_parser("gap", help="which effect (Mullins, permanent set) closes the gap on held-out tests",
                       description="Fit the PRF model to the calibration test, refit it with each effect, "
                       "name an effect only if it lowers BIC by > 10 and lowers the held-out NRMSE.",
                       epilog=EXAMPLES["gap"])
    g.add_argument("test", help="calibration test (CSV/.mat)")
    g.add_argument("--holdout", nargs="+", required=True, help="held-out tests (other protocols)")
    g.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    g.add_argument("--effects", nargs="+", default=None, help="effects to try (default all)")
    g.add_argument("--bounds", default=None, help="'auto' or a JSON file {name: [lo, hi]}")
    g.add_argument("--start", default=None, help="params.json of a previous fit to start from")
    _add_search(g, max_evals=3000, max_evals_help="CMA-ES evaluations per run (default 3000; 0: least "
                                                  "squares from --start only)")
    g.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    return p


def _read_params(path: str):
    from .prf import PRFParams

    try:
        d = json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: not a UTF-8 JSON text file (byte {exc.start} is not UTF-8 text: a "
                        "binary file, or another encoding); expected the params.json of a fit") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: cannot read parameters ({exc})") from None
    return PRFParams.from_dict(d.get("params", d))


def _figure(params, tests, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .prf import simulate

    fig, axes = plt.subplots(1, len(tests), figsize=(5 * len(tests), 4), squeeze=False)
    for ax, t in zip(axes[0], tests):
        ax.plot(t.stretch, t.stress, "k.", ms=2, label="data")
        ax.plot(t.stretch, simulate(params, t.time, t.stretch).nominal, "r-", label="model")
        ax.set(xlabel="stretch", ylabel="nominal stress (MPa)", title=t.name)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _run(a) -> int:
    from .fit import fit, objective
    from .io import read_test

    if a.cmd == "fit":
        tests = [read_test(x) for x in a.tests]
        bounds = _read_bounds(a.bounds)
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        r = fit(tests, bounds=bounds, seed=a.seed, restarts=a.restarts, max_evals=a.max_evals,
                time_budget=a.time_budget, progress=not a.no_progress)
        if r.stopped_by == "time_budget":
            print(f"warning: time budget of {a.time_budget:.0f} s reached after {r.evaluations} evaluations: "
                  "the best fit so far is written; raise it with --time-budget (none: no limit)",
                  file=sys.stderr)
        # the fit is written before anything that could still fail (the figure); the uncertainty step
        # inside fit() never raises: its failures are NaN rel_sigma with reasons in "uncertainty_notes"
        doc = {"params": r.params.as_dict(), "f": r.f, "f_total": r.f_total}
        rel = {n: (None if v != v else v) for n, v in r.rel_sigma.items()}  # NaN -> null (strict JSON)
        ext = _extrapolation(r.params, tests, a.tests)  # fitted tests near a fitted chain's lock
        (out / "params.json").write_text(json.dumps({
            **doc, "stretch_range": list(r.stretch_range), "combinations": r.combinations,
            "ref_rate": r.ref_rate,
            "flow_parameterisation": list(r.flow_thresholds) or "C1", "rel_sigma": rel,
            "uncertainty_notes": list(r.uncertainty_notes), "evaluations": r.evaluations,
            "stopped_by": r.stopped_by}, indent=2))
        for note in r.uncertainty_notes:
            print(f"warning: {note}", file=sys.stderr)
        if r.f_total > len(tests):  # each test's f > 1 on average: worse than predicting zero stress
            print(f"warning: f_total = {r.f_total:.3g} is worse than a zero prediction ({len(tests)}); "
                  "the box does not fit these data (the default is the study's polyurethane box, "
                  "C10 >= 1 MPa): try --bounds auto", file=sys.stderr)
        _figure(r.params, tests, out / "fit.png")
        print(json.dumps({**doc, "stretch_range": list(r.stretch_range), "extrapolation": ext}) if a.json
              else r.summary())
    elif a.cmd == "predict":
        p = _read_params(a.params)
        fitted = _read_stretch_range(a.params)
        tests = [read_test(x) for x in a.tests]
        f = {t.name: float(v) for t, v in zip(tests, objective(p, tests, rtol=1e-8))}
        ext = _extrapolation(p, tests, a.tests, fitted)
        if fitted is None:
            print(f"warning: {a.params} has no stretch_range (a fit by an older version, or written by "
                  "hand): only the chains' locking stretches are checked", file=sys.stderr)
        print(json.dumps({"f": f, "extrapolation": ext}) if a.json
              else "\n".join(f"{k}: f = {v:.4e}" for k, v in f.items()))
    elif a.cmd == "cases":
        from .study import cases

        r = cases(read_test(a.p1), read_test(a.p2), seed=a.seed, restarts=a.restarts, max_evals=a.max_evals)
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "table.txt").write_text(r.table() + "\n")
        (out / "cases.json").write_text(json.dumps({c: {"params": x.params.as_dict(), "f": r.f[c]}
                                                    for c, x in r.fits.items()}, indent=2))
        _cases_figure(r, [read_test(a.p1), read_test(a.p2)], out / "cases.png")
        print(r.table())
    elif a.cmd == "cards":
        from .cards import write_cards

        write_cards(_read_params(a.params), a.out)
        print(f"wrote {a.out}/material.json, abaqus.inp, curves.csv, relaxation_creep.csv")
    elif a.cmd == "gap":
        _gap(a)
    return 0


def _read_stretch_range(path: str) -> tuple[float, float] | None:
    """The fitted stretch range ``[min, max]`` of a ``params.json`` written by ``fit`` (None if absent)."""
    d = json.loads(Path(path).read_text())
    r = d.get("stretch_range") if isinstance(d, dict) else None
    if r is None:
        return None
    try:
        lo, hi = (float(x) for x in r)
    except (TypeError, ValueError):
        raise UserError(f"{path}: stretch_range = {r!r}: expected [min, max]") from None
    return lo, hi


def _extrapolation(params, tests, files, fitted=None) -> dict:
    """Warn on stderr for each test (named by its file) beyond the fitted stretch range or within
    10 % of a chain's locking stretch; return the records per file for ``--json``."""
    from .extrapolation import check

    found = check(params, tests, sources=list(files), fitted_range=fitted)
    for item in found:
        print(f"warning: {item.message}", file=sys.stderr)
    return {str(x): by_source(found).get(str(x), []) for x in files}


def _read_bounds(bounds):
    if bounds in (None, "auto"):
        return bounds
    try:
        return json.loads(Path(bounds).read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise UserError(f"--bounds {bounds}: not a UTF-8 JSON text file (byte {exc.start} is not UTF-8 "
                        "text); expected 'auto' or a JSON file {name: [lo, hi]}") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"--bounds {bounds}: expected 'auto' or a JSON file ({exc})") from None


def _gap(a) -> None:
    from .gap import RubberModel, rank_effects
    from .io import read_test

    cal = read_test(a.test)
    hos = [read_test(x) for x in a.holdout]
    start = _read_params(a.start) if a.start else None
    model = RubberModel(bounds=_read_bounds(a.bounds), start=start, restarts=a.restarts,
                        max_evals=a.max_evals)
    rep = rank_effects(model, cal, hos, effects=a.effects, seed=a.seed)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "gap.md").write_text(rep.table() + "\n")
    _gap_figure(rep, [cal, *hos], out / "gap.png")
    print(json.dumps(rep.as_dict()) if a.json else rep.table())


def _gap_figure(rep, tests, path: Path) -> None:
    """Baseline vs the best augmented fit (lowest held-out NRMSE) on calibration and held-out tests."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    base = rep.fits["prf"]
    best = rep.rows[0] if rep.rows else None
    fig, axes = plt.subplots(1, len(tests), figsize=(5 * len(tests), 4), squeeze=False)
    for i, (ax, t) in enumerate(zip(axes[0], tests)):
        ax.plot(t.stretch, t.stress, "k.", ms=2, label="data")
        ax.plot(t.stretch, base.stress(t), "b-", lw=1, label="prf (baseline)")
        if best is not None:
            tag = "" if best.accepted else " (not accepted)"
            ax.plot(t.stretch, rep.fits[best.model].stress(t), "r-", lw=1, label=best.model + tag)
        ax.set(xlabel="stretch [-]", ylabel="nominal stress [MPa]",
               title=("calibration: " if i == 0 else "held out: ") + t.name)
        ax.legend()
    fig.suptitle(f"diagnosis: {rep.diagnosis}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _cases_figure(r, tests, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .prf import simulate

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, t in zip(axes, tests):
        ax.plot(t.time, t.stress, "k.", ms=2, label="data")
        for c, x in r.fits.items():
            ax.plot(t.time, simulate(x.params, t.time, t.stretch).nominal, label=f"case {c}")
        ax.set(xlabel="time (s)", ylabel="nominal stress (MPa)", title=t.name)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    try:
        return _run(a)
    except (UserError, ValueError, OSError, *NUMERICAL_ERRORS) as exc:
        if is_numerical(exc):  # NumericalFailure subclasses ValueError: test it first
            print(plain_numbers(f"error: numerical failure ({type(exc).__name__}): {exc}").splitlines()[0],
                  file=sys.stderr)
            return 1
        print(plain_numbers(f"error: {exc}").splitlines()[0], file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
