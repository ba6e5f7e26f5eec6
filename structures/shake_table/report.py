"""Markdown report and figures of :func:`structures.shake_table.gap.shake_table_gap`.

:func:`write_report` writes ``DIR/shake_table.md`` with, per held-out run, the figures
``loops_<run>.png`` (isolation-system force [kN] against isolator displacement [m]: measured,
baseline and final model), ``isolator_disp_<run>.png`` and ``roof_accel_<run>.png`` (time
histories with the predictive 95 % band), and the tables of the gap before and after the
diagnosed effect, the band coverage, the effect ranking and the residual table ("where").
Figures are matplotlib ``Figure`` objects not managed by pyplot.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from rrfrei.gap.report import verdict_text
from structures.shake_table.gap import ShakeTableGap
from structures.shake_table.sequence import CHANNELS, UNITS

__all__ = ["figures", "runs_table", "write_report"]


def _figure(nrows: int, ncols: int = 1, size=(9.0, 3.0)):
    from matplotlib.figure import Figure  # deferred: matplotlib only for the report

    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def loops_figure(res: ShakeTableGap, run: str):
    """Measured and predicted (median) isolation-system loops of ``run``: baseline and final."""
    fig, axes = _figure(1, 2, size=(10.0, 4.0))
    b, a = res.before, res.after
    panels = ((axes[0, 0], b, f"baseline {res.law}"), (axes[0, 1], a, f"final {res.final_law}"))
    for ax, p, label in panels:
        ax.plot(p.measured[run]["isolator_disp"], p.measured[run]["isolator_force"], color="k", lw=0.5,
                label="measured")
        ax.plot(p.median[run]["isolator_disp"], p.median[run]["isolator_force"], color="C3", lw=0.6,
                label=f"{label} (median)")
        for x in (-res.calibrated_peak, res.calibrated_peak):
            ax.axvline(x, color="C0", ls="--", lw=0.8)
        ax.set_xlabel("isolator displacement [m]")
        ax.set_ylabel("isolation-system force [kN]")
        ax.set_title(f"{run}: {label}; dashed: calibrated range", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    return fig


def history_figure(res: ShakeTableGap, run: str, channel: str):
    """Time history of ``channel`` on ``run``: measured, baseline median, final median and the
    final model's predictive 95 % band (parameter draws plus the calibration-run error)."""
    fig, axes = _figure(1, 1, size=(10.0, 3.2))
    ax = axes[0, 0]
    b, a = res.before, res.after
    t = a.time[run]
    lo, hi = a.lower[run][channel], a.upper[run][channel]
    ax.fill_between(t, lo, hi, color="C0", alpha=0.25, lw=0, label="final: predictive 95 % band")
    ax.plot(t, a.measured[run][channel], color="k", lw=0.6, label="measured")
    ax.plot(t, b.median[run][channel], color="C1", lw=0.6, label=f"baseline {res.law}")
    ax.plot(t, a.median[run][channel], color="C3", lw=0.6, label=f"final {res.final_law}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{channel} [{UNITS[channel]}]")
    nb = res.before.nrmse([run])[channel]
    na = res.after.nrmse([run])[channel]
    ax.set_title(f"{run}, {channel}: NRMSE {100 * nb:.0f} % (baseline) -> {100 * na:.0f} % (final)",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    return fig


def figures(res: ShakeTableGap) -> dict[str, object]:
    """File name -> Figure for every held-out run (loops, isolator displacement, roof acceleration)."""
    out = {}
    for run in res.holdout:
        out[f"loops_{run}.png"] = loops_figure(res, run)
        out[f"isolator_disp_{run}.png"] = history_figure(res, run, "isolator_disp")
        out[f"roof_accel_{run}.png"] = history_figure(res, run, "roof_accel")
    return out


def runs_table(res: ShakeTableGap) -> pd.DataFrame:
    """One row per (run, channel) of the final model: NRMSE, peak error, coverage of the predictive
    95 % band and its width over the measured RMS."""
    rows = []
    for run, chans in res.runs.items():
        part = "held out" if run in res.holdout else "calibration"
        for c, m in chans.items():
            rows.append({"run": run, "part": part, "channel": c, **m})
    return pd.DataFrame(rows)


def gap_table(res: ShakeTableGap) -> pd.DataFrame:
    """One row per channel: NRMSE before/after on the calibration and held-out runs, shrink and
    held-out coverage of both bands."""
    rows = []
    sh = res.shrink() if res.holdout else {}
    for c in CHANNELS:
        hb = res.gap_before["holdout"] or {}
        ha = res.gap_after["holdout"] or {}
        rows.append({"channel": c, "unit": UNITS[c],
                     "calibration before": res.gap_before["calibration"][c],
                     "calibration after": res.gap_after["calibration"][c],
                     "held out before": hb.get(c, math.nan), "held out after": ha.get(c, math.nan),
                     "shrink": sh.get(c, math.nan),
                     "coverage (predictive)": res.coverage.get(c, math.nan),
                     "coverage (parameters)": res.coverage_parameter_band.get(c, math.nan)})
    return pd.DataFrame(rows)


def _interval(ci) -> str:
    """`(90 % interval a-b %) ` of a coverage, or nothing when it is unknown."""
    if not ci or not all(math.isfinite(v) for v in ci):
        return ""
    return f"(90 % interval {100 * ci[0]:.0f}-{100 * ci[1]:.0f} %, 10 s blocks) "


def _md(df: pd.DataFrame, pct: tuple[str, ...] = ()) -> str:
    def cell(col, v):
        if isinstance(v, (float, np.floating)):
            if not math.isfinite(v):
                return "n/a"
            return f"{100 * v:.1f} %" if col in pct else f"{v:.4g}"
        return str(v)

    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(cell(c, v) for c, v in zip(cols, row)) + " |")
    return "\n".join(lines)


