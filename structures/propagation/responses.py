"""The result of a propagation: a tidy table of demands with its summaries and plots.

:class:`ResponseSet` holds one row per analysis (sample x record x scale) in prototype units and
answers the questions asked of it: percentiles, the variance split between the isolator
parameters and the records, exceedance probabilities and fragility curves
(:mod:`structures.propagation.summaries`, :mod:`structures.propagation.fragility`); its plots are drawn by
:mod:`structures.propagation.response_plots`.  :func:`chunk_table` turns the batched kernel's demand arrays
of one chunk into the table's rows.

Units: m, s, kN, tonnes; accelerations m/s^2; drift ratios dimensionless.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from structures.propagation import response_plots, summaries
from structures.propagation.fragility import Fragility, fit_fragility

__all__ = ["MAIN_DEMANDS", "ResponseSet", "chunk_table"]

MAIN_DEMANDS = ("iso_disp_peak_m", "iso_disp_residual_m", "drift_ratio_max", "floor_acc_max_ms2",
                "base_shear_peak_kN", "iso_energy_kNm")


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

        See :func:`structures.propagation.summaries.percentiles` (converged runs only).
        """
        return summaries.percentiles(self.table, self._check(demands), self.records)

    def variance_split(self, demands: str | Sequence[str] | None = None) -> pd.DataFrame:
        """Share of Var(ln D) from the isolator parameters vs. record-to-record variability.

        Law of total variance over the crossed (sample x record) design, per scale:
        ``share_params = Var_theta(E[ln D | theta]) / Var(ln D)``,
        ``share_records = Var_r(E[ln D | r]) / Var(ln D)``, the rest is their interaction
        (see :func:`structures.propagation.summaries.variance_split`).
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
        :func:`structures.propagation.fragility.fit_fragility`.  The intensity is the scale factor.
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
        return response_plots.distributions(self, demand, scale=scale, ax=ax)

    def plot_exceedance(self, demand: str = "iso_disp_peak_m", *, scale: float | None = None, ax=None):
        """Empirical exceedance curves P(D > d) per record and over all records at one scale."""
        return response_plots.exceedance(self, demand, scale=scale, ax=ax)

    def plot_fragility(self, limits: Mapping[str, float] | None = None, ax=None):
        """Fitted fragility curves with the observed stripe fractions."""
        return response_plots.fragility(self, limits, ax=ax)


def chunk_table(out: dict, samples: np.ndarray, record: str, scale: float, d_max: float | None,
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
    cols["extrapolated"] = extrapolated(np.asarray(out["iso_disp_max_abs"], dtype=float), d_max, length_scale)
    return pd.DataFrame(cols)


def extrapolated(peak: np.ndarray, d_max: float | None, length_scale: float,
                 unknown: np.ndarray | None = None) -> pd.api.extensions.ExtensionArray:
    """Per run: did the peak isolator displacement ``peak`` [m] (prototype) exceed the
    calibrated range ``d_max`` [m] (specimen) times ``length_scale``?  NA where ``d_max`` is
    unknown (None) or where ``unknown`` (bool mask) is True."""
    if d_max is None:
        return pd.array([pd.NA] * peak.size, dtype="boolean")
    flag = pd.array(peak / length_scale > d_max * (1 + 1e-9), dtype="boolean")
    if unknown is not None:
        flag[unknown] = pd.NA
    return flag
