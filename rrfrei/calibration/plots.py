"""Figures of a calibration (matplotlib; callers choose the backend).  Units on the axes: mm, kN."""

from __future__ import annotations

import numpy as np

__all__ = ["pair_plot", "loop_plot", "loop_title", "energy_plot", "cumulative_plot"]


def _fig(nrows=1, ncols=1, size=(6.0, 4.0)):
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=size, constrained_layout=True, squeeze=False)


def _axes(ax):
    """(figure, axes): a new one-panel figure when ``ax`` is None, else ``ax`` and its figure."""
    if ax is None:
        fig, axes = _fig()
        return fig, axes[0, 0]
    return ax.figure, ax


def pair_plot(cal, *, max_points: int = 1000, seed: int = 0):
    """Scatter matrix of the sampled quantities with histograms on the diagonal, MAP marked.

    Only the lower triangle's k (k + 1) / 2 axes are made, on a fixed grid (no layout engine),
    with three ticks per axis labelled on the outer row and column only, and the histograms
    drawn as one filled outline each (not one patch per bin): the axes, their ticks and the
    layout were the calibrate command's slowest figure step.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    th = cal.theta()
    names = cal.sampled
    rng = np.random.default_rng(seed)
    if th.shape[0] > max_points:
        th = th[rng.choice(th.shape[0], max_points, replace=False)]
    k = len(names)
    side = 1.7 * k + 1
    fig = plt.figure(figsize=(side, side))
    margin = 0.75 / side  # inches for the outer tick labels and axis labels
    grid = fig.add_gridspec(k, k, left=margin, bottom=margin, right=1 - 0.1 / side,
                            top=1 - 0.45 / side, wspace=0.08, hspace=0.08)
    for i in range(k):
        for j in range(i + 1):
            ax = fig.add_subplot(grid[i, j])
            if i == j:
                counts, edges = np.histogram(th[:, i], bins=30)
                ax.stairs(counts, edges, fill=True, color="tab:blue", alpha=0.7)
                ax.axvline(cal.map[names[i]], color="k", lw=0.8)
            else:
                ax.plot(th[:, j], th[:, i], ".", ms=1.5, alpha=0.4, color="tab:blue")
                ax.plot(cal.map[names[j]], cal.map[names[i]], "k+", ms=8)
            ax.tick_params(labelsize=6, labelbottom=i == k - 1, labelleft=j == 0 and i > 0)
            ax.xaxis.set_major_locator(MaxNLocator(3))
            ax.yaxis.set_major_locator(MaxNLocator(3))
            if i == k - 1:
                ax.set_xlabel(names[j], fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(names[i], fontsize=8)
    fig.suptitle(f"{cal.law} posterior on {cal.test.name} (black: MAP)", fontsize=9)
    return fig


def loop_plot(pred, title: str = "", ax=None):
    """Measured loop, posterior mean and the 95 % band with noise."""
    fig, ax = _axes(ax)
    d = 1e3 * np.asarray(pred.test.disp)
    order = np.arange(d.size)
    ax.fill_between(order * 0 + d, pred.lower, pred.upper, color="tab:blue", alpha=0.25, lw=0,
                    label="95 % band (with noise)")
    ax.plot(d, pred.test.force, lw=0.6, color="0.45", label="test")
    ax.plot(d, pred.mean, lw=0.8, color="tab:blue", label="posterior mean")
    ax.set_xlabel("shear displacement [mm]")
    ax.set_ylabel("shear force [kN]")
    ax.set_title(title or loop_title(pred), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def loop_title(pred) -> str:
    """``law on test`` with NRMSE, systematic part and coverage, and the adequacy reading: a
    coverage shown alone reads as a good fit when the noise sd absorbed the misfit."""
    a = pred.adequacy
    if a is None:
        return (f"{pred.law} on {pred.test.name}: NRMSE {100 * pred.nrmse:.1f} %, "
                f"coverage {100 * pred.coverage:.1f} %")
    short = {"adequate": "adequate fit", "marginal": "marginal fit: misses part of the shape",
             "inadequate": "INADEQUATE: the law cannot reproduce this test's shape"}[a.level]
    return (f"{pred.law} on {pred.test.name}: NRMSE {100 * a.nrmse:.1f} % (systematic "
            f"{100 * a.systematic:.1f} %), coverage {100 * a.coverage:.1f} %\n{short}")


def energy_plot(pred, ax=None):
    """Energy dissipated per cycle: test, MAP and the 95 % band of the model."""
    fig, ax = _axes(ax)
    c = pred.cycles
    x = np.arange(len(c))
    if len(c):
        ax.bar(x - 0.2, c["energy_test"], width=0.4, color="0.5", label="test")
        ax.bar(x + 0.2, c["energy_map"], width=0.4, color="tab:blue", label="MAP")
        if "energy_lo" in c:
            ax.errorbar(x + 0.2, c["energy_map"], yerr=[np.clip(c["energy_map"] - c["energy_lo"], 0, None),
                                                        np.clip(c["energy_hi"] - c["energy_map"], 0, None)],
                        fmt="none", ecolor="k", capsize=2, label="95 % band")
    ax.set_xlabel("cycle")
    ax.set_ylabel("energy per cycle [kN m]")
    ax.set_title(f"{pred.law} on {pred.test.name}: energy per cycle", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")
    return fig


def cumulative_plot(pred, ax=None):
    """Cumulative dissipated energy against sample index (or time): test vs MAP."""
    fig, ax = _axes(ax)
    t = pred.test.time
    ax.plot(t, pred.cumulative_test, color="0.4", label="test")
    ax.plot(t, pred.cumulative_map, color="tab:blue", label="MAP")
    ax.set_xlabel("time [s]" if pred.test.has_time else "sample")
    ax.set_ylabel("cumulative energy [kN m]")
    ax.set_title(f"{pred.law} on {pred.test.name}: cumulative energy", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return fig
