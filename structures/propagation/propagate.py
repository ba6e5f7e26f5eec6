"""Posterior propagation: isolator parameter draws x ground motions x intensities -> demands.

:func:`propagate` draws ``n_samples`` full parameter sets from a calibrated posterior (up front,
from ``seed``), runs every draw on every record at every scale with the batched Newmark kernel
(:func:`structures.time_history_batch`, threads over blocks of the draws of a chunk), and returns a
:class:`ResponseSet`: a tidy table (one row per sample x record x scale) with summaries and plots.

Work is cut into deterministic chunks (record, scale, block of ``chunk_size`` samples).  Chunks run

* locally by default, one after the other, each over all cores (Numba threads); or
* on any ``concurrent.futures``-style ``executor`` (``.submit`` returning futures), including a
  ``dask.distributed.Client``.  Each task then sets its Numba thread count to
  ``max(1, cores // workers)`` so threads x workers never exceeds the cores (with a
  ``ProcessPoolExecutor`` prefer ``mp_context=multiprocessing.get_context("spawn")``: the OpenMP
  threading layer is not fork-safe once the parent has run a parallel kernel).

Every analysis is independent and deterministic, so the same inputs and seed give the same table
whatever runs the chunks.  With ``store=DIR`` finished chunks go to a Parquet store
(:class:`structures.propagation.store.ParquetStore`); rerunning with the same store skips them.

The pieces live in modules named for their idea: :mod:`structures.propagation.inputs` (building, records,
scales, posterior draws), :mod:`structures.propagation.executors` (where chunks run, :func:`run_chunk`),
:mod:`structures.propagation.store` (the Parquet store), :mod:`structures.propagation.responses`
(:class:`ResponseSet` and its figures).  This module is the workflow; it re-exports their public
names, so ``from structures.propagation.propagate import ResponseSet, SpectrumScaling`` works.

Units: m, s, kN, tonnes; accelerations m/s^2; drift ratios dimensionless.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ground_motions import scale_to_spectrum
from rrfrei.laws import get as get_law
from structures.building.specimen import SpecimenWarning, specimen_checks
from structures.propagation.executors import as_completed, run_chunk, submit, workers
from structures.propagation.inputs import (
    SpectrumScaling,
    pack_draws,
    resolve_building,
    resolve_posterior,
    resolve_records,
    resolve_scales,
)
from structures.propagation.responses import DEMAND_LABELS, MAIN_DEMANDS, ResponseSet, chunk_table, label
from structures.propagation.store import ParquetStore

__all__ = ["DEMAND_LABELS", "MAIN_DEMANDS", "ResponseSet", "SpectrumScaling", "label", "propagate",
           "run_chunk"]

DEFAULT_DRIFT_LIMIT = 0.005
"""Default limit of ``drift_ratio_max`` for exceedance and fragility (0.5 % story drift ratio)."""


def _stable(obj: Any) -> Any:
    """A JSON-able, exact description of (nested) dataclasses, arrays and numbers."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {"__type__": type(obj).__name__,
                **{f.name: _stable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}}
    if hasattr(obj, "param_names") and hasattr(obj, "name"):  # a LawSpec
        return {"law": obj.name}
    if isinstance(obj, np.ndarray):
        return [_stable(x) for x in obj.tolist()]
    if isinstance(obj, (float, np.floating)):
        return repr(float(obj))
    if isinstance(obj, (int, np.integer, bool, str)) or obj is None:
        return obj
    if isinstance(obj, Mapping):
        return {str(k): _stable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_stable(x) for x in obj]
    return repr(obj)


