"""Cycle detection, dissipated energy and per-cycle isolator metrics (the one definition).

Every later analysis (calibration summaries, gap diagnosis, time histories, the report) uses
these functions, so "a cycle", "the energy of a cycle", ``k_eff`` and ``beta_eff`` mean the same
thing everywhere.

Units: displacement [m], force [kN], energy [kN*m] (= kJ), stiffness [kN/m].

Cycles
------
A cycle runs from one upward zero crossing of the displacement to the next.  Crossings are
detected with a hysteresis band ``eps = eps_frac * max|u|`` so that measurement noise around zero
does not create spurious cycles: an upward crossing counts only after the signal has gone below
``-eps`` and then above ``+eps``; its index is whichever of the last sample at or below zero
(before the signal first exceeds ``+eps``) and the sample after it is closer to zero.

A history that *starts* at rest (``|u[0]| <= eps``) is treated as if it had just crossed zero
upward at sample 0, and a history that *ends* at rest (``|u[-1]| <= eps``) after having gone
below ``-eps`` is closed at its last sample.  So a test made of full cycles from zero to zero
(the FEMA 450-style protocols) gives all its cycles.  Any other part before the first or after
the last crossing is not a full cycle and is left out of :func:`cycle_bounds` and
:func:`cycle_metrics`; it still counts in the cumulative :func:`dissipated_energy`.

Per-cycle metrics (as isolator test reports state them, e.g. ASCE 7 / EN 15129)
-------------------------------------------------------------------------------
With ``d+``, ``d-`` the maximum and minimum displacement of the cycle and ``F+``, ``F-`` the
forces at those samples::

    k_eff    = (F+ - F-) / (d+ - d-)
    d        = (d+ - d-) / 2
    beta_eff = EDC / (2 pi k_eff d^2)

with EDC the energy dissipated in the cycle, the trapezoidal integral of F du over it.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from rrfrei._inputs import as_history

__all__ = ["cycle_bounds", "dissipated_energy", "cycle_metrics", "cycle_metrics_batch", "METRIC_COLUMNS"]

METRIC_COLUMNS = ("cycle", "start", "end", "energy", "d_pos", "d_neg", "f_pos", "f_neg", "k_eff",
                  "beta_eff")
"""Columns of :func:`cycle_metrics` (energy [kN*m], d [m], f [kN], k_eff [kN/m], beta_eff [-])."""


def _as_1d(values, name: str, min_len: int = 2) -> np.ndarray:
    return as_history(values, name, min_len=min_len)


def _pair(disp, force) -> tuple[np.ndarray, np.ndarray]:
    u = _as_1d(disp, "disp")
    f = _as_1d(force, "force")
    if u.size != f.size:
        raise ValueError(f"disp has {u.size} values but force has {f.size}")
    return u, f


def cycle_bounds(disp, *, eps_frac: float = 0.02) -> np.ndarray:
    """Start and end sample indices of the full displacement cycles.

    Parameters
    ----------
    disp : (n,) displacement history [m].
    eps_frac : half-width of the hysteresis band around zero as a fraction of ``max|disp|``
        (0 < eps_frac < 1).  It must exceed the noise amplitude near zero.

    Returns
    -------
    (n_cycles, 2) int64 array; row i is ``[start, end]`` (both inclusive), and ``end`` of one
    cycle is ``start`` of the next.  Empty (shape (0, 2)) when there is no full cycle.

    Notes
    -----
    See the module docstring for the crossing rule and the treatment of the partial cycles
    before the first and after the last crossing.
    """
    u = _as_1d(disp, "disp")
    if not (0.0 < eps_frac < 1.0):
        raise ValueError(f"eps_frac must be in (0, 1), got {eps_frac!r}")
    amp = float(np.max(np.abs(u)))
    if amp == 0.0:
        return np.zeros((0, 2), dtype=np.int64)
    eps = eps_frac * amp
    crossings: list[int] = []
    armed = abs(u[0]) <= eps  # starting at rest counts as having just been below the band
    last_nonpos = 0  # last sample at or below zero (sample 0 when starting at rest above zero)
    for i in range(u.size):
        x = u[i]
        if x <= 0.0:
            last_nonpos = i
        if x < -eps:
            armed = True
        elif armed and x > eps:
            j = last_nonpos
            crossings.append(j + 1 if abs(u[j + 1]) < abs(u[j]) else j)
            armed = False
    # A history ending at rest after a negative excursion is closed at its last sample.
    # (With at least one crossing, ``armed`` means the signal went below -eps since the last one.)
    if armed and crossings and abs(u[-1]) <= eps:
        crossings.append(u.size - 1)
    if len(crossings) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    c = np.asarray(crossings, dtype=np.int64)
    return np.column_stack([c[:-1], c[1:]])


def dissipated_energy(disp, force) -> np.ndarray:
    """Cumulative energy dissipated (work done on the bearing) [kN*m].

    ``E[k] = sum_{i<k} (F[i] + F[i+1]) / 2 * (u[i+1] - u[i])`` (trapezoidal rule), ``E[0] = 0``.
    Over a closed cycle this is the area of the hysteresis loop; for a polygon inscribed in an
    ellipse it is exact (see the tests).
    """
    u, f = _pair(disp, force)
    return _cumulative_work(u, f[None, :])[0]


def _cumulative_work(u: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The trapezoidal cumulative work of :func:`dissipated_energy` for every row of ``F``."""
    out = np.empty_like(F)
    out[:, 0] = 0.0
    np.cumsum(0.5 * (F[:, 1:] + F[:, :-1]) * np.diff(u), axis=1, out=out[:, 1:])
    return out


