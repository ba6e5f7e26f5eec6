"""Posterior propagation: isolator parameter draws x ground motions x intensities -> demands.

:func:`propagate` draws ``n_samples`` full parameter sets from a calibrated posterior (up front,
from ``seed``), runs every draw on every record at every scale with the batched Newmark kernel
(:func:`structures.time_history_batch`, Numba ``prange`` over the draws of a chunk), and returns a
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
(:class:`structures.store.ParquetStore`); rerunning with the same store skips them.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from structures import summaries
from structures.fragility import Fragility, fit_fragility
from structures.specimen import SpecimenWarning, specimen_checks
from structures.store import ParquetStore

__all__ = ["DEMAND_LABELS", "ResponseSet", "SpectrumScaling", "propagate"]

#: Demand column -> axis label with unit (per-story/floor columns are labelled by prefix).
DEMAND_LABELS = {
    "iso_disp_peak_m": "peak isolator displacement [m]",
    "iso_disp_residual_m": "residual isolator displacement [m]",
    "drift_ratio_max": "peak story drift ratio, largest story [-]",
    "floor_acc_max_ms2": "peak absolute floor acceleration, largest floor [m/s$^2$]",
    "base_shear_peak_kN": "peak base shear [kN]",
    "iso_energy_kNm": "isolator dissipated energy [kN m]",
    "energy_error": "energy balance error (relative) [-]",
}
MAIN_DEMANDS = ("iso_disp_peak_m", "iso_disp_residual_m", "drift_ratio_max", "floor_acc_max_ms2",
                "base_shear_peak_kN", "iso_energy_kNm")
DEFAULT_DRIFT_LIMIT = 0.005


def label(demand: str) -> str:
    """Axis label with unit of a demand column."""
    if demand in DEMAND_LABELS:
        return DEMAND_LABELS[demand]
    if demand.startswith("drift_ratio_s"):
        return f"peak drift ratio, story {demand[len('drift_ratio_s'):]} [-]"
    if demand.startswith("floor_acc_f"):
        floor = demand[len("floor_acc_f"):].removesuffix("_ms2")
        return f"peak absolute acceleration, floor {floor} [m/s$^2$]"
    return demand


@dataclass(frozen=True)
class SpectrumScaling:
    """Scale every record to a target spectrum first, then apply the ``stripes`` multipliers.

    ``target`` is what :func:`ground_motions.scale_to_spectrum` accepts (a ``Spectrum``, a
    callable ``T -> PSA [m/s^2]`` or a ``(periods, psa)`` pair), matched over ``period_range``
    [s] (``method`` ``"log-ls"`` or ``"asce7"``).  The intensity of a stripe is then the
    multiple of the target spectrum.
    """

    target: Any
    period_range: tuple[float, float]
    stripes: tuple[float, ...] = (1.0,)
    damping: float = 0.05
    method: str = "log-ls"


# ---------------------------------------------------------------------------------------------
# the result
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ResponseSet:
    """Demands of a building on posterior draws of its isolator law, over records and scales.

    Attributes
    ----------
    table
        Tidy DataFrame, one row per run: ``sample`` (draw index), ``record`` (name), ``scale``
        (intensity multiplier), then the demands (prototype units: ``iso_disp_peak_m``,
        ``iso_disp_residual_m``, ``drift_ratio_s1..``, ``drift_ratio_max``,
        ``floor_acc_f1_ms2..``, ``floor_acc_max_ms2``, ``base_shear_peak_kN``, ``iso_energy_kNm``,
        ``energy_error``), ``converged`` and ``extrapolated`` (the isolator went beyond the largest
        displacement the law was calibrated on, ``length_scale`` x specimen amplitude).
    draws
        The parameter draws, one row per ``sample`` (specimen units, the law's parameter names).
    law, records, scales, seed
        The inputs.
    limits
        Default demand limits for :meth:`exceedance` and :meth:`fragility`.
    calibrated_range
        Specimen displacement range [m] the posterior was calibrated on (None when unknown).
    length_scale
        Prototype displacement = ``length_scale`` x specimen displacement.
    """

    table: pd.DataFrame
    draws: pd.DataFrame
    law: str
    records: tuple[str, ...]
    scales: tuple[float, ...]
    seed: int
    limits: dict[str, float]
    calibrated_range: tuple[float, float] | None
    length_scale: float
    building: str = ""
    im_label: str = "intensity (record scale factor) [-]"
    record_factors: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = field(default=())

    # -------------------------------------------------------------------- table helpers
    @property
    def demands(self) -> tuple[str, ...]:
        """Every demand column of :attr:`table`."""
        skip = {"sample", "record", "scale", "converged", "extrapolated"}
        return tuple(c for c in self.table.columns if c not in skip)

    @property
    def main_demands(self) -> tuple[str, ...]:
        return tuple(d for d in MAIN_DEMANDS if d in self.table.columns)

    def _check(self, demands) -> tuple[str, ...]:
        if demands is None:
            ds = self.main_demands
        else:
            ds = (demands,) if isinstance(demands, str) else tuple(demands)
        for d in ds:
            if d not in self.table.columns:
                raise ValueError(f"unknown demand {d!r}; available: {', '.join(self.demands)}")
        return ds

    # -------------------------------------------------------------------- summaries
    def summary(self, demands: str | Sequence[str] | None = None) -> pd.DataFrame:
        """Median, 16/84 and 2.5/97.5 percentiles per record and over all records, per scale.

        See :func:`structures.summaries.percentiles` (converged runs only).
        """
        return summaries.percentiles(self.table, self._check(demands), self.records)

    def variance_split(self, demands: str | Sequence[str] | None = None) -> pd.DataFrame:
        """Share of Var(ln D) from the isolator parameters vs. record-to-record variability.

        Law of total variance over the crossed (sample x record) design, per scale:
        ``share_params = Var_theta(E[ln D | theta]) / Var(ln D)``,
        ``share_records = Var_r(E[ln D | r]) / Var(ln D)``, the rest is their interaction
        (see :func:`structures.summaries.variance_split`).
        """
        return summaries.variance_split(self.table, self._check(demands))

    def exceedance(self, limits: Mapping[str, float] | None = None) -> pd.DataFrame:
        """P(D > limit) per record and over all records, per scale (default: :attr:`limits`)."""
        lim = dict(self.limits if limits is None else limits)
        self._check(list(lim))
        return summaries.exceedance(self.table, lim, self.records)

    def fragility(self, limits: Mapping[str, float] | None = None) -> list[Fragility]:
        """Lognormal fragility per limit, fitted across the scales by maximum likelihood.

        Baker (2015): the runs of all records and draws at one scale form a stripe; see
        :func:`structures.fragility.fit_fragility`.  The intensity is the scale factor.
        """
        ex = self.exceedance(limits)
        ex = ex[ex["record"] == summaries.ALL]
        out = []
        for (d, lim), g in ex.groupby(["demand", "limit"], sort=False):
            out.append(fit_fragility(g["scale"], g["n"], g["n_exceed"], demand=d, limit=lim))
        return out

    def extrapolated_share(self) -> float:
        """Share of runs where the isolator left the calibrated displacement range (NaN if unknown)."""
        col = self.table["extrapolated"]
        if col.isna().all():
            return float("nan")
        return float(col.astype(float).mean())

    # -------------------------------------------------------------------- plots
    def plot_distributions(self, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
        """Box plots of ``demand`` per record (and over all records) at one scale."""
        import matplotlib.pyplot as plt

        (d,) = self._check(demand)
        s = self.scales[0] if scale is None else float(scale)
        t = summaries._converged(self.table)
        t = t[np.isclose(t["scale"], s)]
        data = [t.loc[t["record"] == r, d].to_numpy(float) for r in self.records] + [t[d].to_numpy(float)]
        names = [*self.records, summaries.ALL]
        if ax is None:
            _, ax = plt.subplots(figsize=(max(5.0, 0.7 * len(names) + 2), 4))
        ax.boxplot(data, whis=(2.5, 97.5), showfliers=True)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
        ax.set_xlabel("ground motion record")
        ax.set_ylabel(label(d))
        ax.set_title(f"{self.law}, {len(self.draws)} draws, scale {s:g}\n(box 25-75 %, whiskers 2.5-97.5 %)",
                     fontsize=10)
        if d in self.limits:
            ax.axhline(self.limits[d], color="C3", ls="--", label=f"limit {self.limits[d]:g}")
            ax.legend()
        ax.figure.tight_layout()
        return ax.figure

    def plot_exceedance(self, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
        """Empirical exceedance curves P(D > d) per record and over all records at one scale."""
        import matplotlib.pyplot as plt

        (d,) = self._check(demand)
        s = self.scales[-1] if scale is None else float(scale)
        t = summaries._converged(self.table)
        t = t[np.isclose(t["scale"], s)]
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        for r in [*self.records, summaries.ALL]:
            x = np.sort((t if r == summaries.ALL else t[t["record"] == r])[d].to_numpy(float))
            if not x.size:
                continue
            p = 1.0 - np.arange(1, x.size + 1) / x.size
            kw = {"color": "k", "lw": 2.2} if r == summaries.ALL else {"lw": 1.0, "alpha": 0.8}
            ax.step(x, p, where="post", label=r, **kw)
        if d in self.limits:
            ax.axvline(self.limits[d], color="C3", ls="--", label=f"limit {self.limits[d]:g}")
        ax.set_xlabel(label(d))
        ax.set_ylabel("probability of exceedance P(D > d) [-]")
        ax.set_title(f"scale {s:g}")
        ax.legend(fontsize=7, ncol=2)
        ax.figure.tight_layout()
        return ax.figure

    def plot_fragility(self, limits: Mapping[str, float] | None = None, ax=None):
        """Fitted fragility curves with the observed stripe fractions."""
        import matplotlib.pyplot as plt

        frs = self.fragility(limits)
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        lo = min(self.scales) * 0.5
        hi = max(self.scales) * 1.5
        x = np.linspace(lo, hi, 200)
        for i, fr in enumerate(frs):
            c = f"C{i}"
            name = f"{fr.demand} > {fr.limit:g}"
            ax.plot(fr.im, np.divide(fr.z, fr.n), "o", color=c)
            if math.isfinite(fr.theta):
                ax.plot(x, fr.probability(x), color=c,
                        label=f"{name}: theta={fr.theta:.3g}, beta={fr.beta:.2f}")
            else:
                ax.plot([], [], "o", color=c, label=f"{name}: {fr.note}")
        ax.set_xlabel(self.im_label)
        ax.set_ylabel("P(demand > limit) [-]")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title("lognormal fragility, maximum likelihood (Baker 2015)")
        ax.legend(fontsize=7)
        ax.figure.tight_layout()
        return ax.figure


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def _resolve_building(building):
    import structures

    if isinstance(building, (str, os.PathLike)):
        text = str(building)
        if text.endswith(".toml") or os.sep in text or Path(text).exists():
            return structures.ShearBuilding.from_toml(text)
        return structures.load_building(text)
    if not hasattr(building, "isolator"):
        raise ValueError(
            f"building must be a ShearBuilding, an example name or a TOML path, got {type(building).__name__}"
        )
    return building


def _resolve_records(records) -> list:
    import ground_motions

    if isinstance(records, (str, os.PathLike, ground_motions.Record)):
        records = [records]
    out = []
    for r in records:
        if isinstance(r, ground_motions.Record):
            out.append(r)
        elif isinstance(r, (str, os.PathLike)):
            text = str(r)
            if os.sep in text or Path(text).suffix or Path(text).exists():
                out.append(ground_motions.read(text))
            else:
                out.append(ground_motions.load(text))
        else:
            raise ValueError(f"a record must be a name, a path or a Record, got {type(r).__name__}")
    if not out:
        raise ValueError("records is empty: give at least one record name, path or Record")
    names = [r.name for r in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"record names must be unique (they key the table); repeated: {', '.join(dup)}")
    return out


def _resolve_scales(scales) -> tuple[float, ...]:
    if isinstance(scales, (int, float)):
        scales = (scales,)
    try:
        vals = tuple(float(s) for s in scales)
    except (TypeError, ValueError):
        raise ValueError(f"scales must be a sequence of positive numbers, got {scales!r}") from None
    if not vals or any(not (math.isfinite(s) and s > 0) for s in vals):
        raise ValueError(f"scales must be finite numbers > 0, got {list(vals)}")
    if len(set(vals)) != len(vals):
        raise ValueError(f"scales must be distinct, got {list(vals)}")
    return vals


def _range_from_attrs(attrs: Mapping) -> tuple[float, float] | None:
    if "disp_min_m" in attrs and "disp_max_m" in attrs:
        return float(attrs["disp_min_m"]), float(attrs["disp_max_m"])
    if "disp_range" in attrs:
        lo, hi = attrs["disp_range"]
        return float(lo), float(hi)
    return None


def _resolve_posterior(posterior, n: int, seed: int) -> tuple[str, pd.DataFrame, tuple[float, float] | None]:
    """(law name, n full parameter sets, calibrated specimen displacement range [m] or None).

    The range comes from the calibration (``idata.posterior.attrs["disp_min_m"/"disp_max_m"]``),
    or from ``df.attrs`` (same keys, or ``"disp_range"``) for a DataFrame of draws.
    """
    from rrfrei.calibration import Calibration, posterior_draws

    if isinstance(posterior, (str, os.PathLike)):
        path = Path(posterior)
        if not path.exists():
            raise FileNotFoundError(2, "No such file or directory", str(path))
        try:
            posterior = Calibration.from_netcdf(path)
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"cannot read a posterior from {str(path)!r}: {exc}") from None
    elif hasattr(posterior, "groups") and hasattr(posterior, "posterior"):
        posterior = Calibration.from_idata(posterior)
    if isinstance(posterior, pd.DataFrame):
        cal_range = _range_from_attrs(posterior.attrs)
    elif isinstance(posterior, Calibration):
        cal_range = _range_from_attrs(posterior.idata.posterior.attrs)
    else:
        raise ValueError(
            "posterior must be a Calibration, an InferenceData, a netCDF path or a DataFrame of draws, "
            f"got {type(posterior).__name__}"
        )
    law, df = posterior_draws(posterior, n, seed)
    return str(law), df.reset_index(drop=True), cal_range


def _pack_draws(spec, df: pd.DataFrame) -> np.ndarray:
    """(n, n_params) parameters in the law's order; optional ones take their default."""
    cols = []
    for p in spec.params:
        if p.name in df.columns:
            cols.append(df[p.name].to_numpy(float))
        elif p.optional:
            cols.append(np.full(len(df), float(p.default)))
        else:
            raise ValueError(
                f"the posterior draws lack parameter {p.name!r} of law {spec.name!r} "
                f"(columns: {', '.join(map(str, df.columns))})"
            )
    arr = np.ascontiguousarray(np.column_stack(cols))
    for j, p in enumerate(spec.params):
        bad = np.flatnonzero(~np.isfinite(arr[:, j]) | (arr[:, j] < p.lower) | (arr[:, j] > p.upper))
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"posterior draw {i}: {p.name} = {arr[i, j]:g} {p.unit} is outside its physical bounds "
                f"[{p.lower:g}, {p.upper:g}] {p.unit}"
            )
    if spec.check is not None:
        for row in arr:
            spec.check(row)
    return arr


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


