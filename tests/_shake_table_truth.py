"""A known shake-table building for the tests of the building as a gap model: plasticity isolators
under five stories, and runs cut from one simulation of it under two records with rest between
them (so the truth is known and the isolators' state is carried from run to run)."""

from __future__ import annotations

import warnings

import numpy as np

import ground_motions
import structures
from rrfrei.gap.model import IsolatorFit
from rrfrei.laws import get
from structures.building.shear_building import Isolator, ShearBuilding
from structures.shake_table import BNCS_WEIGHTS_KN, ShakeTableRun
from structures.shake_table.building_model import BuildingModel
from structures.shake_table.sequence import CHANNELS
from structures.shake_table.simulation import calibration_test, measured_channels

MASSES = np.array(BNCS_WEIGHTS_KN) / 9.81
K = np.array([125e3, 95e3, 98e3, 108e3, 60e3])
PL = dict(k_init=20000.0, qd=80.0, alpha1=0.15, alpha2=0.0, mu=2.0)
ZETA = 0.04


def runs_of(building: ShearBuilding, scales=(1.0, 1.8), seconds: float = 12.0):
    """Runs cut from ONE simulation of (record, 10 s rest, record x 1.8, ...): the isolators' state
    is carried from each run to the next, as on the shake table."""
    r = ground_motions.load("elcentro")
    n = int(seconds / r.dt)
    pad = int(round(10.0 / r.dt))
    accs = [s * np.asarray(r.accel[:n]) for s in scales]
    parts = [np.zeros(1)]
    starts = []
    for a in accs:
        if len(parts) > 1:
            parts.append(np.zeros(pad))
        starts.append(sum(p.size for p in parts))
        parts.append(a)
    resp = structures.time_history(building, ground_motions.Record("all", r.dt, np.concatenate(parts)))
    runs = []
    for i, (start, acc) in enumerate(zip(starts, accs)):
        s = slice(start, start + n)
        u0 = resp.isolator_disp[start - 1]
        f0 = resp.floor_disp[start - 1]
        runs.append(ShakeTableRun(
            name=f"run{i + 1}", time=np.arange(n) * r.dt, table_accel=acc,
            accel=np.column_stack([resp.base_accel_abs[s], resp.floor_accel_abs[s]]),
            disp=np.column_stack([resp.isolator_disp[s] - u0, resp.floor_disp[s] - f0]),
            masses=MASSES, level_names=("base", "f2", "f3", "f4", "f5", "roof")))
    return runs


def loop_start(params):
    spec = get("plasticity")
    p = spec.pack(params)
    return IsolatorFit(spec=spec, p_opt=p, P=p[None, :].repeat(2, axis=0), sig=np.ones(2), sigma=1.0,
                       noise=1.0, free=spec.param_names)


def model_of(runs, sup, start_params, draws=8):
    cal = calibration_test(runs[:1], 50.0)
    scales = {c: float(np.sqrt(np.mean(measured_channels(runs[0])[c] ** 2))) for c in CHANNELS}
    return BuildingModel("plasticity", sup, cal, scales, draws=draws, loop_fit=loop_start(start_params))


def building_and_runs():
    """(the true building, its runs ``run1`` then ``run2`` at 1.8 times the record)."""
    b = ShearBuilding(MASSES[1:], K, [4.27] * 5, ZETA, MASSES[0], Isolator("plasticity", PL))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return b, runs_of(b)