def cycle_metrics(disp, force, *, eps_frac: float = 0.02) -> pd.DataFrame:
    """Per-cycle energy, peak displacements and forces, effective stiffness and damping.

    Parameters
    ----------
    disp : (n,) displacement [m].
    force : (n,) force [kN].
    eps_frac : see :func:`cycle_bounds`.

    Returns
    -------
    DataFrame with one row per full cycle and columns :data:`METRIC_COLUMNS`: ``cycle`` (0-based),
    ``start``/``end`` sample indices, ``energy`` EDC [kN*m], ``d_pos``/``d_neg`` [m],
    ``f_pos``/``f_neg`` forces at those samples [kN], ``k_eff`` [kN/m], ``beta_eff`` [-].
    ``k_eff`` is NaN for a cycle with d+ == d-, ``beta_eff`` NaN when k_eff d^2 == 0.
    """
    u, f = _pair(disp, force)
    bounds = cycle_bounds(u, eps_frac=eps_frac)
    ip, im = _cycle_peaks(u, bounds)
    m = _cycle_arrays(u, f[None, :], bounds, ip, im)
    df = pd.DataFrame({
        "cycle": np.arange(len(bounds), dtype=np.int64), "start": bounds[:, 0], "end": bounds[:, 1],
        "energy": m["energy"][0], "d_pos": u[ip], "d_neg": u[im], "f_pos": f[ip], "f_neg": f[im],
        "k_eff": m["k_eff"][0], "beta_eff": m["beta_eff"][0],
    }, columns=list(METRIC_COLUMNS))
    return df.astype({"cycle": np.int64, "start": np.int64, "end": np.int64})


def cycle_metrics_batch(disp, forces, *, eps_frac: float = 0.02) -> dict[str, np.ndarray]:
    """Per-cycle ``energy`` [kN*m], ``k_eff`` [kN/m] and ``beta_eff`` [-] of every row of
    ``forces`` (rows, n) [kN] along one displacement history ``disp`` (n,) [m].

    The values of :func:`cycle_metrics` for each row, computed for all rows at once (the cycles
    and their peak samples depend on the displacement only).  Returns arrays (rows, cycles).
    """
    u = _as_1d(disp, "disp")
    F = np.atleast_2d(np.asarray(forces, dtype=float))
    if F.shape[1] != u.size:
        raise ValueError(f"disp has {u.size} values but forces have {F.shape[1]} per row")
    bounds = cycle_bounds(u, eps_frac=eps_frac)
    ip, im = _cycle_peaks(u, bounds)
    return _cycle_arrays(u, F, bounds, ip, im)


def _cycle_peaks(u: np.ndarray, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples of the largest and smallest displacement of each cycle (the first of ties)."""
    ip = np.array([s + int(np.argmax(u[s:e + 1])) for s, e in bounds], dtype=np.int64)
    im = np.array([s + int(np.argmin(u[s:e + 1])) for s, e in bounds], dtype=np.int64)
    return ip, im


def _cycle_arrays(u, F, bounds, ip, im) -> dict[str, np.ndarray]:
    """EDC, k_eff = (F+ - F-) / (d+ - d-) and beta_eff = EDC / (2 pi k_eff d^2), d = (d+ - d-) / 2,
    per row of ``F`` and cycle; NaN where d+ == d- or k_eff d^2 == 0."""
    energy = _cumulative_work(u, F)
    edc = energy[:, bounds[:, 1]] - energy[:, bounds[:, 0]]
    dp, dm = u[ip], u[im]
    span = dp - dm
    with np.errstate(divide="ignore", invalid="ignore"):
        k_eff = np.where(span != 0.0, (F[:, ip] - F[:, im]) / np.where(span != 0.0, span, 1.0), np.nan)
        d = 0.5 * (dp - dm)
        denom = 2.0 * math.pi * k_eff * d * d
        beta = np.where(np.isfinite(denom) & (denom != 0.0), edc / np.where(denom != 0.0, denom, 1.0), np.nan)
    return {"energy": edc, "k_eff": k_eff, "beta_eff": beta}
