"""Where the calibrated baseline misses: residuals split along physically meaningful axes.

Definitions (issue 7), for measured force ``y``, predicted (posterior-mean) force ``f`` and the
noise level ``sigma`` (white part of the residuals, :func:`rrfrei.gap.model.white_noise`)::

    gap        = RMS(y - f) / RMS(y)                      (NRMSE)
    systematic = sqrt(max(MSE - sigma^2, 0)) / RMS(y)

Axes of the segment table: ``amplitude`` (amplitude level of the protocol, cycles grouped by
peak |u| within 10 %), ``cycle`` (first vs repeated cycle at an amplitude), ``branch`` (loading
``u v > 0`` vs unloading), ``sign`` of u, ``|u|`` bins (quarters of max |u|), ``velocity`` bins
(terciles of |v|; absent without real time), ``energy`` bins (terciles of cumulative dissipated
energy).  Per segment: share of the total squared error, bias, RMS error over sigma, coverage of
the predictive band, and the mean relative error of the energy dissipated per cycle (for axes made
of whole cycles).  Segments are ranked by their excess error over noise ``MSE / sigma^2 - 1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from rrfrei.energy import cycle_bounds, dissipated_energy
from rrfrei.io import ShearTest

__all__ = ["gap", "systematic_gap", "segment_table", "cycle_levels", "energy_error", "Segments"]


def gap(measured, predicted) -> float:
    """NRMSE = RMS(measured - predicted) / RMS(measured)."""
    y = np.asarray(measured, dtype=float)
    f = np.asarray(predicted, dtype=float)
    return float(np.sqrt(np.mean((y - f) ** 2)) / np.sqrt(np.mean(y**2)))


def systematic_gap(measured, predicted, sigma: float) -> float:
    """sqrt(max(MSE - sigma^2, 0)) / RMS(measured)."""
    y = np.asarray(measured, dtype=float)
    f = np.asarray(predicted, dtype=float)
    mse = float(np.mean((y - f) ** 2))
    return float(np.sqrt(max(mse - sigma**2, 0.0)) / np.sqrt(np.mean(y**2)))


@dataclass(frozen=True)
class Segments:
    """Per-sample labels of a test: cycle index (-1 outside full cycles), level, first cycle."""

    cycle: np.ndarray
    level: np.ndarray  # amplitude level index (-1 outside full cycles), ordered by amplitude
    level_amp: np.ndarray  # amplitude [m] of each level
    first: np.ndarray  # bool: in the first cycle at its level


def cycle_levels(disp: np.ndarray, *, tol: float = 0.10) -> Segments:
    """Cycles of ``disp`` grouped into amplitude levels (peak |u| within ``tol``)."""
    u = np.asarray(disp, dtype=float)
    b = cycle_bounds(u)
    cyc = np.full(u.size, -1, dtype=np.int64)
    lev = np.full(u.size, -1, dtype=np.int64)
    first = np.zeros(u.size, dtype=bool)
    amps: list[float] = []
    seen: set[int] = set()
    for c, (s, e) in enumerate(b):
        a = float(np.max(np.abs(u[s: e + 1])))
        k = next((i for i, x in enumerate(amps) if abs(a - x) <= tol * max(a, x)), None)
        if k is None:
            amps.append(a)
            k = len(amps) - 1
        cyc[s: e + 1] = c
        lev[s: e + 1] = k
        first[s: e + 1] = k not in seen
        seen.add(k)
    order = np.argsort(amps) if amps else np.zeros(0, dtype=int)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    lev = np.where(lev >= 0, rank[np.clip(lev, 0, None)] if amps else lev, -1)
    return Segments(cyc, lev, np.asarray(sorted(amps)), first)


def energy_error(disp, measured, predicted, mask=None) -> float:
    """Mean relative error of the energy dissipated per full cycle (cycles inside ``mask``)."""
    u = np.asarray(disp, dtype=float)
    b = cycle_bounds(u)
    errs = []
    for s, e in b:
        if mask is not None and not np.all(mask[s: e + 1]):
            continue
        em = dissipated_energy(u[s: e + 1], measured[s: e + 1])[-1]
        ep = dissipated_energy(u[s: e + 1], predicted[s: e + 1])[-1]
        if abs(em) > 0:
            errs.append(abs(ep - em) / abs(em))
    return float(np.mean(errs)) if errs else float("nan")


def _labels(test: ShearTest, seg: Segments) -> dict[str, np.ndarray]:
    u = np.asarray(test.disp)
    y = np.asarray(test.force)
    du = np.gradient(u)
    out: dict[str, np.ndarray] = {}
    amp = np.array([f"{1e3 * a:.3g} mm" for a in seg.level_amp] + ["partial"], dtype=object)
    out["amplitude"] = amp[np.where(seg.level >= 0, seg.level, len(seg.level_amp))]
    out["cycle"] = np.where(seg.cycle < 0, "partial", np.where(seg.first, "first", "repeated")).astype(object)
    out["branch"] = np.where(u * du > 0, "loading", "unloading").astype(object)
    out["sign"] = np.where(u >= 0, "u >= 0", "u < 0").astype(object)
    um = float(np.max(np.abs(u)))
    q = np.minimum((np.abs(u) / um * 4).astype(int), 3)
    out["|u|"] = np.array([f"{25 * i}-{25 * (i + 1)} % max|u|" for i in range(4)], dtype=object)[q]
    if test.has_time:
        av = np.abs(np.gradient(u, np.asarray(test.time)))
        edges = np.quantile(av, [1 / 3, 2 / 3])
        k = np.searchsorted(edges, av, side="right")
        out["velocity"] = np.array(["slow third", "middle third", "fast third"], dtype=object)[k]
    e = dissipated_energy(u, y)
    edges = np.quantile(e, [1 / 3, 2 / 3])
    k = np.searchsorted(edges, e, side="right")
    out["energy"] = np.array(["early third", "middle third", "late third"], dtype=object)[k]
    return out


def segment_table(test: ShearTest, mean, lower, upper, sigma: float) -> pd.DataFrame:
    """Segment table of the residuals ``test.force - mean`` (columns in the module docstring).

    Returns a DataFrame with columns ``axis, segment, n, error_share, bias, rms_over_noise,
    excess, coverage, energy_error`` sorted by ``excess`` (descending).
    """
    y = np.asarray(test.force, dtype=float)
    f = np.asarray(mean, dtype=float)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    if not (f.shape == lo.shape == hi.shape == y.shape):
        raise ValueError(f"mean, lower and upper must have the test's {y.size} samples")
    if not sigma > 0:
        raise ValueError(f"sigma must be > 0, got {sigma!r}")
    r = y - f
    sse = float(r @ r)
    seg = cycle_levels(test.disp)
    rows = []
    for axis, lab in _labels(test, seg).items():
        for name in pd.unique(lab):
            m = lab == name
            rm = r[m]
            mse = float(np.mean(rm**2))
            cyc_axis = axis in ("amplitude", "cycle")
            rows.append({
                "axis": axis, "segment": str(name), "n": int(m.sum()),
                "error_share": float(rm @ rm) / sse if sse > 0 else 0.0,
                "bias": float(rm.mean()),
                "rms_over_noise": float(np.sqrt(mse)) / sigma,
                "excess": mse / sigma**2 - 1.0,
                "coverage": float(np.mean((y[m] >= lo[m]) & (y[m] <= hi[m]))),
                "energy_error": energy_error(test.disp, y, f, m) if cyc_axis else float("nan"),
            })
    return pd.DataFrame(rows).sort_values("excess", ascending=False, ignore_index=True)