def propagate(
    posterior,
    building,
    records,
    *,
    n_samples: int = 200,
    scales: Sequence[float] | float = (1.0,),
    seed: int = 0,
    executor=None,
    store: str | os.PathLike | None = None,
    progress: bool = True,
    limits: Mapping[str, float] | None = None,
    chunk_size: int = 50,
) -> ResponseSet:
    """Run posterior draws of the isolator law through a building under ground motions.

    Parameters
    ----------
    posterior
        A ``Calibration``, an ``InferenceData``, a netCDF path, or a DataFrame of full parameter
        draws with the law's name in ``df.attrs["law"]`` (read by
        :func:`rrfrei.calibration.posterior_draws`).  Its law must be the building's isolator law.
    building
        A :class:`structures.ShearBuilding`, an example name (``"five_story"``) or a TOML path.
    records
        Names of bundled records (``ground_motions.available()``), file paths, or ``Record``\\ s.
    n_samples
        Number of parameter draws (drawn up front from ``seed``).
    scales
        Intensity multipliers applied to every record (stripes), or a :class:`SpectrumScaling`
        (records first scaled to a target spectrum, factors in ``ResponseSet.record_factors``).
    seed
        Seed of the posterior draws; the analyses themselves are deterministic.
    executor
        None: chunks run here one after the other, each on all cores.  Otherwise anything with
        ``.submit`` (``concurrent.futures`` executors, ``dask.distributed.Client``).
    store
        Directory of a Parquet store: finished chunks are written there atomically and skipped on
        a rerun with the same inputs; a store made for other inputs is refused (ValueError).
    progress
        Show a tqdm progress bar over chunks.
    limits
        Demand limits for exceedance probabilities and fragilities, by demand column.  Default:
        the largest tested isolator displacement (prototype, ``length_scale`` x specimen) for
        ``iso_disp_peak_m`` and a 0.5 % drift ratio for ``drift_ratio_max``.
    chunk_size
        Draws per chunk (a chunk is one record x one scale x ``chunk_size`` draws); part of the
        store's identity.

    Returns
    -------
    ResponseSet
    """
    check_run_options(n_samples, chunk_size, seed, executor)
    n_samples, chunk_size, seed = int(n_samples), int(chunk_size), int(seed)
    spectrum = scales if isinstance(scales, SpectrumScaling) else None
    scale_values = resolve_scales(spectrum.stripes if spectrum else scales)
    bld = resolve_building(building)
    recs = resolve_records(records)
    record_factors = {r.name: 1.0 for r in recs}
    im_label = "intensity (record scale factor) [-]"
    if spectrum is not None:
        pairs = scale_to_spectrum(recs, spectrum.target, spectrum.period_range, spectrum.damping,
                                  method=spectrum.method)
        recs = [r for r, _ in pairs]
        record_factors = {r.name: float(f) for r, f in pairs}
        im_label = "intensity (multiple of the target spectrum) [-]"
    run = prepare_run(posterior, bld, n_samples, seed, limits)

    # ---- identity of the inputs (the store refuses anything else)
    description = {
        "law": run.law,
        "building": run.building_name,
        "records": [r.name for r in recs],
        "scales": list(scale_values),
        "record_factors": [repr(record_factors[r.name]) for r in recs],
        "n_samples": n_samples,
        "seed": seed,
        "chunk_size": chunk_size,
    }
    fingerprint = input_fingerprint(description, bld, run.params, recs)

    def task_args(chunk):
        _, ri, s, a, b = chunk
        return (bld, recs[ri], s, run.params[a:b])

    def rows(chunk, out):
        _, ri, s, a, b = chunk
        return chunk_table(out, np.arange(a, b), recs[ri].name, s, run.d_max, run.length_scale)

    table = run_chunks(make_chunks(len(recs), scale_values, n_samples, chunk_size), run_chunk, task_args,
                       rows, executor=executor, store=store, fingerprint=fingerprint,
                       description=description, progress=progress)
    return response_set(run, table, tuple(r.name for r in recs), scale_values, seed, im_label,
                        record_factors, stacklevel=3)


# ---------------------------------------------------------------------------------------------
# the machinery shared with structures.propagation.plan_propagate (pairs of records on the plan building)
# ---------------------------------------------------------------------------------------------
def check_run_options(n_samples, chunk_size, seed, executor) -> None:
    """ValueError naming a bad ``n_samples``, ``chunk_size``, ``seed`` or ``executor``."""
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples!r}")
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if executor is not None and not hasattr(executor, "submit"):
        raise ValueError(
            f"executor must have a .submit method (concurrent.futures or Dask), got {executor!r}"
        )


@dataclasses.dataclass(frozen=True, eq=False)
class PreparedRun:
    """The posterior draws checked against the building, with the limits and notes of a run."""

    law: str
    spec: Any
    params: np.ndarray
    cal_range: tuple[float, float] | None
    d_max: float | None
    length_scale: float
    limits: dict
    notes: list
    building_name: str


def prepare_run(posterior, bld, n_samples: int, seed: int, limits) -> PreparedRun:
    """Draw the posterior, check its law against the building's isolator, set the limits.

    The specimen checks (:func:`structures.building.specimen.specimen_checks`) warn, never refuse.
    """
    law_name, draws, cal_range = resolve_posterior(posterior, n_samples, seed)
    iso = bld.isolator
    bld_law = get_law(iso.law).name
    if get_law(law_name).name != bld_law:
        raise ValueError(
            f"the posterior is for law {law_name!r} but the building's isolator uses {bld_law!r}; "
            "calibrate that law or change the building's isolator law"
        )
    spec = get_law(bld_law)
    params = pack_draws(spec, draws)
    length_scale = float(getattr(iso, "length_scale", 1.0))
    d_max = None if cal_range is None else max(abs(cal_range[0]), abs(cal_range[1]))
    notes = []
    if cal_range is None:
        notes.append("calibrated displacement range unknown: the extrapolation flag is NA")
    lim = {}
    if d_max is not None:
        lim["iso_disp_peak_m"] = length_scale * d_max
    lim["drift_ratio_max"] = DEFAULT_DRIFT_LIMIT
    if limits is not None:
        lim = {str(k): float(v) for k, v in dict(limits).items()}
    # ---- is this posterior an isolator for this building? (warn, never refuse)
    for msg in specimen_checks(bld, np.median(params, axis=0),
                               None if d_max is None else length_scale * d_max):
        notes.append(msg)
        warnings.warn(msg, SpecimenWarning, stacklevel=3)
    return PreparedRun(bld_law, spec, params, cal_range, d_max, length_scale, lim, notes,
                       str(getattr(bld, "name", "") or ""))


