"""Plots of a :class:`structures.responses.ResponseSet`: distributions, exceedance, fragility.

Each function takes the response set and returns the matplotlib figure it drew on (``ax`` given:
its figure; else a new pyplot figure).  Axis labels carry units (:func:`label`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from structures import summaries

if TYPE_CHECKING:
    from structures.responses import ResponseSet

__all__ = ["DEMAND_LABELS", "distributions", "exceedance", "fragility", "label"]

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
    ax.set_title(f"{rs.law}, {len(rs.draws)} draws, scale {s:g}\n(box 25-75 %, whiskers 2.5-97.5 %)",
                 fontsize=10)
    if d in rs.limits:
        ax.axhline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
        ax.legend()
    ax.figure.tight_layout()
    return ax.figure


def exceedance(rs: ResponseSet, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
    """Empirical exceedance curves P(D > d) per record and over all records at one scale (default: last)."""
    (d,) = rs._check(demand)
    s = rs.scales[-1] if scale is None else float(scale)
    t = summaries._converged(rs.table)
    t = t[np.isclose(t["scale"], s)]
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6, 4))
    for r in [*rs.records, summaries.ALL]:
        x = np.sort((t if r == summaries.ALL else t[t["record"] == r])[d].to_numpy(float))
        if not x.size:
            continue
        p = 1.0 - np.arange(1, x.size + 1) / x.size
        kw = {"color": "k", "lw": 2.2} if r == summaries.ALL else {"lw": 1.0, "alpha": 0.8}
        ax.step(x, p, where="post", label=r, **kw)
    if d in rs.limits:
        ax.axvline(rs.limits[d], color="C3", ls="--", label=f"limit {rs.limits[d]:g}")
    ax.set_xlabel(label(d))
    ax.set_ylabel("probability of exceedance P(D > d) [-]")
    ax.set_title(f"scale {s:g}")
    ax.legend(fontsize=7, ncol=2)
    ax.figure.tight_layout()
    return ax.figure


def fragility(rs: ResponseSet, limits: Mapping[str, float] | None = None, ax=None):
    """Fitted fragility curves with the observed stripe fractions."""
    frs = rs.fragility(limits)
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6, 4))
    lo = min(rs.scales) * 0.5
    hi = max(rs.scales) * 1.5
    x = np.linspace(lo, hi, 200)
    for i, fr in enumerate(frs):
        c = f"C{i}"
        name = f"{fr.demand} > {fr.limit:g}"
        ax.plot(fr.im, np.divide(fr.z, fr.n), "o", color=c)
        if math.isfinite(fr.theta):
            ax.plot(x, fr.probability(x), color=c,
                    label=f"{name}: theta={fr.theta:.3g}, beta={fr.beta:.2f}")
        else:
            ax.plot([], [], "o", color=c, label=f"{name}: {fr.note}")
    ax.set_xlabel(rs.im_label)
    ax.set_ylabel("P(demand > limit) [-]")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title("lognormal fragility, maximum likelihood (Baker 2015)")
    ax.legend(fontsize=7)
    ax.figure.tight_layout()
    return ax.figure
