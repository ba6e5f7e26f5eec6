"""Posterior propagation on the plan building under pairs of records (both components at once).

:func:`propagate_pairs` is :func:`structures.propagation.propagate.propagate` for record *pairs*: every
posterior draw runs the plan building (:func:`structures.plan_time_history`, the isolator a
coupled plan law of :mod:`rrfrei.laws.plan`) under both horizontal components of every pair at
every scale.  It reuses propagate's machinery (posterior vs. building checks, deterministic
chunks, executors, the resumable Parquet store, :class:`~structures.propagation.responses.ResponseSet`), so
the summaries, exceedance, fragility and plots work unchanged.  The table's columns:

* the ResponseSet columns, with their plan meaning: ``iso_disp_peak_m`` is the maximum **plan**
  isolator displacement (vector sum, ASCE 7-22 section 17.6), ``iso_disp_residual_m`` the plan
  displacement at the end, ``drift_ratio_max`` / ``floor_acc_max_ms2`` the largest of both
  directions, ``base_shear_peak_kN`` the larger of the two directions' peak base shears,
  ``iso_energy_kNm`` the isolator's work (line integral of F . du in plan);
* per direction: ``iso_disp_x_peak_m``, ``iso_disp_y_peak_m``, ``drift_ratio_x_max``,
  ``drift_ratio_y_max``, ``floor_acc_x_max_ms2``, ``floor_acc_y_max_ms2``,
  ``base_shear_x_peak_kN``, ``base_shear_y_peak_kN``;
* ``total_max_disp_m``: the plan displacement times the optional torsional amplification
  (:class:`structures.propagation.plan_design.TorsionAmplification`; 1 when not given: no torsion).

:func:`suite_design` turns the table into the code's design values over the suite per draw (the
average for 7 or more pairs, the maximum for fewer) and :func:`design_distribution` their
percentiles over the posterior draws.

Units: m, s, kN, tonnes; accelerations m/s^2; drift ratios dimensionless.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from rrfrei.gap.design import bound_params
from rrfrei.laws import get as get_law
from structures.dynamics.plan_history import plan_time_history_batch
from structures.propagation.executors import set_threads
from structures.propagation.inputs import resolve_building, resolve_scales
from structures.propagation.plan_design import (
    ANSWERS,
    TorsionAmplification,
    check_plan_law,
    plan_arrays,
    resolve_pairs,
    suite_rule,
    suite_value,
    torsion_factor,
)
from structures.propagation.propagate import (
    check_run_options,
    input_fingerprint,
    make_chunks,
    prepare_run,
    response_set,
    run_chunks,
)
from structures.propagation.responses import ResponseSet, extrapolated
from structures.propagation.summaries import QUANTILES

__all__ = ["ANSWER_COLUMNS", "check_plan_law", "design_distribution", "propagate_pairs", "resolve_pairs",
           "run_plan_chunk", "suite_design"]

ANSWER_COLUMNS = {
    "plan_disp_max_m": "iso_disp_peak_m",
    "disp_x_max_m": "iso_disp_x_peak_m",
    "disp_y_max_m": "iso_disp_y_peak_m",
    "total_max_disp_m": "total_max_disp_m",
    "base_shear_x_max_kN": "base_shear_x_peak_kN",
    "base_shear_y_max_kN": "base_shear_y_peak_kN",
}
"""The code's answers (:data:`structures.propagation.plan_design.ANSWERS`) -> their column in the table."""


