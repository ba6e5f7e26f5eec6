"""Inputs of a propagation: the building, the records, the intensities and the posterior draws.

Each ``resolve_*`` function accepts what a user may give (an object, a name, a path) and returns
the object the workflow runs, or raises ValueError naming the input and what was expected.
:func:`pack_draws` orders posterior draws as the isolator law's parameter vector and checks them
against the law's physical bounds.

Units: m, s, kN, tonnes; spectra in m/s^2.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import ground_motions
from rrfrei.calibration import Calibration, posterior_draws
from structures.building.shear_building import ShearBuilding, load_building

__all__ = ["SpectrumScaling", "pack_draws", "range_from_attrs", "resolve_building", "resolve_posterior",
           "resolve_records", "resolve_scales"]


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


def resolve_building(building) -> ShearBuilding:
    """A :class:`ShearBuilding` as it is, from a TOML path, or a bundled example by name."""
    if isinstance(building, (str, os.PathLike)):
        text = str(building)
        if text.endswith(".toml") or os.sep in text or Path(text).exists():
            return ShearBuilding.from_toml(text)
        return load_building(text)
    if not hasattr(building, "isolator"):
        raise ValueError(
            f"building must be a ShearBuilding, an example name or a TOML path, got {type(building).__name__}"
        )
    return building


def resolve_records(records) -> list[ground_motions.Record]:
    """Records from names of bundled records, file paths or ``Record``\\ s (names must be unique)."""
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


def resolve_scales(scales) -> tuple[float, ...]:
    """Intensity multipliers: distinct finite numbers > 0."""
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


def range_from_attrs(attrs: Mapping) -> tuple[float, float] | None:
    """Calibrated specimen displacement range [m] from ``disp_min_m``/``disp_max_m`` or ``disp_range``."""
    if "disp_min_m" in attrs and "disp_max_m" in attrs:
        return float(attrs["disp_min_m"]), float(attrs["disp_max_m"])
    if "disp_range" in attrs:
        lo, hi = attrs["disp_range"]
        return float(lo), float(hi)
    return None


def resolve_posterior(posterior, n: int, seed: int) -> tuple[str, pd.DataFrame, tuple[float, float] | None]:
    """(law name, n full parameter sets, calibrated specimen displacement range [m] or None).

    The range comes from the calibration (``idata.posterior.attrs["disp_min_m"/"disp_max_m"]``),
    or from ``df.attrs`` (same keys, or ``"disp_range"``) for a DataFrame of draws.
    """
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
        cal_range = range_from_attrs(posterior.attrs)
    elif isinstance(posterior, Calibration):
        cal_range = range_from_attrs(posterior.idata.posterior.attrs)
    else:
        raise ValueError(
            "posterior must be a Calibration, an InferenceData, a netCDF path or a DataFrame of draws, "
            f"got {type(posterior).__name__}"
        )
    law, df = posterior_draws(posterior, n, seed)
    return str(law), df.reset_index(drop=True), cal_range


def pack_draws(spec, df: pd.DataFrame) -> np.ndarray:
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