def reading(res: ShakeTableGap) -> str:
    """The diagnosis in words, from the numbers."""
    rep = res.report
    lines = []
    ext = ", ".join(f"{h} {r:.2f} x" for h, r in res.extrapolation.items())
    ff = res.final_fit
    lines.append(f"Building calibrated by output error on {', '.join(res.calibrate)}: the superstructure "
                 f"from {res.identified_on} on the isolator law {res.law}, driven by every run's measured "
                 "table acceleration in order (isolator state carried"
                 + ("; the final model's runs each from the isolators' virgin state, which recover between "
                    "runs" if ff is not None and getattr(ff.model, "recover", False) else "")
                 + "), its simulated isolator displacement, "
                 "isolation-layer force and roof acceleration fitted to the measured ones"
                 + (f" (importance-sampling check of the Laplace posterior: effective sample size "
                    f"{ff.ess:.1f} of {ff.X.shape[0]})" if ff is not None else "")
                 + ".  Held-out peak isolator displacement over the calibrated peak "
                 f"({res.calibrated_peak:.3f} m): "
                 f"{ext or 'no held-out run'}"
                 + (" - beyond the calibrated range, where only the law's form governs."
                    if any(r > 1 for r in res.extrapolation.values()) else "."))
    lines.append("Diagnosis on the held-out runs' simulated responses (time windows, all fitted channels): "
                 + verdict_text(rep))
    if res.holdout:
        hb, ha = res.gap_before["holdout"], res.gap_after["holdout"]
        pk = {h: res.runs[h]["isolator_disp"]["peak_error"] for h in res.holdout}
        lines.append("Held-out isolator-displacement NRMSE "
                     f"{100 * hb['isolator_disp']:.0f} % without effects, "
                     f"{100 * ha['isolator_disp']:.0f} % with the final model {res.final_law}; peak error "
                     + ", ".join(f"{h} {100 * v:+.0f} %" for h, v in pk.items())
                     + "; the predictive 95 % band covers "
                     f"{100 * res.coverage['isolator_disp']:.0f} % "
                     + _interval(res.coverage_interval.get("isolator_disp"))
                     + "of the "
                     f"held-out isolator displacements with a mean width of "
                     f"{res.band_width['isolator_disp']:.2f} x their RMS.")
        lines.append(peaks_text(res))
        lf = res.loop_fit.get("holdout") or {}
        if lf:
            lines.append("For comparison, the isolator loop fit (force given the measured displacement) in "
                         f"the identified building: held-out isolator-displacement NRMSE "
                         f"{100 * lf['isolator_disp']:.0f} %.")
    return "\n\n".join(lines)


def data_warnings(res: ShakeTableGap) -> list[str]:
    """The report's opening lines when the readers warned about a run (levels upside down,
    masses in the opposite order, inconsistent channels: notes ``"reading: ..."``): every number
    of the report rests on the runs as read, so they go before the results, not among the notes
    at the end.  Empty when the reader said nothing."""
    data = [str(n)[len("reading: "):] for n in res.notes if str(n).startswith("reading: ")]
    if not data:
        return []
    return ["**Check the data first.** The results below rest on the runs as read, and the reader "
            "warned:", "", *[f"- {n}" for n in data], ""]