# ----------------------------------------------------------------------------- the task
def run_plan_chunk(building, pair, scale: float, params: np.ndarray, simulate: Callable | None = None,
                   threads: int | None = None) -> dict:
    """Run the draws ``params`` (m, n_params) on ``pair`` x ``scale``: dict of per-run arrays.

    By default all draws run at once in :func:`structures.plan_time_history_batch` (threads
    over blocks of draws; a run that fails holds NaN demands and ``converged`` False).  With ``simulate``
    (``simulate(building, law, params, ground) -> plan response``) each draw is one call, read by
    :func:`structures.propagation.plan_design.plan_arrays`; a ``RuntimeError`` (e.g.
    :class:`structures.ConvergenceError`) marks the run as not converged.
    """
    set_threads(threads)
    ground = pair if scale == 1.0 else pair.scaled(scale)
    P = np.ascontiguousarray(np.atleast_2d(np.asarray(params, dtype=float)))
    if simulate is None:
        res = plan_time_history_batch(building, None, P, ground)
        return {
            "plan": res["iso_plan_disp_peak"], "residual": res["iso_plan_disp_residual"],
            "x": res["iso_disp_peak"][:, 0], "y": res["iso_disp_peak"][:, 1],
            "shear_x": res["base_shear_peak"][:, 0], "shear_y": res["base_shear_peak"][:, 1],
            "drift_x": res["drift_peak"][:, 0, :], "drift_y": res["drift_peak"][:, 1, :],
            "acc_x": res["floor_acc_peak"][:, 0, :], "acc_y": res["floor_acc_peak"][:, 1, :],
            "energy": res["iso_energy"], "energy_error": res["energy_error"],
            "converged": np.asarray(res["converged"], dtype=bool),
        }
    spec = get_law(building.isolator.law)
    m, ns = P.shape[0], building.n_stories
    nan = np.full(m, np.nan)
    out = {k: nan.copy() for k in ("plan", "x", "y", "residual", "shear_x", "shear_y", "energy",
                                   "energy_error")}
    for k in ("drift_x", "drift_y", "acc_x", "acc_y"):
        out[k] = np.full((m, ns), np.nan)
    out["converged"] = np.zeros(m, dtype=bool)
    for i in range(m):
        try:
            resp = simulate(building, spec.name, spec.as_dict(P[i]), ground)
        except RuntimeError:
            continue
        a = plan_arrays(resp)
        u, v = a["isolator_disp"], a["base_shear"]
        r = np.hypot(u[:, 0], u[:, 1])
        out["plan"][i] = r.max()
        out["x"][i], out["y"][i] = np.abs(u).max(axis=0)
        out["residual"][i] = r[-1]
        out["shear_x"][i], out["shear_y"][i] = np.abs(v).max(axis=0)
        for key, name in (("drift", "drift_ratio"), ("acc", "floor_accel_abs")):
            if name in a:
                peak = np.abs(a[name]).max(axis=0)  # (stories, 2)
                out[f"{key}_x"][i], out[f"{key}_y"][i] = peak[:, 0], peak[:, 1]
        if "iso_energy" in a:
            out["energy"][i] = a["iso_energy"][-1]
        if "energy_error" in a:
            out["energy_error"][i] = float(a["energy_error"])
        out["converged"][i] = True
    return out


def plan_chunk_table(out: dict, samples: np.ndarray, record: str, scale: float, d_max: float | None,
                     length_scale: float, torsion_factor: float = 1.0) -> pd.DataFrame:
    """Tidy rows of one chunk (columns in the module docstring)."""
    n = samples.size
    cols = {"sample": samples.astype(np.int64), "record": [record] * n, "scale": np.full(n, scale)}
    cols["iso_disp_peak_m"] = out["plan"]
    cols["iso_disp_x_peak_m"] = out["x"]
    cols["iso_disp_y_peak_m"] = out["y"]
    cols["total_max_disp_m"] = out["plan"] * torsion_factor
    cols["iso_disp_residual_m"] = out["residual"]
    for j in range(out["drift_x"].shape[1]):
        cols[f"drift_ratio_x_s{j + 1}"] = out["drift_x"][:, j]
        cols[f"drift_ratio_y_s{j + 1}"] = out["drift_y"][:, j]
    cols["drift_ratio_x_max"] = out["drift_x"].max(axis=1)
    cols["drift_ratio_y_max"] = out["drift_y"].max(axis=1)
    cols["drift_ratio_max"] = np.fmax(cols["drift_ratio_x_max"], cols["drift_ratio_y_max"])
    cols["floor_acc_x_max_ms2"] = out["acc_x"].max(axis=1)
    cols["floor_acc_y_max_ms2"] = out["acc_y"].max(axis=1)
    cols["floor_acc_max_ms2"] = np.fmax(cols["floor_acc_x_max_ms2"], cols["floor_acc_y_max_ms2"])
    cols["base_shear_x_peak_kN"] = out["shear_x"]
    cols["base_shear_y_peak_kN"] = out["shear_y"]
    cols["base_shear_peak_kN"] = np.fmax(out["shear_x"], out["shear_y"])
    cols["iso_energy_kNm"] = out["energy"]
    cols["energy_error"] = out["energy_error"]
    ok = np.asarray(out["converged"], dtype=bool)
    cols["converged"] = ok
    # (a failed run's largest displacement is unknown)
    cols["extrapolated"] = extrapolated(np.asarray(out["plan"], dtype=float), d_max, length_scale, ~ok)
    return pd.DataFrame(cols)


