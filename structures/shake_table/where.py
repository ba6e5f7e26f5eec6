"""Where a building's prediction of held-out shake-table runs misses: the residual table by run,
channel, amplitude, time window and frequency band (issues 15 and 27)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from rrfrei.calibration.checks import nrmse
from structures.shake_table.sequence import CHANNELS, SequencePrediction

__all__ = ["BANDS_HZ", "COMPONENT", "residual_table"]

COMPONENT = {"isolator_disp": "isolator", "isolator_force": "isolator", "base_shear": "superstructure",
             "roof_accel": "superstructure"}
"""Which part of the building a channel reads first."""

BANDS_HZ = ((0.0, 0.3), (0.3, 1.0), (1.0, 3.0), (3.0, 10.0), (10.0, math.inf))
"""Frequency bands of the residual table [Hz] (isolation mode ~0.4 Hz, superstructure 1.5-10 Hz)."""

def residual_table(pred: SequencePrediction, runs: Sequence[str], calibrated_peak: float, *,
                   window_s: float = 10.0) -> pd.DataFrame:
    """Where the prediction of ``runs`` misses: one row per (axis, segment) with ``run``,
    ``channel``, ``n`` samples, ``error_share`` (share of the channel's squared error over
    ``runs``, normalised by the channel's measured RMS so channels compare) and ``nrmse`` of the
    segment.  Axes: ``run``, ``channel``, ``amplitude`` (|d_0| within or beyond the calibrated
    peak), ``time window`` (``window_s`` s, the worst 5 per run and channel) and ``frequency``
    (:data:`BANDS_HZ`, share of the residual's power)."""
    rows = []
    for c in CHANNELS:
        rms = float(np.sqrt(np.mean(np.concatenate([pred.measured[r][c] for r in runs]) ** 2))) or 1.0
        tot = float(sum(np.sum(((pred.measured[r][c] - pred.median[r][c]) / rms) ** 2) for r in runs)) or 1.0
        rows.append({"axis": "channel", "segment": f"{c} ({COMPONENT[c]})", "run": "all", "channel": c,
                     "n": int(sum(pred.measured[r][c].size for r in runs)),
                     "error_share": 1.0, "nrmse": pred.nrmse(runs)[c]})
        for r in runs:
            m, p, t = pred.measured[r][c], pred.median[r][c], pred.time[r]
            e = ((m - p) / rms) ** 2
            if len(runs) > 1:
                rows.append({"axis": "run", "segment": r, "run": r, "channel": c, "n": int(m.size),
                             "error_share": float(e.sum() / tot), "nrmse": float(nrmse(m, p))})
            d = np.abs(pred.measured[r]["isolator_disp"])
            for lab, sel in ((f"|d0| <= {calibrated_peak:.3f} m (calibrated)", d <= calibrated_peak),
                             (f"|d0| > {calibrated_peak:.3f} m (beyond)", d > calibrated_peak)):
                if sel.any():
                    rows.append({"axis": "amplitude", "segment": lab, "run": r, "channel": c,
                                 "n": int(sel.sum()), "error_share": float(e[sel].sum() / tot),
                                 "nrmse": float(nrmse(m[sel], p[sel])) if np.any(m[sel] != 0) else math.nan})
            wins = []
            for w0 in np.arange(0.0, float(t[-1]) + 1e-9, window_s):
                sel = (t >= w0) & (t < w0 + window_s)
                if sel.sum() > 1:
                    wins.append({"axis": "time window", "segment": f"{w0:.0f}-{w0 + window_s:.0f} s",
                                 "run": r, "channel": c, "n": int(sel.sum()),
                                 "error_share": float(e[sel].sum() / tot),
                                 "nrmse": float(nrmse(m[sel], p[sel])) if np.any(m[sel] != 0) else math.nan})
            rows.extend(sorted(wins, key=lambda x: -x["error_share"])[:5])
            res = m - p
            spec = np.abs(np.fft.rfft(res)) ** 2
            f = np.fft.rfftfreq(res.size, d=float(t[1] - t[0]))
            share_run = float(e.sum() / tot)
            ps = float(spec.sum()) or 1.0
            for lo, hi in BANDS_HZ:
                sel = (f >= lo) & (f < hi)
                if sel.any():
                    lab = f"{lo:g}-{hi:g} Hz" if math.isfinite(hi) else f"> {lo:g} Hz"
                    rows.append({"axis": "frequency", "segment": lab, "run": r, "channel": c,
                                 "n": int(sel.sum()), "nrmse": math.nan,
                                 "error_share": share_run * float(spec[sel].sum()) / ps})
    df = pd.DataFrame(rows)
    order = {"channel": 0, "run": 1, "amplitude": 2, "frequency": 3, "time window": 4}
    df["_o"] = df["axis"].map(order)
    return df.sort_values(["_o", "channel", "error_share"], ascending=[True, True, False]) \
        .drop(columns="_o").reset_index(drop=True)

