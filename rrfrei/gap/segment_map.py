"""The segment table of a gap diagnosis as a heat map coloured by concern, not by rank.

Each cell keeps its value as text; its colour is a *concern* in [0, 1] on a fixed scale per
column, so that calm (pale) means "as a good model would show" and alarming (dark red) means
"far from it", whatever the other segments do:

=====================  ======================================  ===========================
column                 calm (concern 0)                         alarming (concern 1)
=====================  ======================================  ===========================
error share            no more than the segment's share of      3 x its share of points
                       the points (n / n of its axis)
RMS / noise            the noise level (ratio 1)                3 x the noise
coverage               the nominal 95 %                          50 % or less
energy error           0 (absolute value)                        30 % or more
=====================  ======================================  ===========================

Concern rises linearly in between and is clipped to [0, 1]; an undefined value (the energy
error of a segment without a full cycle) is drawn grey and written ``n/a``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["COLUMNS", "CMAP", "concern", "draw_segment_map"]

#: (column of the segment table, tick label stating the alarm level).
COLUMNS = (
    ("error_share", "error share\n(alarm: 3x its points)"),
    ("rms_over_noise", "RMS / noise\n(alarm: 3)"),
    ("coverage", "band coverage\n(alarm: 50 %)"),
    ("energy_error", "|energy error|\n(alarm: 30 %)"),
)

CMAP = "YlOrRd"
"""Sequential map: pale yellow (concern 0, calm) to dark red (concern 1, alarming)."""

NOMINAL_COVERAGE = 0.95


def concern(where: pd.DataFrame) -> np.ndarray:
    """(segments, 4) concern in [0, 1] of the columns in :data:`COLUMNS` (NaN where undefined).

    ``where`` is the segment table (columns ``axis``, ``n``, ``error_share``, ``rms_over_noise``,
    ``coverage``, ``energy_error``; :func:`rrfrei.gap.residuals.segment_table`).
    """
    n = where["n"].to_numpy(float)
    n_axis = where.groupby("axis")["n"].transform("sum").to_numpy(float)
    point_share = np.divide(n, n_axis, out=np.full_like(n, np.nan), where=n_axis > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        share_ratio = where["error_share"].to_numpy(float) / point_share
        cols = [
            (share_ratio - 1.0) / 2.0,
            (where["rms_over_noise"].to_numpy(float) - 1.0) / 2.0,
            (NOMINAL_COVERAGE - where["coverage"].to_numpy(float)) / (NOMINAL_COVERAGE - 0.5),
            np.abs(where["energy_error"].to_numpy(float)) / 0.3,
        ]
    c = np.column_stack(cols)
    return np.where(np.isfinite(c), np.clip(c, 0.0, 1.0), np.nan)


def draw_segment_map(fig, ax, where: pd.DataFrame) -> None:
    """Draw the segment table on ``ax`` (values as text, colour = :func:`concern`) with a
    labelled colour bar on ``fig``."""
    from matplotlib import colormaps

    vals = where[[c for c, _ in COLUMNS]].to_numpy(dtype=float)
    conc = concern(where)
    cmap = colormaps[CMAP].with_extremes(bad="0.85")
    im = ax.imshow(np.ma.masked_invalid(conc), aspect="auto", cmap=cmap, vmin=0.0, vmax=1.0)
    ax.set_yticks(range(len(where)), [f"{a}: {s}" for a, s in zip(where["axis"], where["segment"])],
                  fontsize=6)
    ax.set_xticks(range(len(COLUMNS)), [lab for _, lab in COLUMNS], fontsize=6)
    for i in range(vals.shape[0]):
        for j in range(vals.shape[1]):
            v, c = vals[i, j], conc[i, j]
            text = f"{v:.2g}" if math.isfinite(v) else "n/a"
            ax.text(j, i, text, ha="center", va="center", fontsize=6,
                    color="white" if math.isfinite(c) and c > 0.6 else "black")
    cb = fig.colorbar(im, ax=ax, ticks=[0.0, 0.5, 1.0])
    cb.ax.set_yticklabels(["0 calm", "0.5", "1 alarming"], fontsize=6)
    cb.set_label("concern (0: noise level, 95 % coverage; 1: at the alarm level of its column)",
                 fontsize=6)
    ax.set_title("segments ranked by excess error over noise\n(colour: concern on a fixed scale; "
                 "grey: not defined)", fontsize=8)