# ----------------------------------------------------------------------------- the workflow
def propagate_pairs(
    posterior,
    building,
    pairs,
    *,
    n_samples: int = 200,
    scales: Sequence[float] | float = (1.0,),
    seed: int = 0,
    executor=None,
    store: str | os.PathLike | None = None,
    progress: bool = True,
    limits: Mapping[str, float] | None = None,
    chunk_size: int = 50,
    lam: float = 1.0,
    torsion: TorsionAmplification | None = None,
    simulate: Callable | None = None,
) -> ResponseSet:
    """Run posterior draws of the isolator law through the plan building under record pairs.

    Parameters are those of :func:`structures.propagation.propagate.propagate`, except:

    pairs
        Record pairs (see :func:`resolve_pairs`): bundled pair names, ``"A.AT2+B.AT2"``, or
        pair objects; each scale multiplies both components (one factor per pair, as the code
        scales pairs).
    lam
        Property modification factor applied to every draw (:func:`rrfrei.gap.design.bound_params`:
        force-like parameters x lam): 1 for the nominal properties, lambda_min / lambda_max for
        the lower- / upper-bound analyses.  Part of the store's identity.
    torsion
        Corner-bearing amplification of ``total_max_disp_m`` (None: no torsion, the column equals
        the plan displacement at the centre).
    simulate
        ``simulate(building, law, params, pair) -> plan response`` (default
        :func:`structures.plan_time_history`); must be picklable to run on an executor.

    Returns
    -------
    ResponseSet whose ``records`` are the pair names and whose table has the plan columns of the
    module docstring.
    """
    check_run_options(n_samples, chunk_size, seed, executor)
    n_samples, chunk_size, seed = int(n_samples), int(chunk_size), int(seed)
    if isinstance(scales, (int, float)):
        scales = (scales,)
    scale_values = resolve_scales(scales)
    bld = resolve_building(building)
    law = check_plan_law(bld.isolator.law)
    recs = resolve_pairs(pairs)
    lam = float(lam)
    if not (math.isfinite(lam) and lam > 0.0):
        raise ValueError(f"lam = {lam!r} is invalid: expected a finite property modification factor > 0")
    factor = torsion_factor(torsion)
    run = prepare_run(posterior, bld, n_samples, seed, limits)
    if lam != 1.0:  # the bound analyses: every draw's force-like parameters x lam
        spec = get_law(law)
        run = dataclasses.replace(run, params=np.ascontiguousarray(np.array(
            [spec.pack(bound_params(law, spec.as_dict(row), lam)) for row in run.params], dtype=float)))
        run.notes.append(f"isolator properties x {lam:g} (property modification factor)")
    params = run.params
    description = {
        "bidirectional": True,
        "law": run.law,
        "building": run.building_name,
        "records": [str(r.name) for r in recs],
        "scales": list(scale_values),
        "n_samples": n_samples,
        "seed": seed,
        "chunk_size": chunk_size,
        "lambda": repr(lam),
        "torsion_factor": repr(factor),
        "simulate": "plan_time_history" if simulate is None else getattr(simulate, "__qualname__",
                                                                         repr(simulate)),
    }
    fingerprint = input_fingerprint(description, bld, params, recs)

    def task_args(chunk):
        _, ri, s, a, b = chunk
        return (bld, recs[ri], s, params[a:b], simulate)

    def rows(chunk, out):
        _, ri, s, a, b = chunk
        return plan_chunk_table(out, np.arange(a, b), str(recs[ri].name), s, run.d_max,
                                run.length_scale, factor)

    table = run_chunks(make_chunks(len(recs), scale_values, n_samples, chunk_size), run_plan_chunk,
                       task_args, rows, executor=executor, store=store, fingerprint=fingerprint,
                       description=description, progress=progress)
    run.notes.append("plan building without torsion: total_max_disp_m is the plan displacement at the "
                     "centre" if torsion is None else
                     f"total_max_disp_m = plan displacement x {factor:.4g} (torsional amplification)")
    return response_set(run, table, tuple(str(r.name) for r in recs), scale_values, seed,
                        "intensity (pair scale factor) [-]", {str(r.name): 1.0 for r in recs},
                        stacklevel=3)


