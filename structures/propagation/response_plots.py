"""Plots of a :class:`structures.propagation.responses.ResponseSet`: distributions, exceedance, fragility.

Each function takes the response set and returns the matplotlib figure it drew on (``ax`` given:
its figure; else a new pyplot figure).  Axis labels carry units (:func:`label`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from structures.propagation import summaries

if TYPE_CHECKING:
    from structures.propagation.responses import ResponseSet

__all__ = ["DEMAND_LABELS", "distributions", "exceedance", "fragility", "intensity_text", "label"]

#: Demand column -> axis label with unit (per-story/floor columns are labelled by prefix).
DEMAND_LABELS = {
    "iso_disp_peak_m": "peak isolator displacement [m]",
    "iso_disp_residual_m": "residual isolator displacement [m]",
    "drift_ratio_max": "peak story drift ratio, largest story [-]",
    "floor_acc_max_ms2": "peak absolute floor acceleration, largest floor [m/s$^2$]",
    "base_shear_peak_kN": "peak base shear [kN]",
    "iso_energy_kNm": "isolator dissipated energy [kN m]",
    "energy_error": "energy balance error (relative) [-]",
}


def label(demand: str) -> str:
    """Axis label with unit of a demand column."""
    if demand in DEMAND_LABELS:
        return DEMAND_LABELS[demand]
    if demand.startswith("drift_ratio_s"):
        return f"peak drift ratio, story {demand[len('drift_ratio_s'):]} [-]"
    if demand.startswith("floor_acc_f"):
        floor = demand[len("floor_acc_f"):].removesuffix("_ms2")
        return f"peak absolute acceleration, floor {floor} [m/s$^2$]"
    return demand


def _pyplot():
    import matplotlib.pyplot as plt  # deferred: matplotlib only when a figure is drawn

    return plt


def distributions(rs: ResponseSet, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
    """Box plots of ``demand`` per record (and over all records) at one scale (default: the first)."""
    (d,) = rs._check(demand)
    s = rs.scales[0] if scale is None else float(scale)
    t = summaries._converged(rs.table)
    t = t[np.isclose(t["scale"], s)]
    data = [t.loc[t["record"] == r, d].to_numpy(float) for r in rs.records] + [t[d].to_numpy(float)]
    names = [*rs.records, summaries.ALL]
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(max(5.0, 0.7 * len(names) + 2), 4))
    ax.boxplot(data, whis=(2.5, 97.5), showfliers=True)
    ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
    ax.set_xlabel("ground motion record")
    ax.set_ylabel(label(d))
    ax.set_title(f"{rs.law}, {len(rs.draws)} draws per record, {intensity_text(rs, s)}\n"
                 "(box 25-75 %, whiskers 2.5-97.5 %)", fontsize=9)
    if d in rs.limits:
        ax.axhline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
        ax.legend()
    ax.figure.tight_layout()
    return ax.figure


def intensity_text(rs: ResponseSet, s: float) -> str:
    """Stripe ``s`` in words: ``record scale factor 1 (records as recorded)``, ``Sa(...) = 0.3 g``."""
    lab = rs.im_label
    name, _, unit = lab.rpartition(" [")
    unit = unit.rstrip("]")
    if "scale factor" in lab:
        return f"record scale factor {s:g}" + (" (records as recorded)" if s == 1.0 else "")
    name = name or lab
    return f"{name} = {s:g}" + (f" {unit}" if unit and unit != "-" else "")


def exceedance(rs: ResponseSet, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
    """Empirical exceedance curves P(D > d) at one intensity (default: the last stripe).

    Thin lines: over the posterior draws on one record (parameter uncertainty only); thick line:
    over the draws on every record (records and parameters).  The title, the axis and the legend
    say which set each curve is over.
    """
    (d,) = rs._check(demand)
    s = rs.scales[-1] if scale is None else float(scale)
    t = summaries._converged(rs.table)
    t = t[np.isclose(t["scale"], s)]
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6.4, 4.4))
    for r in [*rs.records, summaries.ALL]:
        x = np.sort((t if r == summaries.ALL else t[t["record"] == r])[d].to_numpy(float))
        if not x.size:
            continue
        p = 1.0 - np.arange(1, x.size + 1) / x.size
        if r == summaries.ALL:
            kw = {"color": "k", "lw": 2.2,
                  "label": f"{r}: {x.size} runs (draws x {len(rs.records)} records)"}
        else:
            kw = {"lw": 1.0, "alpha": 0.8, "label": f"{r}: {x.size} draws"}
        ax.step(x, p, where="post", **kw)
    if d in rs.limits:
        ax.axvline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
    ax.set_xlabel(label(d))
    ax.set_ylabel("P(D > d) over the runs of each curve [-]")
    ax.set_title(f"{rs.law}: exceedance of the demand at {intensity_text(rs, s)}\n"
                 "thin: posterior draws on one record; thick: draws on all records", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    ax.figure.tight_layout()
    return ax.figure


def fragility(rs: ResponseSet, limits: Mapping[str, float] | None = None, ax=None):
    """Fitted fragility curves P(D > limit | IM) with the observed fraction at each stripe.

    The x axis is the response set's intensity measure (:attr:`ResponseSet.im_label`, e.g.
    ``Sa(T_iso, 5 %) [g]`` of a multiple stripe analysis); each point is the share of the
    stripe's runs (every draw on every record) beyond the limit.
    """
    frs = rs.fragility(limits)
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6.4, 4.4))
    hi = max(rs.scales) * 1.15
    x = np.linspace(hi / 400, hi, 300)
    n_runs = 0
    for i, fr in enumerate(frs):
        c = f"C{i}"
        what, _, unit = label(fr.demand).rpartition(" [")
        unit = unit.rstrip("]").replace("$^2$", "2")
        name = f"{what} > {fr.limit:.3g}" + (f" {unit}" if unit and unit != "-" else "")
        ax.plot(fr.im, np.divide(fr.z, fr.n), "o", color=c)
        n_runs = max(n_runs, max(fr.n, default=0))
        if math.isfinite(fr.theta):
            ax.plot(x, fr.probability(x), color=c,
                    label=f"{name}: median {fr.theta:.3g}, beta {fr.beta:.2f}")
        else:
            ax.plot([], [], "o", color=c, label=f"{name}: {fr.note}")
    ax.set_xlim(0.0, hi)
    ax.set_xlabel(rs.im_label)
    ax.set_ylabel("P(demand > limit | intensity) [-]")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"lognormal fragility, maximum likelihood over {len(rs.scales)} stripes (Baker 2015)\n"
                 f"points: share of the up to {n_runs} runs of a stripe ({len(rs.records)} records x "
                 "posterior draws) beyond the limit", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    ax.figure.tight_layout()
    return ax.figure
