"""Markdown report and figures of a gap diagnosis (:class:`rrfrei.gap.GapReport`).

Figures (PNG, matplotlib Figures not managed by pyplot): ``gap_map.png`` (residual vs displacement
coloured by cycle, and the segment table as a heat map), ``loops.png`` (baseline vs augmented
hysteresis loops on the calibration and each held-out test), ``ranking.png`` (elpd gain +- 2 se
and held-out shrink per effect).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rrfrei.gap.design import PropertyModification, design_gap, plot_design_gap, property_modification
from rrfrei.gap.diagnose import GapReport
from rrfrei.jsonable import number as _num
from rrfrei.notes import label as note_label
from rrfrei.notes import ordered

__all__ = ["write_report", "figures", "verdict_text", "COVERAGE_NOTE", "DesignSummary", "design_summary"]


def _fig(w: float, h: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(w, h), dpi=110, layout="constrained")


def figures(rep: GapReport) -> dict:
    """{file name: Figure} of the report."""
    from rrfrei.gap.residuals import cycle_levels
    from rrfrei.gap.segment_map import draw_segment_map

    out = {}
    test = rep.calibration_data
    base = rep.fits[rep.law]
    pr = base.predict(test)
    r = np.asarray(test.force) - pr.mean
    seg = cycle_levels(test.disp)
    fig = _fig(11, 4.2)
    ax1, ax2 = fig.subplots(1, 2, width_ratios=[1, 1.2])
    sc = ax1.scatter(1e3 * np.asarray(test.disp), r, c=seg.cycle, s=3, cmap="viridis")
    fig.colorbar(sc, ax=ax1, label="cycle")
    ax1.set(xlabel="displacement [mm]", ylabel="residual measured - baseline [kN]",
            title=f"{rep.law} on {test.name}: residuals")
    w = rep.where
    if len(w):
        draw_segment_map(fig, ax2, w)  # colour = concern on a fixed scale (pale calm, red alarming)
    out["gap_map.png"] = fig
    final = "+".join([rep.law, *rep.combination])
    tests = [test, *rep.holdout_data]
    fig = _fig(3.6 * len(tests), 3.4)
    axes = np.atleast_1d(fig.subplots(1, len(tests)))
    for ax, t in zip(axes, tests):
        u = 1e3 * np.asarray(t.disp)
        ax.plot(u, t.force, color="0.6", lw=0.8, label="test")
        ax.plot(u, base.predict(t).mean, color="tab:red", lw=0.8, label=rep.law)
        if final in rep.fits and final != rep.law:
            ax.plot(u, rep.fits[final].predict(t).mean, color="tab:blue", lw=0.8, label=final)
        ax.set(xlabel="displacement [mm]", title=t.name + (" (calibration)" if t is test else " (held out)"))
    axes[0].set_ylabel("force [kN]")
    axes[0].legend(fontsize=7)
    out["loops.png"] = fig
    fig = _fig(8, 3.2)
    ax1, ax2 = fig.subplots(1, 2)
    names = [s.label for s in rep.ranking]
    y = np.arange(len(names))
    ax1.errorbar([s.delta_elpd for s in rep.ranking], y, xerr=[2 * s.se for s in rep.ranking], fmt="o")
    ax1.axvline(0, color="k", lw=0.5)
    ax1.set_yticks(y, names)
    ax1.set(xlabel="delta elpd (leave-one-cycle-out) +- 2 se", xscale="symlog")
    ax2.barh(y, [s.shrink_holdout if math.isfinite(s.shrink_holdout) else s.shrink_calibration
                 for s in rep.ranking],
             color=["tab:blue" if s.effect in rep.combination else "0.7" for s in rep.ranking])
    ax2.set_yticks(y, names)
    ax2.set(xlabel="shrink of the systematic gap (held out)", xlim=(-0.5, 1.05))
    out["ranking.png"] = fig
    return out


COVERAGE_NOTE = ("Band coverage is not adequacy: a predictive band whose noise sd has absorbed the "
                 "misfit covers about 95 % of the points even when the model misses (a linear spring "
                 "missing a bearing by 78 % NRMSE shows about 95 %); read the systematic gap and the "
                 "verdict, not the coverage.")


def _named(rep: GapReport, s) -> str:
    if s.effect in rep.combination:
        return "yes" if s.effect == rep.combination[0] else "yes (combined)"
    if s.significant:
        if s.effect in rep.evidence.get("tied", []):
            return "no (tied)"
    if s.effect in {a["effect"] for a in rep.evidence.get("alternatives", [])}:
        return "no (alternative)"
    return "no (not combined)" if s.significant else "no"


def _pct(x) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def _f(x, d=1) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.{d}f}"


def _summary(rep: GapReport) -> str:
    """One paragraph: what was found, in words (read from the same numbers as the JSON)."""
    if not rep.ranking:
        if not rep.complete:
            return (f"No effect was evaluated ({len(rep.skipped)} skipped after a numerical failure, "
                    f"{len(rep.not_evaluated)} not evaluated for lack of time): the diagnosis is incomplete.")
        return "No effect could be judged."
    txt = (f"Baseline gap: {_pct(rep.baseline[0].gap)} on the calibration test (systematic part "
           f"{_pct(rep.baseline[0].systematic)})")
    if rep.baseline[1] is not None:
        txt += f", {_pct(rep.baseline[1].gap)} pooled over the held-out tests " \
               f"(systematic {_pct(rep.baseline[1].systematic)})"
    return txt + ". " + verdict_text(rep)


def _left(d: dict) -> str:
    return (f"systematic gap {_pct(d.get('systematic'))}, "
            f"MSE / sigma^2 - 1 = {_f(d.get('excess_over_noise'), 2)}, "
            f"lag-1 autocorrelation of the residuals {_f(d.get('lag1_autocorrelation'), 2)}")


def verdict_text(rep: GapReport) -> str:
    """The verdict and its evidence in words (from ``rep.evidence``, the JSON's ``evidence``)."""
    ev = rep.evidence or {}
    v = rep.verdict or rep.diagnosis
    if v == "incomplete":
        return ("Verdict `incomplete`: no evaluated effect passes the decision rule, but not every effect "
                "was evaluated (see the list above); an untried effect might close the gap.")
    if v == "none":
        return ("Verdict `none`: what is left is noise. " + " ".join(f"{r}." for r in ev.get("reasons", [])))
    if v == "unexplained":
        where = ", ".join(f"{w['axis']}: {w['segment']} ({_pct(w['error_share'])} of the squared error)"
                          for w in ev.get("where", []))
        size = ", ".join(f"{k} {_pct(x)}" for k, x in ev.get("size", {}).items())
        txt = (f"Verdict `unexplained`: a systematic gap (NRMSE of its systematic part: {size}) that no "
               f"catalogued effect closes. It lies mostly in {where or 'no single segment'}.")
        c = ev.get("closest")
        if c:
            txt += (f" Closest candidate: `{c['effect']}`, shrink of the {c['shrink_on']} systematic gap "
                    f"{_pct(c['shrink'])}; not named because {c['why']}.")
        if ev.get("tied"):
            txt += (f" Effects that pass the rule but cannot be told apart on this protocol: "
                    f"{', '.join(ev['tied'])} (give held-out tests).")
        return txt
    named = ev.get("named", {})
    steps = named.get("steps", [])
    txt = f"Verdict `{v}`: named by the decision rule ({steps[0]['why'] if steps else ''})"
    if len(rep.combination) > 1:
        labels = {s.effect: s.label for s in rep.steps}
        txt += f"; combination `{'+'.join(labels.get(e, e) for e in rep.combination)}`"
    alts = ev.get("alternatives", [])
    if alts:
        def vs(a):
            d = a.get("against_named") or {}
            lo, hi = d.get("ci", [None, None])
            return (f"; leaves {_pct(d.get('difference'))} [{_pct(lo)}, {_pct(hi)}] more of the baseline's "
                    "systematic gap than the named effect")

        txt += ("; the held-out data support as well "
                + ", ".join(f"`{a['label']}` (held-out shrink {_pct(a['shrink'])}{vs(a)})" for a in alts)
                + " (the held-out blocks do not show the named effect to predict better): read the verdict "
                  "as one of these")
    left = ev.get("left", {})
    if left:
        txt += (". What is left after it: " + "; ".join(f"{k}: {_left(d)}" for k, d in left.items())
                + (" (noise)" if ev.get("left_is_noise") else " (a systematic gap remains)"))
    return txt + "."


@dataclass(frozen=True)
class DesignSummary:
    """The gap in design quantities (issue 12 point 5), read from a :class:`GapReport`.

    Attributes
    ----------
    final_law : the law with the named effects (``base+effect...``), or the base law itself.
    tests : test name -> :func:`rrfrei.gap.design.design_gap` table (k_eff [kN/m], beta_eff
        [-], EDC [kN m], Qd [kN], F(DD) and F(DM) [kN]: measured, before = baseline, after = the
        law with the named effects; relative errors).
    lambdas_measured : ASCE 7-22 17.2.8.4 factors from the spread of the *measured* k_eff, Qd and
        EDC over the cycles at the calibration test's DD in every test (None: no such cycle).
    lambdas_model : the same from the *law with the named effects* along the same displacements:
        the factors that the effect implies (None without a named effect).
    notes : why a part is missing.
    """

    final_law: str
    tests: dict
    lambdas_measured: PropertyModification | None
    lambdas_model: PropertyModification | None
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        def table(df):
            return {q: {k: _num(df.loc[q, k]) for k in ("measured", "before", "after", "rel_err_before",
                                                       "rel_err_after")} | {"unit": df.loc[q, "unit"]}
                    for q in df.index}

        return {"final_law": self.final_law, "tests": {n: table(df) for n, df in self.tests.items()},
                "lambdas_measured": (None if self.lambdas_measured is None
                                     else self.lambdas_measured.to_dict()),
                "lambdas_model": None if self.lambdas_model is None else self.lambdas_model.to_dict(),
                "notes": list(self.notes)}


def design_summary(rep: GapReport) -> DesignSummary:
    """Design quantities of every test before and after the named effects, and the ASCE 7-22
    section 17.2.8.4 property modification factors measured and implied by the effect
    (:mod:`rrfrei.gap.design`; defaults: DD = the test's largest cycle amplitude, DM = 1.5 DD,
    lambda_ae = 1, lambda_spec = 0.85 / 1.15)."""
    tests = [rep.calibration_data, *rep.holdout_data]
    base = rep.fits[rep.law]
    final_name = "+".join([rep.law, *rep.combination])
    final = rep.fits.get(final_name) if rep.combination else None
    notes: list[str] = []
    tables = {}
    for t in tests:
        tables[t.name] = design_gap(t, None, base.predict(t).mean,
                                    None if final is None else final.predict(t).mean)
    pm_meas = pm_model = None
    try:
        pm_meas = property_modification(tests)
    except ValueError as exc:
        notes.append(f"measured property modification factors not formed: {exc}")
    if final is not None:
        try:
            pm_model = property_modification(tests, [final.predict(t).mean for t in tests])
        except ValueError as exc:
            notes.append(f"property modification factors of {final_name} not formed: {exc}")
    return DesignSummary(final_name, tables, pm_meas, pm_model, tuple(notes))


def _design_lines(ds: DesignSummary, building=None) -> list[str]:
    from rrfrei.gap.design import LABELS

    lines = ["## In design quantities", "",
             "Per test: k_eff, beta_eff (from EDC), Qd and the force at DD and DM (DD = the test's largest "
             "cycle amplitude, DM = 1.5 DD; F(DM) is n/a when the test does not reach DM: nothing is "
             f"extrapolated). *before* = the baseline law, *after* = `{ds.final_law}`.", "",
             "| test | quantity | measured | before | after | error before | error after |",
             "|---|---|---|---|---|---|---|"]
    for name, df in ds.tests.items():
        for q in df.index:
            r = df.loc[q]
            lines.append(f"| {name} | {LABELS.get(q, q)} [{r['unit']}] | {_g(r['measured'])} | "
                         f"{_g(r['before'])} | {_g(r['after'])} | {_pct(r['rel_err_before'])} | "
                         f"{_pct(r['rel_err_after'])} |")
    lines += ["", "![design gap](design_gap.png)", "",
              "### ASCE 7-22 section 17.2.8.4 property modification factors", "",
              "lambda_test from the spread over the cycles at the reference amplitude, over all tests "
              "(extreme cycle / pooled mean); lambda_max = (1 + 0.75 (lambda_ae,max - 1)) lambda_test,max "
              "lambda_spec,max and likewise for lambda_min, with lambda_ae = 1 (no aging data) and "
              "lambda_spec = 0.85 / 1.15 (defaults, `rrfrei.gap.design.property_modification`).", ""]
    for label, pm in (("measured", ds.lambdas_measured), (f"implied by `{ds.final_law}`", ds.lambdas_model)):
        if pm is None:
            continue
        lines += [f"{label.capitalize()} (reference amplitude {1e3 * pm.reference_amplitude:.1f} mm, "
                  f"{pm.n_cycles} cycles of {', '.join(pm.tests)}):", "",
                  "| property | nominal | lambda_test min / max | lambda_min / lambda_max "
                  "| lower bound | upper bound |",
                  "|---|---|---|---|---|---|"]
        for p, r in pm.table().iterrows():
            lines.append(f"| {p} [{r['unit']}] | {_g(r['nominal'])} | {r['lambda_test_min']:.3f} / "
                         f"{r['lambda_test_max']:.3f} | {r['lambda_min']:.3f} / {r['lambda_max']:.3f} | "
                         f"{_g(r['lower'])} | {_g(r['upper'])} |")
        lines += [""]
    lines += [f"> {n}" for n in ds.notes]
    if building is not None and len(building):
        med = building[building["record"] == "median"]
        lines += ["", "### Consequence for a building", "",
                  f"The bundled five-story building (`structures/building/buildings/five_story.toml`) on "
                  f"{building['record'].nunique() - 1} bundled records, its isolators at lower, nominal and "
                  "upper bound (force-like law parameters times lambda, `rrfrei.gap.design.bound_params`), "
                  "with and without the named effect. Medians over the records "
                  f"({building.attrs.get('seconds', float('nan')):.1f} s of analyses):", "",
                  "| law | effect | bound | lambda | isolator displacement [mm] | base shear [kN] |",
                  "|---|---|---|---|---|---|"]
        for r in med.itertuples():
            lines.append(f"| `{r.law}` | {r.effect} | {r.bound} | {r._4:.3f} | {1e3 * r.iso_disp_peak:.1f} | "
                         f"{r.base_shear_peak:.0f} |")
        lines += ["", "![building consequences](consequences.png)", ""]
    return lines


def _g(x) -> str:
    return "n/a" if x is None or not math.isfinite(float(x)) else f"{float(x):.4g}"


def write_report(rep: GapReport, out: str | Path, *, title: str | None = None,
                 design: DesignSummary | None = None, building=None) -> Path:
    """Write ``out/report.md`` and the figures; return the Markdown path.

    ``design``: the design-quantity section (:func:`design_summary`, computed when None);
    ``building``: the table of :func:`structures.propagation.consequences.building_consequences` (its figure
    saved by the caller as ``consequences.png``), or None for no building section.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name, fig in figures(rep).items():
        fig.savefig(out / name)
    if design is None:
        design = design_summary(rep)
    ref = rep.holdout_data[0].name if rep.holdout_data else rep.calibration_data.name
    plot_design_gap(design.tests[ref], title=f"{ref}: design quantities, {rep.law} vs "
                    f"{design.final_law}").savefig(out / "design_gap.png")
    b, f = rep.baseline, rep.final
    test = rep.calibration_data
    lines = [f"# {title or 'Sim-to-real gap diagnosis'}", "",
             f"Law `{rep.law}` calibrated on `{test.name}`; held out: "
             f"{', '.join(f'`{t.name}`' for t in rep.holdout_data) or 'none'}.", "",
             f"**Verdict: `{rep.verdict or rep.diagnosis}`**; effects named: "
             f"`{'+'.join(rep.combination) if rep.combination else 'none'}`.", ""]
    if not rep.complete:
        lines += ["**Incomplete diagnosis.** Effects not evaluated:", ""]
        lines += [f"* `{e}` skipped: {why}" for e, why in rep.skipped.items()]
        lines += [f"* `{e}` not evaluated: {why}" for e, why in rep.not_evaluated.items()]
        lines += [""]
    if rep.budget_message:
        lines += [f"Time budget: {rep.budget_message}", ""]
    for n in ordered(rep.notes):  # critical first: the notes that change how the result reads
        listed = n == rep.budget_message or (n.startswith("effect ") and " skipped: " in n)
        if not listed:  # (those are in the lists above)
            lines += [f"> **{note_label(n)}**" if n.severity == "critical" else f"> {note_label(n)}", ""]
    lines += [_summary(rep), ""]
    lines += [COVERAGE_NOTE, ""]
    lines += ["## How far it shrinks", "",
              "| model | data | gap (NRMSE) | systematic | energy/cycle error | band coverage |",
              "|---|---|---|---|---|---|"]
    rows = [(rep.law, b)] + [(s.law, (s.calibration, s.holdout)) for s in rep.ranking]
    for name, (mc, mh) in rows:
        for label, m in (("calibration", mc), ("held out", mh)):
            if m is not None:
                lines.append(f"| `{name}` | {label} | {_pct(m.gap)} | {_pct(m.systematic)} | "
                             f"{_pct(m.energy_error)} | {_pct(m.coverage)} |")
    lines += ["", f"Final (`{'+'.join([rep.law, *rep.combination])}`): calibration gap {_pct(f[0].gap)}"
              + (f", held-out gap {_pct(f[1].gap)}" if f[1] is not None else "") + ".", "",
              "## Which effect", "",
              "Decision rule (`rrfrei.gap.decision`): " + str(rep.evidence.get("rule", "")) + ". "
              "Blocks are half-cycles (time windows for tests without two full cycles); *gaining* counts "
              "the blocks where the effect lowers the leave-one-block-out loss (calibration) or the squared "
              "error (held out); p is the smaller of the sign and Wilcoxon signed-rank p-values.", "",
              "| effect | screen | delta elpd (LOCO) | calibration blocks gaining (p) "
              "| held-out blocks gaining (p) | shrink cal. | shrink held out [90 % CI on the one decided on] "
              "| passes the rule | named |",
              "|---|---|---|---|---|---|---|---|---|"]
    for s in rep.ranking:
        bc, bh, ci = s.blocks_calibration, s.blocks_holdout, s.shrink_ci
        lines.append(
            f"| {s.label} | {_f(s.screen, 2)} | {_f(s.delta_elpd)} +- {_f(s.se)} | "
            + (f"{bc.positive}/{bc.blocks} ({bc.p:.2g})" if bc is not None else "n/a") + " | "
            + (f"{bh.positive}/{bh.blocks} ({bh.p:.2g})" if bh is not None else "n/a") + " | "
            + f"{_pct(s.shrink_calibration)}"
            + (f" [{_pct(ci.lower)}, {_pct(ci.upper)}]" if ci is not None and bh is None else "")
            + f" | {_pct(s.shrink_holdout)}"
            + (f" [{_pct(ci.lower)}, {_pct(ci.upper)}]" if ci is not None and bh is not None else "") + " | "
            + f"{'yes' if s.significant else 'no'} | {_named(rep, s)} |")
    lines += ["", "Why each effect passes or not:", ""]
    lines += [f"* `{s.label}`: {s.why}" for s in rep.ranking]
    if rep.steps[1:]:
        lines += ["", "Greedy combination steps (each against the previous combination):", ""]
        for s in rep.steps[1:]:
            lines.append(f"* + {s.label}: delta elpd {_f(s.delta_elpd)} (se {_f(s.se)}); {s.why}")
    lines += ["", "![ranking](ranking.png)", "", "## Where the baseline misses", "",
              "Segments ranked by excess error over the noise level (MSE / sigma^2 - 1).", "",
              "| axis | segment | n | error share | bias [kN] | RMS / noise | coverage | energy error |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rep.where.head(12).itertuples():
        lines.append(f"| {r.axis} | {r.segment} | {r.n} | {_pct(r.error_share)} | {r.bias:.3g} | "
                     f"{r.rms_over_noise:.2f} | {_pct(r.coverage)} | {_pct(r.energy_error)} |")
    lines += ["", "![gap map](gap_map.png)", "", "## Loops", "", "![loops](loops.png)", ""]
    lines += _design_lines(design, building)
    lines += ["",
              "Method: optimum by bounded least squares, Laplace posterior draws, PSIS leave-one-block-out "
              "elpd on the calibration test, per-block squared-error reductions and a block bootstrap of the "
              "systematic gap on the held-out tests (see `rrfrei.gap.decision`).", ""]
    md = out / "report.md"
    md.write_text("\n".join(lines), encoding="utf-8")
    return md