# ---------------------------------------------------------------------------------------------
# one chunk (runs on any worker)
# ---------------------------------------------------------------------------------------------
def _kernel():
    from structures import time_history_batch

    return time_history_batch


def run_chunk(building, record, scale: float, params: np.ndarray, threads: int | None = None) -> dict:
    """Run ``params`` (m, n_params) on ``record`` x ``scale``: dict of per-run demand arrays.

    ``threads`` sets this thread's Numba thread count (executors pass ``cores // workers``);
    None keeps the default (all cores).
    """
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    rec = record if scale == 1.0 else record.scaled(scale)
    out = _kernel()(building, rec, np.ascontiguousarray(params, dtype=float))
    return {k: np.asarray(v) for k, v in out.items()}


def _frame(out: dict, samples: np.ndarray, record: str, scale: float, d_max: float | None,
           length_scale: float) -> pd.DataFrame:
    """Tidy rows of one chunk from the kernel's demand arrays."""
    cols: dict[str, Any] = {"sample": samples.astype(np.int64), "record": [record] * samples.size,
                            "scale": np.full(samples.size, scale)}
    cols["iso_disp_peak_m"] = out["iso_disp_peak"]
    cols["iso_disp_residual_m"] = out["iso_disp_residual"]
    drift = np.atleast_2d(out["drift_peak"]).reshape(samples.size, -1)
    for j in range(drift.shape[1]):
        cols[f"drift_ratio_s{j + 1}"] = drift[:, j]
    cols["drift_ratio_max"] = drift.max(axis=1)
    acc = np.atleast_2d(out["floor_acc_peak"]).reshape(samples.size, -1)
    for j in range(acc.shape[1]):
        cols[f"floor_acc_f{j + 1}_ms2"] = acc[:, j]
    cols["floor_acc_max_ms2"] = acc.max(axis=1)
    cols["base_shear_peak_kN"] = out["base_shear_peak"]
    cols["iso_energy_kNm"] = out["iso_energy"]
    cols["energy_error"] = out["energy_error"]
    cols["converged"] = np.asarray(out["converged"], dtype=bool)
    umax = np.asarray(out["iso_disp_max_abs"], dtype=float)
    if d_max is None:
        cols["extrapolated"] = pd.array([pd.NA] * samples.size, dtype="boolean")
    else:
        cols["extrapolated"] = pd.array(umax / length_scale > d_max * (1 + 1e-9), dtype="boolean")
    return pd.DataFrame(cols)