PEAK_TOLERANCE = 0.10
"""Relative under-prediction of a held-out peak beyond which the reading calls it unconservative."""

_PEAK_WORDS = {"isolator_disp": "isolator displacement", "isolator_force": "isolation-layer force",
               "base_shear": "story-1 shear", "roof_accel": "roof acceleration"}


def peaks_text(res: ShakeTableGap) -> str:
    """The held-out runs' peaks, where a designer reads them: every channel's peak error of the final
    model's median, and a warning when a peak is under-predicted by more than
    :data:`PEAK_TOLERANCE` (a design value read from it would be unconservative), with the run's
    peak displacement over the calibrated one when it lies beyond the calibrated range."""
    parts, low = [], []
    for h in res.holdout:
        pe = {c: res.runs[h][c]["peak_error"] for c in _PEAK_WORDS if c in res.runs.get(h, {})}
        parts.append(f"{h}: " + ", ".join(f"{_PEAK_WORDS[c]} {100 * v:+.0f} %" for c, v in pe.items()))
        low += [(h, c, v) for c, v in pe.items() if v < -PEAK_TOLERANCE]
    txt = "Held-out peaks of the final model's median against the measured ones: " + "; ".join(parts) + "."
    if low:
        names = ", ".join(f"{_PEAK_WORDS[c]} ({h})" for h, c, _ in low)
        txt += (f"  Under-predicted by more than {100 * PEAK_TOLERANCE:.0f} %: {names}; a design value read "
                "from them would be unconservative")
        runs = dict.fromkeys(h for h, _, _ in low)  # each run once, in order
        far = [f"{h} at {res.extrapolation.get(h, 1.0):.2f} x the calibrated displacement" for h in runs
               if res.extrapolation.get(h, 1.0) > 1]
        if far:
            txt += (f" ({', '.join(far)}: beyond the calibrated range the model's force "
                    "follows the law's form, not a measurement; calibrate on a run that reaches the "
                    "design displacement)")
        txt += "."
    return txt


def write_report(res: ShakeTableGap, out: str | Path) -> Path:
    """Write ``out/shake_table.md`` and its figures; returns the Markdown path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    figs = figures(res)
    for name, fig in figs.items():
        fig.savefig(out / name, dpi=100)
    rep = res.report
    held = ", ".join(res.holdout) or "(no held-out run)"
    parts = [f"# Shake-table gap: {', '.join(res.calibrate)} -> {held}", "", *data_warnings(res),
             reading(res), "",
             "## Gap per channel (NRMSE of the posterior median)", "",
             _md(gap_table(res), pct=("calibration before", "calibration after", "held out before",
                                      "held out after", "shrink", "coverage (predictive)",
                                      "coverage (parameters)")),
             "",
             "Predictive band: posterior draws of the building's parameters plus the residual model (per "
             "channel, sd of the calibration residuals); parameter band: the draws only.", "",
             "## Every run, final model", "",
             _md(runs_table(res), pct=("nrmse", "peak_error", "coverage", "coverage_low", "coverage_high")),
             ""]
    if len(res.law_scores):
        parts += ["## Law choice (leave-one-cycle-out elpd on the calibration isolation tests)", "",
                  _md(res.law_scores), ""]
    if rep.ranking:
        rk = pd.DataFrame([{"effect": e.effect, "delta_elpd": e.delta_elpd, "se": e.se,
                            "delta_holdout": e.delta_holdout, "se_holdout": e.se_holdout,
                            "shrink_holdout": e.shrink_holdout, "significant": e.significant}
                           for e in rep.ranking])
        parts += ["## Effects (each fitted by output error on the calibration runs, judged on the held-out "
                  "runs' simulated responses)", "",
                  _md(rk, pct=("shrink_holdout",)), ""]
    if len(res.building_check):
        parts += ["## Every candidate in the building (held-out NRMSE, optimum of each law)", "",
                  _md(res.building_check, pct=CHANNELS), ""]
    if len(res.where):
        parts += ["## Where the held-out gap lies", "",
                  _md(res.where.head(40), pct=("error_share", "nrmse")), ""]
    for name in figs:
        parts += [f"![{name}]({name})", ""]
    if res.notes:
        parts += ["## Notes", "", *[f"- {n}" for n in res.notes], ""]
    steps = ", ".join(f"{k} {v:.0f} s" for k, v in res.seconds.items())
    parts += [f"Elapsed {res.elapsed:.0f} s ({steps})."]
    md = out / "shake_table.md"
    md.write_text("\n".join(parts) + "\n")
    return md