def input_fingerprint(description: Mapping, bld, params: np.ndarray, records: Sequence) -> str:
    """SHA-256 of the inputs: the description, the building, the draws and every record's dt and
    acceleration (1-D or (n, 2) arrays alike)."""
    h = hashlib.sha256(json.dumps(description, sort_keys=True).encode())
    h.update(json.dumps(_stable(bld), sort_keys=True).encode())
    h.update(params.tobytes())
    for r in records:
        h.update(repr(float(r.dt)).encode())
        h.update(np.ascontiguousarray(r.accel).tobytes())
    return h.hexdigest()


def make_chunks(n_records: int, scale_values: Sequence[float], n_samples: int,
                chunk_size: int) -> list[tuple]:
    """Deterministic chunks ``(id, record index, scale, first draw, end draw)``."""
    chunks = []
    n_blocks = math.ceil(n_samples / chunk_size)
    for ri in range(n_records):
        for si, s in enumerate(scale_values):
            for ci in range(n_blocks):
                a, b = ci * chunk_size, min(n_samples, (ci + 1) * chunk_size)
                chunks.append((f"r{ri:03d}-s{si:03d}-c{ci:05d}", ri, s, a, b))
    return chunks


def run_chunks(chunks, task, task_args, rows, *, executor, store, fingerprint: str,
               description: Mapping, progress: bool) -> pd.DataFrame:
    """Run every chunk not already in the store; return all rows in chunk order.

    ``task(*task_args(chunk), [threads])`` runs a chunk (here, or submitted to ``executor`` with
    the thread count ``cores // workers`` appended); ``rows(chunk, out)`` turns its output into
    the chunk's tidy rows, written to the Parquet store when there is one.
    """
    order = [c[0] for c in chunks]
    st = None if store is None else ParquetStore(store, fingerprint, dict(description))
    done = st.done() if st is not None else set()
    frames: dict[str, pd.DataFrame] = {}
    todo = [c for c in chunks if c[0] not in done]

    bar = None
    if progress and todo:
        try:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(chunks), initial=len(chunks) - len(todo), desc="propagate", unit="chunk",
                       leave=False)  # one line at a time, also when nested in the demo
        except ImportError:  # pragma: no cover - tqdm is a dependency
            bar = None

    def finish(chunk, out):
        frame = rows(chunk, out)
        if st is not None:
            st.write(chunk[0], frame)
        else:
            frames[chunk[0]] = frame
        if bar is not None:
            bar.update(1)

    try:
        if executor is None:
            for chunk in todo:
                finish(chunk, task(*task_args(chunk)))
        else:
            threads = max(1, (os.cpu_count() or 1) // workers(executor))
            futures = {}
            for chunk in todo:
                fut = submit(executor, task, *task_args(chunk), threads)
                futures[fut] = chunk
            for fut in as_completed(executor, list(futures)):
                finish(futures[fut], fut.result())
    finally:
        if bar is not None:
            bar.close()

    return st.read(order) if st is not None else pd.concat([frames[c] for c in order], ignore_index=True)


def response_set(run: PreparedRun, table: pd.DataFrame, records: tuple[str, ...],
                 scale_values: tuple[float, ...], seed: int, im_label: str,
                 record_factors: dict, *, stacklevel: int = 2) -> ResponseSet:
    """The :class:`ResponseSet` of a finished run (notes on runs that did not converge)."""
    notes = list(run.notes)
    if not table.empty:
        table["extrapolated"] = table["extrapolated"].astype("boolean")
    n_bad = int((~table["converged"].astype(bool)).sum())
    if n_bad:
        notes.append(f"{n_bad} of {len(table)} analyses did not converge; summaries exclude them")
        warnings.warn(notes[-1], RuntimeWarning, stacklevel=stacklevel)
    draws_out = pd.DataFrame(run.params, columns=list(run.spec.param_names))
    draws_out.index.name = "sample"
    return ResponseSet(
        table=table,
        draws=draws_out,
        law=run.law,
        records=records,
        scales=scale_values,
        seed=seed,
        limits=run.limits,
        calibrated_range=run.cal_range,
        length_scale=run.length_scale,
        building=run.building_name,
        im_label=im_label,
        record_factors=record_factors,
        notes=tuple(notes),
    )