# ---------------------------------------------------------------------------------------------
# executors
# ---------------------------------------------------------------------------------------------
def _is_dask(executor) -> bool:
    return type(executor).__module__.split(".")[0] == "distributed"


def _workers(executor) -> int:
    if _is_dask(executor):
        return max(1, int(sum(executor.nthreads().values())))
    n = getattr(executor, "_max_workers", None)
    return max(1, int(n)) if n else (os.cpu_count() or 1)


def _submit(executor, fn, *args):
    if _is_dask(executor):
        return executor.submit(fn, *args, pure=False)
    return executor.submit(fn, *args)


def _as_completed(executor, futures):
    if _is_dask(executor):
        from distributed import as_completed

        return as_completed(futures)
    from concurrent.futures import as_completed

    return as_completed(futures)


# ---------------------------------------------------------------------------------------------
# the workflow
# ---------------------------------------------------------------------------------------------
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
    from rrfrei.laws import get as get_law

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
    n_samples, chunk_size, seed = int(n_samples), int(chunk_size), int(seed)
    spectrum = scales if isinstance(scales, SpectrumScaling) else None
    scale_values = _resolve_scales(spectrum.stripes if spectrum else scales)
    bld = _resolve_building(building)
    recs = _resolve_records(records)
    record_factors = {r.name: 1.0 for r in recs}
    im_label = "intensity (record scale factor) [-]"
    if spectrum is not None:
        from ground_motions import scale_to_spectrum

        pairs = scale_to_spectrum(recs, spectrum.target, spectrum.period_range, spectrum.damping,
                                  method=spectrum.method)
        recs = [r for r, _ in pairs]
        record_factors = {r.name: float(f) for r, f in pairs}
        im_label = "intensity (multiple of the target spectrum) [-]"
    law_name, draws, cal_range = _resolve_posterior(posterior, n_samples, seed)
    iso = bld.isolator
    bld_law = get_law(iso.law).name
    if get_law(law_name).name != bld_law:
        raise ValueError(
            f"the posterior is for law {law_name!r} but the building's isolator uses {bld_law!r}; "
            "calibrate that law or change the building's isolator law"
        )
    spec = get_law(bld_law)
    params = _pack_draws(spec, draws)
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
        warnings.warn(msg, SpecimenWarning, stacklevel=2)
    building_name = str(getattr(bld, "name", "") or "")

    # ---- identity of the inputs (the store refuses anything else)
    description = {
        "law": bld_law,
        "building": building_name,
        "records": [r.name for r in recs],
        "scales": list(scale_values),
        "record_factors": [repr(record_factors[r.name]) for r in recs],
        "n_samples": n_samples,
        "seed": seed,
        "chunk_size": chunk_size,
    }
    h = hashlib.sha256(json.dumps(description, sort_keys=True).encode())
    h.update(json.dumps(_stable(bld), sort_keys=True).encode())
    h.update(params.tobytes())
    for r in recs:
        h.update(repr(float(r.dt)).encode())
        h.update(np.ascontiguousarray(r.accel).tobytes())
    fingerprint = h.hexdigest()

    # ---- deterministic chunks
    chunks = []
    n_blocks = math.ceil(n_samples / chunk_size)
    for ri in range(len(recs)):
        for si, s in enumerate(scale_values):
            for ci in range(n_blocks):
                a, b = ci * chunk_size, min(n_samples, (ci + 1) * chunk_size)
                chunks.append((f"r{ri:03d}-s{si:03d}-c{ci:05d}", ri, s, a, b))
    order = [c[0] for c in chunks]

    st = None if store is None else ParquetStore(store, fingerprint, description)
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
        cid, ri, s, a, b = chunk
        frame = _frame(out, np.arange(a, b), recs[ri].name, s, d_max, length_scale)
        if st is not None:
            st.write(cid, frame)
        else:
            frames[cid] = frame
        if bar is not None:
            bar.update(1)

    try:
        if executor is None:
            for chunk in todo:
                _, ri, s, a, b = chunk
                finish(chunk, run_chunk(bld, recs[ri], s, params[a:b]))
        else:
            threads = max(1, (os.cpu_count() or 1) // _workers(executor))
            futures = {}
            for chunk in todo:
                _, ri, s, a, b = chunk
                fut = _submit(executor, run_chunk, bld, recs[ri], s, params[a:b], threads)
                futures[fut] = chunk
            for fut in _as_completed(executor, list(futures)):
                finish(futures[fut], fut.result())
    finally:
        if bar is not None:
            bar.close()

    table = st.read(order) if st is not None else pd.concat([frames[c] for c in order], ignore_index=True)
    if not table.empty:
        table["extrapolated"] = table["extrapolated"].astype("boolean")
    n_bad = int((~table["converged"].astype(bool)).sum())
    if n_bad:
        notes.append(f"{n_bad} of {len(table)} analyses did not converge; summaries exclude them")
        warnings.warn(notes[-1], RuntimeWarning, stacklevel=2)
    draws_out = pd.DataFrame(params, columns=list(spec.param_names))
    draws_out.index.name = "sample"
    return ResponseSet(
        table=table,
        draws=draws_out,
        law=bld_law,
        records=tuple(r.name for r in recs),
        scales=scale_values,
        seed=seed,
        limits=lim,
        calibrated_range=cal_range,
        length_scale=length_scale,
        building=building_name,
        im_label=im_label,
        record_factors=record_factors,
        notes=tuple(notes),
    )
