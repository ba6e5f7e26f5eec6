"""The demo page's figures: matplotlib ``Figure`` objects drawn from the steps' results.

Figures are not managed by pyplot (no GUI backend, nothing global); the page embeds them as PNG
(:meth:`rrfrei.app.report.Section.add_figure`).  Displacements are drawn in mm, forces in kN,
stresses in MPa.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrfrei.app.demo.context import SYNTHETIC, TESTS
from rrfrei.app.demo.prose import pct
from rubber import simulate

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def new_figure(nrows: int = 1, ncols: int = 1, *, size: tuple[float, float] = (7.0, 4.2), **kw):
    """A matplotlib Figure not managed by pyplot and its (nrows, ncols) array of axes."""
    from matplotlib.figure import Figure  # deferred: matplotlib is not needed to start the CLI

    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def plot_prediction(ax, test, pred: Any, title: str) -> None:
    """Loop of the test, the posterior mean and the band (its edges, as the loop is not monotonic)."""
    d_mm = 1e3 * np.asarray(test.disp)
    ax.plot(d_mm, test.force, lw=0.6, color="0.55", label="test")
    ax.plot(d_mm, pred.lower, lw=0.4, color="tab:blue", alpha=0.45, label="95 % band")
    ax.plot(d_mm, pred.upper, lw=0.4, color="tab:blue", alpha=0.45)
    ax.plot(d_mm, pred.mean, lw=0.9, color="tab:red", label="posterior mean")
    ax.set_title(f"{title}: NRMSE {pct(pred.nrmse)}", fontsize=9)
    ax.set_xlabel("shear displacement [mm]")
    ax.set_ylabel("shear force [kN]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def isolator_loops(tests: Mapping[str, Any]) -> Figure:
    """Force-displacement loops of the four bundled tests (2 x 2)."""
    fig, axes = new_figure(2, 2, size=(9.0, 6.5))
    for ax, name in zip(axes.ravel(), TESTS):
        t = tests[name]
        ax.plot(1e3 * np.asarray(t.disp), np.asarray(t.force), lw=0.7, color="0.25")
        ax.set_title(f"{name} ({SYNTHETIC})", fontsize=9)
        ax.set_xlabel("shear displacement [mm]")
        ax.set_ylabel("shear force [kN]")
        ax.grid(alpha=0.3)
    return fig


def calibration_fits(test, panels: Sequence[tuple[str, Any]]) -> Figure:
    """One panel per law (2 x 2): the test against the posterior prediction, or 'failed' (None)."""
    fig, axes = new_figure(2, 2, size=(9.0, 6.5))
    for ax in axes.ravel()[len(panels):]:  # fewer laws (a quick run): no empty frames
        ax.set_axis_off()
    for ax, (law, pred) in zip(axes.ravel(), panels):
        if pred is None:
            ax.set_title(f"{law}: calibration failed", fontsize=9)
            ax.set_axis_off()
        else:
            plot_prediction(ax, test, pred, f"{law} on protocol1 ({SYNTHETIC})")
    return fig


def holdout_fits(tests: Mapping[str, Any], preds: Mapping[str, Any], law: str) -> Figure:
    """The held-out tests (1 x 3) against the posterior prediction of ``law``."""
    fig, axes = new_figure(1, 3, size=(11.0, 3.8))
    for ax, name in zip(axes.ravel(), preds):
        plot_prediction(ax, tests[name], preds[name], f"{law}: {name} held out")
    return fig


def rubber_fits(panels: Sequence[tuple[Any, Any, str]]) -> Figure:
    """Stress histories (1 x 3): each (test, fit result, title) as data against the fitted PRF model."""
    fig, axes = new_figure(1, 3, size=(12.0, 3.8))
    for ax, (t, r, title) in zip(axes.ravel(), panels):
        model = simulate(r.params, t.time, t.stretch).nominal
        ax.plot(t.time, t.stress, lw=0.8, color="0.45", label="data")
        ax.plot(t.time, model, lw=0.9, color="tab:red", label="PRF fit")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("nominal stress [MPa]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return fig
