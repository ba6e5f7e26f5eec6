"""The isolation system of a shake-table run: the force the whole isolator layer applies to the
building, F_iso = -sum_i m_i a_i, against the isolator displacement, as a shear test and per
cycle."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from rrfrei.energy import cycle_metrics
from rrfrei.io import ShearTest
from structures.shake_table.run import ShakeTableRun

__all__ = ["isolation_metrics", "isolation_test"]


def isolation_test(run: ShakeTableRun, *, name: str | None = None):
    """The isolation system of ``run`` as a :class:`rrfrei.io.ShearTest`.

    disp = isolator displacement d_0 [m] (base slab relative to the table); force =
    F_iso = -sum_i m_i a_i [kN] over every level above the isolators (base slab included), the
    force the whole isolation layer applies to the building (all bearings together, their
    viscous part included); time [s].  ``rrfrei.calibrate``, ``compare`` and ``diagnose_gap``
    take it unchanged; a law calibrated on it is the *layer* law (count 1, length scale 1).
    """
    return ShearTest(
        name=name or run.name,
        time=np.asarray(run.time) - float(run.time[0]),
        disp=run.isolator_disp,
        force=run.isolator_force,
        has_time=True,
        source=run.source,
        meta={"run": run.name, "force": "-sum_i m_i a_i (all levels above the isolators)",
              "masses_t": [float(x) for x in run.masses], "rate_hz": run.rate_hz},
    )


def _zero_cross_force(u: np.ndarray, f: np.ndarray, i: int) -> float:
    """Force at the zero crossing of u between samples i and i+1 (linear interpolation)."""
    du = u[i + 1] - u[i]
    w = 0.0 if du == 0 else -u[i] / du
    return float(f[i] + w * (f[i + 1] - f[i]))


def isolation_metrics(run: ShakeTableRun, *, eps_frac: float = 0.02) -> pd.DataFrame:
    """Per-cycle metrics of the isolation system of ``run``.

    The columns of :func:`rrfrei.energy.cycle_metrics` (energy EDC [kN m], d+/d- [m], F+/F- [kN],
    k_eff = (F+ - F-)/(d+ - d-) [kN/m], beta_eff = EDC / (2 pi k_eff d^2)) plus ``qd`` [kN], the
    characteristic strength, half the gap between the loading and unloading branches at zero
    displacement: Qd = (F(u = 0, u rising) - F(u = 0, u falling)) / 2, and ``run``.
    """
    u = run.isolator_disp
    f = run.isolator_force
    df = cycle_metrics(u, f, eps_frac=eps_frac)
    qd = []
    for s, e in zip(df["start"], df["end"]):
        f_up = _zero_cross_force(u, f, s) if s + 1 < u.size and u[s] <= 0 < u[s + 1] else float(f[s])
        seg = u[s:e + 1]
        down = np.flatnonzero((seg[:-1] > 0) & (seg[1:] <= 0))
        qd.append(0.5 * (f_up - _zero_cross_force(u, f, s + int(down[0]))) if down.size else math.nan)
    df["qd"] = qd
    df.insert(0, "run", run.name)
    return df