# ----------------------------------------------------------------------------- the suite
def suite_design(rs: ResponseSet, answers: Sequence[str] = ANSWERS) -> pd.DataFrame:
    """The code's design value over the suite of pairs, per (scale, draw).

    For each answer (:data:`structures.propagation.plan_design.ANSWERS`, read from the column
    :data:`ANSWER_COLUMNS`), the pairs' values of one draw combine by
    :func:`structures.propagation.plan_design.suite_value`: the average for 7 or more pairs, the maximum for
    fewer.  A draw that did not converge on some pair has NaN design values.

    Returns columns ``scale, sample, rule, n_pairs`` and the answers.
    """
    for a in answers:
        if a not in ANSWER_COLUMNS:
            raise ValueError(f"unknown answer {a!r}; expected one of {', '.join(ANSWER_COLUMNS)}")
    t = rs.table.copy()
    for a in answers:
        t.loc[~t["converged"].astype(bool), ANSWER_COLUMNS[a]] = np.nan
    n_pairs = len(rs.records)
    rows = []
    for (scale, sample), g in t.groupby(["scale", "sample"], sort=True):
        row = {"scale": float(scale), "sample": int(sample), "rule": suite_rule(n_pairs), "n_pairs": n_pairs}
        for a in answers:
            x = g[ANSWER_COLUMNS[a]].to_numpy(float)
            row[a] = suite_value(x) if x.size == n_pairs else math.nan
        rows.append(row)
    return pd.DataFrame(rows, columns=["scale", "sample", "rule", "n_pairs", *answers])


def design_distribution(rs: ResponseSet, answers: Sequence[str] = ANSWERS) -> pd.DataFrame:
    """Percentiles over the posterior draws of the suite design values (:func:`suite_design`).

    Returns columns ``answer, scale, rule, n`` (draws with a value), ``mean`` and the
    percentiles of :data:`structures.propagation.summaries.QUANTILES`.
    """
    d = suite_design(rs, answers)
    rows = []
    for a in answers:
        for scale, g in d.groupby("scale", sort=True):
            x = g[a].to_numpy(float)
            x = x[np.isfinite(x)]
            q = np.quantile(x, list(QUANTILES.values())) if x.size else [np.nan] * len(QUANTILES)
            rows.append({"answer": a, "scale": float(scale), "rule": g["rule"].iloc[0], "n": int(x.size),
                         "mean": float(x.mean()) if x.size else math.nan,
                         **dict(zip(QUANTILES, map(float, q)))})
    return pd.DataFrame(rows, columns=["answer", "scale", "rule", "n", "mean", *QUANTILES])
