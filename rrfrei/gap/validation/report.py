"""Markdown, JSON and the confusion-matrix figure of a validation run (``rrfrei gap-validate``).

Files written by :func:`write` into a folder: ``validation.md`` (goals met or missed in plain
words, the generator forms, the confusion matrix, miss rates per effect and per form, false
alarms, held-out shrink, every miss), ``validation.json`` (:meth:`ValidationResult.as_dict`) and
``validation_confusion.png``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from rrfrei.gap.validation.cases import CONTROLS, NOISE_RANGE
from rrfrei.gap.validation.forms import FORMS
from rrfrei.gap.validation.run import VERDICTS, ValidationResult

__all__ = ["markdown", "figure", "write", "percent", "COMMAND"]

COMMAND = "python -m rrfrei.app gap-validate --seeds 10 --out docs/gap"


def percent(x: float) -> str:
    """Percent, to the unit; to a tenth where the unit would round to 0 or 100 % and the
    fraction is not exactly 0 or 1 (one miss in 270 is 99.6 %, not 100 %)."""
    if x is None or not math.isfinite(x):
        return "n/a"
    if 0.0 < x < 0.005 or 0.995 <= x < 1.0:
        return f"{100 * x:.1f} %"
    return f"{100 * x:.0f} %"


def _f(x, fmt: str = ".2f") -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return ""
    return format(x, fmt) if math.isfinite(x) else ""


def _table(header: list[str], rows: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out


def _variants_taken(named) -> str:
    """'k of n (name)' of the named cases fitted as a variant ('' when none was)."""
    if "variant" not in named or not len(named):
        return ""
    v = named.variant.fillna("").astype(str)
    taken = v[v != ""]
    if not len(taken):
        return ""
    return f"{len(taken)} of {len(named)} ({', '.join(sorted(set(taken)))})"


def markdown(res: ValidationResult, *, command: str = COMMAND, title_note: str = "") -> str:
    """The report (see the module docstring)."""
    s = res.settings
    g = res.goals()
    e, c = res.effect_cases, res.control_cases
    seeds = sorted(set(res.ran.seed)) if len(res.ran) else []
    lines = ["# Gap diagnosis: validation on withheld effects", ""]
    if title_note:
        lines += [title_note, ""]
    lines += [
        f"`{command}` ({len(res.cases)} cases: {len(e)} effect cases, {len(c)} controls, seeds "
        f"{seeds[0] if seeds else '-'}-{seeds[-1] if seeds else '-'}; protocols sampled at {s.rate:g} Hz, "
        f"{s.draws} posterior draws per fit, "
        f"{'greedy combination on' if s.combine else 'first effect only'}; "
        f"{_f(res.seconds / 60, '.1f')} min wall time"
        + (f", {res.reused} cases read from the checkpoint" if res.reused else "")
        + ").",
        "",
        "Every case makes protocols 1-4 (`rrfrei.protocols`) from a base law (`plasticity` for even "
        "seeds, `bouc_wen` for odd seeds, `alpha2 = 0` held fixed) plus one effect written by one of "
        "three generator forms that are not the catalogue's kernels (table below), plus noise; "
        "protocol 1 calibrates, 2-4 are held out, the effect is withheld from the model, and the "
        "diagnosis must name it.  Effect sizes are stratified over the seeds from small to large; "
        f"noise is Gaussian, {100 * NOISE_RANGE[0]:g}-{100 * NOISE_RANGE[1]:g} % of the peak force. "
        "Controls have no effect and the noise of their name "
        f"({', '.join(f'`{k}`' for k in CONTROLS)}); a false alarm is an effect named on a control "
        "(`unexplained` is not one).",
        "",
        "## Goals (issue 12)",
        "",
    ]
    top = g["top1_per_effect_ge_95"]
    if top["met"]:
        lines.append(f"- top-1 >= 95 % for every effect: **met** (overall {percent(res.accuracy)}).")
    else:
        per = top["value"]
        lines.append(
            "- top-1 >= 95 % for every effect: **missed** for "
            + ", ".join(f"{k} ({percent(per[k])})" for k in top["missed_by"])
            + f" (overall {percent(res.accuracy)})."
        )
    fa = g["no_false_alarm"]
    lines.append(
        f"- no false alarm: **{'met' if fa['met'] else 'missed'}** ({res.false_alarms} of {len(c)} "
        "controls named an effect)."
    )
    sh = g["shrink_ge_50_when_named"]["value"]
    lines.append(
        f"- held-out shrink >= 50 % whenever an effect is named: "
        f"**{'met' if g['shrink_ge_50_when_named']['met'] else 'missed'}** (median {_f(sh['median'])}, "
        f"min {_f(sh['min'])}, {sh['below']} named cases below 0.50)."
    )
    if res.not_run:
        lines.append(f"- {res.not_run} cases were not run (time budget): the table is incomplete.")
    lines += [
        "",
        "![confusion matrix](validation_confusion.png)",
        "",
        "## Confusion matrix (rows: true effect, columns: verdict)",
        "",
    ]
    conf = res.confusion
    lines += _table(
        ["true"] + [str(x) for x in conf.columns], [[k] + [int(v) for v in row] for k, row in conf.iterrows()]
    )
    lines += ["", "## Top-1 and miss rate per effect", ""]
    per = res.top1("effect")
    lines += _table(
        ["effect", "cases", "named", "top-1", "miss rate"],
        [[k, int(r.cases), int(r.named), percent(r.top1), percent(r.miss_rate)] for k, r in per.iterrows()],
    )
    if len(e) and "effect_gap" in e:
        # thirds of each form's cases ranked by the gap their effect makes (direction-free: a
        # larger slip capacity is a smaller effect)
        rank = e.groupby(["effect", "form"]).effect_gap.rank(pct=True, method="first")
        third = ((rank - 1e-9) * 3).clip(0, 2).astype(int)
        names = ("small (lower third)", "medium", "large (upper third)")
        lines += ["", "## Miss rate by effect size (thirds of each form's cases by effect size)", ""]
        rows = []
        for eff in res.effects:
            m = e.effect == eff
            cells = []
            for k in range(3):
                sel = e[m & (third == k)]
                cells.append(f"{percent(float((sel.verdict != eff).mean()))} of {len(sel)}"
                             if len(sel) else "")
            rows.append([eff] + cells)
        lines += _table(["effect", *names], rows)
    lines += ["", "## Per generator form", ""]
    pf = res.top1("form")
    eg = e.groupby(["effect", "form"], sort=False) if len(e) else None
    rows = []
    for (eff, form), r in pf.iterrows():
        grp = eg.get_group((eff, form))
        named = grp[grp.verdict == eff]
        rows.append(
            [
                eff,
                form,
                int(r.cases),
                percent(r.top1),
                percent(r.miss_rate),
                f"{_f(grp.effect_gap.min() * 100, '.0f')}-{_f(grp.effect_gap.max() * 100, '.0f')} %",
                _f(named.shrink.median()) if len(named) else "",
                _variants_taken(named),
            ]
        )
    lines += _table(
        [
            "effect",
            "form",
            "cases",
            "top-1",
            "miss rate",
            "effect size (held-out NRMSE)",
            "median shrink when named",
            "fitted as a variant",
        ],
        rows,
    )
    lines += [
        "",
        "Effect size: NRMSE of the noise-free force with the effect against the base law's "
        "force over the held-out tests (the gap the effect makes before any refit).  Fitted as a "
        "variant: named cases in which a variant of the effect (`rrfrei.laws.effects.Variant`: a "
        "shape parameter more, taken only when it beats the primary fit on the held-out blocks) "
        "stood for it.",
        "",
        "## Controls",
        "",
    ]
    if len(c):
        cc = c.groupby("form", sort=False)
        lines += _table(
            ["control", "cases", "none", "unexplained", "incomplete", "effect named"],
            [
                [
                    k,
                    len(grp),
                    int((grp.verdict == "none").sum()),
                    int((grp.verdict == "unexplained").sum()),
                    int((grp.verdict == "incomplete").sum()),
                    int((~grp.verdict.isin(VERDICTS)).sum()),
                ]
                for k, grp in cc
            ],
        )
    miss = e[e.verdict != e.effect] if len(e) else e
    lines += ["", f"## Misses ({len(miss)} of {len(e)} effect cases)", ""]
    if len(miss):
        lines += _table(
            ["case", "base", "size", "effect size", "verdict", "top of ranking", "its shrink", "note"],
            [
                [
                    r.key,
                    r.base,
                    _f(r.size, ".3g"),
                    percent(r.effect_gap),
                    r.verdict,
                    r.best,
                    _f(r.best_shrink),
                    str(r.note or "")[:80],
                ]
                for r in miss.itertuples()
            ],
        )
    alarms = c[~c.verdict.isin(VERDICTS)] if len(c) else c
    if len(alarms):
        lines += ["", "## False alarms", ""]
        lines += _table(
            ["case", "base", "verdict"], [[r.key, r.base, r.verdict] for r in alarms.itertuples()]
        )
    lines += [
        "",
        "## Generator forms",
        "",
        "Plain NumPy in `rrfrei/gap/validation/forms.py` (its docstring defines every symbol); "
        "size ranges are the small-to-large span drawn over the seeds.",
        "",
    ]
    lines += _table(
        ["effect", "form", "force with the effect", "size range"],
        [
            [f.effect, f.name, f.equation.replace("|", "\\|"), f"{f.size_range[0]:g}-{f.size_range[1]:g}"]
            for fs in FORMS.values()
            for f in fs
        ],
    )
    t = res.ran.seconds.astype(float) if len(res.ran) and "seconds" in res.ran else None
    if t is not None and len(t.dropna()):
        lines += [
            "",
            f"Diagnosis time per case: median {_f(t.median(), '.0f')} s, max {_f(t.max(), '.0f')} s "
            "(shared 2-core machine).",
        ]
    return "\n".join(lines) + "\n"


def figure(res: ValidationResult):
    """The confusion matrix as a labelled heat map (a matplotlib Figure, not managed by pyplot)."""
    import numpy as np
    from matplotlib.figure import Figure

    conf = res.confusion
    m = conf.to_numpy(dtype=float)
    frac = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig = Figure(figsize=(1.0 + 0.75 * m.shape[1], 1.2 + 0.5 * m.shape[0]), dpi=110, layout="constrained")
    ax = fig.add_subplot()
    im = ax.imshow(frac, cmap="Blues", vmin=0, vmax=1, aspect="auto")
    ax.set_xticks(range(m.shape[1]), [str(c) for c in conf.columns], rotation=40, ha="right")
    ax.set_yticks(range(m.shape[0]), [str(i) for i in conf.index])
    for i in range(m.shape[0]):
        for j in range(m.shape[1]):
            if m[i, j]:
                ax.text(
                    j,
                    i,
                    f"{int(m[i, j])}",
                    ha="center",
                    va="center",
                    color="white" if frac[i, j] > 0.6 else "black",
                    fontsize=8,
                )
    ax.set_xlabel("verdict of the diagnosis")
    ax.set_ylabel("true effect (generator)")
    ax.set_title(f"gap-validate: top-1 {percent(res.accuracy)}, false alarms {res.false_alarms}")
    fig.colorbar(im, ax=ax, label="fraction of the row's cases")
    return fig


def write(
    res: ValidationResult, out: str | Path, *, command: str = COMMAND, title_note: str = ""
) -> dict[str, Path]:
    """Write the three files into ``out`` (created); returns {name: path}."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "validation.md": out / "validation.md",
        "validation.json": out / "validation.json",
        "validation_confusion.png": out / "validation_confusion.png",
    }
    paths["validation.md"].write_text(markdown(res, command=command, title_note=title_note), encoding="utf-8")
    paths["validation.json"].write_text(json.dumps(res.as_dict(), indent=1, default=str), encoding="utf-8")
    figure(res).savefig(paths["validation_confusion.png"])
    return paths
