"""Building consequences of an isolator's bounds: the five-story building at nominal, upper- and
lower-bound isolator properties, with and without a gap effect, on the bundled records.

The answer of issue 12 point 5 in the engineer's terms: how far the isolators move and how much
base shear reaches the building when the isolator properties sit at their ASCE 7-22 section
17.2.8.4 bounds (:class:`rrfrei.gap.design.PropertyModification`), and how much a diagnosed
effect (an augmented law ``base+effect``) changes that.  The bound laws follow
:func:`rrfrei.gap.design.bound_params` (force-like parameters times lambda).  All analyses of a
law on a record run as one :func:`structures.time_history_batch` call.

Units: displacement [m], force [kN].
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

import ground_motions
from rrfrei.gap.design import PropertyModification, bound_params
from rrfrei.laws import get as get_law
from structures.building.shear_building import Isolator
from structures.dynamics.history import time_history_batch
from structures.propagation.inputs import resolve_building, resolve_records

__all__ = ["BOUNDS", "building_consequences", "plot_consequences"]

BOUNDS = ("lower", "nominal", "upper")
"""The isolator property bounds analysed, in table order."""

COLUMNS = ("law", "effect", "bound", "lambda", "record", "iso_disp_peak", "base_shear_peak", "converged")


def _lambdas(lambdas) -> tuple[float, float]:
    if isinstance(lambdas, PropertyModification):
        return lambdas.law_lambdas()
    try:
        lo, hi = (float(x) for x in lambdas)
    except (TypeError, ValueError):
        raise ValueError(
            f"lambdas = {lambdas!r} is invalid: expected a PropertyModification or a pair "
            "(lambda_lower, lambda_upper)"
        ) from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= 1.0 <= hi):
        raise ValueError(f"lambdas = ({lo:g}, {hi:g}) is invalid: expected 0 < lower <= 1 <= upper")
    return lo, hi


def _variants(law: str, params_nominal: Mapping[str, float],
              effect_params: Mapping[str, float] | None) -> list[tuple[str, str, dict]]:
    """(law name, effect label, nominal parameters) of the base law and of the augmented law."""
    name = get_law(law).name
    base, _, effect = name.partition("+")
    base_spec = get_law(base)
    params = dict(params_nominal)
    base_params = {k: v for k, v in params.items() if k in base_spec.param_names}
    out = [(base, "none", base_spec.as_dict(base_spec.pack(base_params)))]
    if effect:
        if effect_params is None:
            raise ValueError(
                f"law {name!r} names the effect {effect!r}: give its parameters as effect_params "
                f"({', '.join(n for n in get_law(name).param_names if n not in base_spec.param_names)})"
            )
        spec = get_law(name)
        out.append((name, effect, spec.as_dict(spec.pack({**base_params, **dict(effect_params)}))))
    elif effect_params:
        raise ValueError(
            f"effect_params {dict(effect_params)!r} given but law {name!r} names no effect: "
            "give the augmented law, e.g. 'bouc_wen+degradation'"
        )
    return out


def building_consequences(law: str, params_nominal: Mapping[str, float], lambdas, *,
                          effect_params: Mapping[str, float] | None = None,
                          records: Sequence | None = None, building="five_story") -> pd.DataFrame:
    """Peak isolator displacement and base shear at nominal, upper and lower bound.

    Parameters
    ----------
    law : the isolator law, plain (``"bouc_wen"``) or augmented with the named effect
        (``"bouc_wen+degradation"``); an augmented law is analysed with and without the effect
        (the base law alone is its first variant).
    params_nominal : the base law's nominal parameters (kN, m, s; specimen scale, as the
        building's ``length_scale`` expects them).
    lambdas : a :class:`rrfrei.gap.design.PropertyModification` (its envelope
        ``law_lambdas()``) or a pair ``(lambda_lower, lambda_upper)``.
    effect_params : the effect's parameters (required with an augmented law).
    records : bundled record names, paths or ``ground_motions.Record``\\ s; None: all eleven
        bundled records (``ground_motions.available()``), unscaled.  A subset is faster.
    building : a :class:`structures.ShearBuilding`, a bundled name or a TOML path; its isolator
        layer keeps its count and length scale and takes ``law`` and the bound parameters.

    Returns
    -------
    DataFrame with columns ``law``, ``effect`` (``"none"`` or the effect's name), ``bound``
    (:data:`BOUNDS`), ``lambda`` [-], ``record``, ``iso_disp_peak`` [m] (prototype),
    ``base_shear_peak`` [kN], ``converged``; one row per law variant, bound and record, then one
    ``record == "median"`` row per law variant and bound (median over the converged runs).
    ``attrs["seconds"]`` holds the wall time of the analyses [s].
    """
    lo, hi = _lambdas(lambdas)
    b = resolve_building(building)
    recs = resolve_records(list(ground_motions.available()) if records is None else records)
    rows = []
    t0 = time.perf_counter()
    for name, effect, nominal in _variants(law, params_nominal, effect_params):
        spec = get_law(name)
        sets = {"lower": bound_params(name, nominal, lo), "nominal": nominal,
                "upper": bound_params(name, nominal, hi)}
        lam = {"lower": lo, "nominal": 1.0, "upper": hi}
        P = np.array([spec.pack(sets[k]) for k in BOUNDS])
        bv = replace(b, isolator=Isolator(name, nominal, b.isolator.count, b.isolator.length_scale))
        for rec in recs:
            out = time_history_batch(bv, rec, P)
            for i, k in enumerate(BOUNDS):
                rows.append((name, effect, k, lam[k], rec.name, float(out["iso_disp_peak"][i]),
                             float(out["base_shear_peak"][i]), bool(out["converged"][i])))
    seconds = time.perf_counter() - t0
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    med = (df[df["converged"]].groupby(["law", "effect", "bound", "lambda"], sort=False)
           [["iso_disp_peak", "base_shear_peak"]].median().reset_index())
    med["record"] = "median"
    med["converged"] = True
    out = pd.concat([df, med[list(COLUMNS)]], ignore_index=True)
    out.attrs["seconds"] = seconds
    return out


def plot_consequences(df: pd.DataFrame, *, title: str = ""):
    """Figure of :func:`building_consequences`: isolator displacement [mm] and base shear [kN]
    at lower, nominal and upper bound; small points per record, large markers the medians, one
    colour per law variant (with / without the effect).  Returns a matplotlib ``Figure`` (not
    managed by pyplot; save it with ``fig.savefig``)."""
    from matplotlib.figure import Figure  # deferred: matplotlib only when a figure is drawn

    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    axes = fig.subplots(1, 2)
    variants = list(dict.fromkeys(zip(df["law"], df["effect"])))
    width = 0.6 / max(1, len(variants))
    for ax, col, scale, label in ((axes[0], "iso_disp_peak", 1e3, "peak isolator displacement [mm]"),
                                  (axes[1], "base_shear_peak", 1.0, "peak base shear [kN]")):
        for j, (law, effect) in enumerate(variants):
            sub = df[(df["law"] == law) & (df["effect"] == effect)]
            colour = f"C{j}"
            tag = f"{law} (base law)" if effect == "none" else f"{law.partition('+')[0]} with {effect}"
            for i, bound in enumerate(BOUNDS):
                x = i + (j - (len(variants) - 1) / 2) * width
                rec = sub[(sub["bound"] == bound) & (sub["record"] != "median")]
                ax.plot(np.full(len(rec), x), rec[col] * scale, ".", color=colour, alpha=0.45, ms=5)
                med = sub[(sub["bound"] == bound) & (sub["record"] == "median")]
                ax.plot([x] * len(med), med[col] * scale, "D", color=colour, ms=8,
                        label=tag if i == 0 else None, markeredgecolor="k")
        ax.set_xticks(range(len(BOUNDS)))
        lam = df.drop_duplicates("bound").set_index("bound")["lambda"]
        ax.set_xticklabels([f"{b}\n(\u03bb = {lam.get(b, float('nan')):.2f})" for b in BOUNDS])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title)
    return fig
