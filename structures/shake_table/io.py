"""Reading and writing shake-table runs: the folder layout (BNCS files ``a1 ... aN``,
``d1 ... dN``, ``u``), the CSV layout, their TOML sidecars and units, and the bundled BNCS runs.
The formats are described in :mod:`structures.shake_table` and ``docs/shake_table_data.md``."""

from __future__ import annotations

import gzip
import math
import warnings
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rrfrei.io import read_toml
from structures.building.checks import positive_vector
from structures.shake_table.checks import (
    _MIN_FILTER_SAMPLES,
    ConsistencyReport,
    ConsistencyWarning,
    LevelOrderWarning,
    check_consistency,
    check_level_order,
)
from structures.shake_table.run import ShakeTableRun

__all__ = ["A1_LEVELS", "ACCEL_UNITS", "BNCS_WEIGHTS_KN", "DISP_UNITS", "G", "LEVEL_ORDERS", "MASS_UNITS",
           "WEIGHT_UNITS", "MetadataError", "available_runs", "load_run", "open_run", "read_run", "write_run"]

G = 9.81
"""Gravity [m/s^2] used to turn level weights into masses (the BNCS source uses 9.81)."""

BNCS_WEIGHTS_KN = (2275.1, 674.0, 703.0, 1036.3, 1078.1, 593.3)
"""Level weights [kN] of the BNCS building, bottom-up (base slab incl. its 406.6 kN addition,
then floors 2-5 and the roof), from the source notebook; the unit kN is inferred (see
``structures/shake_table/data/shake_table_bncs/PROVENANCE.md``)."""

LEVEL_ORDERS = ("base-first", "roof-first")
"""How a list of levels (masses, weights, names, CSV columns) runs: from the base slab above the
isolators up (``base-first``, the default) or from the roof down (``roof-first``)."""

A1_LEVELS = ("roof", "base")
"""Which level the files ``a1``/``d1`` of the folder layout hold (default ``roof``, the BNCS
convention: ``a1`` the roof, ``aN`` the base slab)."""

ACCEL_UNITS = {"mps2": 1.0, "cmps2": 0.01, "g": G}
DISP_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
MASS_UNITS = {"t": 1.0, "kg": 0.001}
WEIGHT_UNITS = {"kN": 1.0, "N": 0.001, "MN": 1000.0}

_DATA = Path(__file__).with_name("data") / "shake_table_bncs"


class MetadataError(ValueError):
    """A run's sampling rate or level masses are missing, or the channels contradict the rate.

    ``fact`` says what is wrong (with the folder or file); ``what`` names the datum, ``"rate_hz"``
    or ``"masses"`` (``"time"`` for a CSV whose time column the channels contradict);
    ``sidecar`` is the TOML file where it can be stated.  The message ends with how to give it
    from Python; the command line (``rrfrei shake-table``) words that part for its options.
    """

    def __init__(self, fact: str, hint: str, *, what: str, sidecar: str):
        super().__init__(f"{fact}: {hint}")
        self.fact, self.what, self.sidecar = fact, what, sidecar


def _sidecar_levels(data: Mapping[str, Any], where: str) -> tuple[list[str] | None, np.ndarray | None]:
    lv = data.get("levels", {})
    if not isinstance(lv, Mapping):
        raise ValueError(f"{where}: [levels] must be a table")
    known = {"names", "masses", "mass_unit", "weights", "weight_unit", "g", "level_order", "a1"}
    extra = sorted(set(lv) - known)
    if extra:
        raise ValueError(f"{where}: unknown [levels] key(s) {', '.join(extra)}; "
                         f"accepted: {', '.join(sorted(known))}")
    names = None
    if "names" in lv:
        names = lv["names"]
        if not isinstance(names, list) or not names or not all(isinstance(x, str) for x in names):
            raise ValueError(f"{where}: [levels] names = {names!r} is invalid: expected a non-empty list of "
                             "strings (bottom-up)")
        if len(set(names)) != len(names):
            raise ValueError(f"{where}: [levels] names = {names!r} repeats a label; expected distinct names")
    if "masses" in lv and "weights" in lv:
        raise ValueError(f"{where}: give [levels] masses or weights, not both")
    masses = None
    if "masses" in lv:
        unit = str(lv.get("mass_unit", "t"))
        if unit not in MASS_UNITS:
            raise ValueError(f"{where}: mass_unit = {unit!r} is unknown; "
                             f"expected one of {', '.join(MASS_UNITS)}")
        masses = positive_vector(f"{where}: [levels] masses", lv["masses"], unit) * MASS_UNITS[unit]
    elif "weights" in lv:
        unit = str(lv.get("weight_unit", ""))
        if unit not in WEIGHT_UNITS:
            raise ValueError(f"{where}: weight_unit = {unit!r} is missing or unknown; expected one of "
                             f"{', '.join(WEIGHT_UNITS)} (weights need a stated unit)")
        g = lv.get("g", G)
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not (math.isfinite(g) and g > 0):
            raise ValueError(f"{where}: [levels] g = {g!r} is invalid: expected a finite number > 0 [m/s^2]")
        masses = positive_vector(f"{where}: [levels] weights", lv["weights"], unit) * WEIGHT_UNITS[unit] / g
    return names, masses


def _option(value: Any, key: str, allowed: tuple[str, ...], where: str) -> str | None:
    """A string option of the sidecar or an argument, checked against ``allowed``."""
    if value is None:
        return None
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{where}: {key} = {value!r} is invalid: expected one of "
                         f"{', '.join(repr(a) for a in allowed)}")
    return value


def _order(level_order, side: Mapping[str, Any], where: str) -> tuple[str, str]:
    """(level order, where it was stated): the argument, else [levels] level_order, else base-first."""
    arg = _option(level_order, "level_order", LEVEL_ORDERS, "level_order")
    lv = side.get("levels", {})
    side_order = _option(lv.get("level_order") if isinstance(lv, Mapping) else None,
                         "[levels] level_order", LEVEL_ORDERS, where)
    if arg is not None:
        return arg, "the argument level_order"
    if side_order is not None:
        return side_order, where
    return "base-first", "the default"


def _level_masses(masses, weights, weight_unit: str, side_masses, n_levels: int, where: str,
                  *, sidecar: str = "run.toml") -> np.ndarray:
    if masses is not None and weights is not None:
        raise ValueError("give masses= or weights=, not both")
    if masses is not None:
        m = positive_vector("masses", masses, "t")
    elif weights is not None:
        if weight_unit not in WEIGHT_UNITS:
            raise ValueError(f"weight_unit = {weight_unit!r} is unknown; "
                             f"expected one of {', '.join(WEIGHT_UNITS)}")
        m = positive_vector("weights", weights, weight_unit) * WEIGHT_UNITS[weight_unit] / G
    elif side_masses is not None:
        m = side_masses
    else:
        raise MetadataError(
            f"{where}: no level masses",
            "give masses= [t] or weights= (base slab first unless level_order='roof-first'), or "
            f"[levels] masses/weights in {sidecar} (docs/shake_table_data.md; for the BNCS building: "
            "weights=structures.shake_table.BNCS_WEIGHTS_KN)", what="masses", sidecar=sidecar)
    if m.size != n_levels:
        raise ValueError(f"{where}: {m.size} level masses for {n_levels} levels")
    return m


def _load_column_file(path: Path) -> np.ndarray:
    try:
        if path.suffix == ".gz":
            with gzip.open(path, "rt", encoding="utf-8") as fh:
                text = fh.read()
        else:
            text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file (byte {exc.start} is not UTF-8 text: a binary "
                         "file, or another encoding); expected one column of numbers") from None
    except (OSError, EOFError, zlib.error) as exc:  # a corrupt .gz: BadGzipFile, EOFError or zlib.error
        raise ValueError(f"{path}: cannot be read as one column of numbers ({exc})") from None
    values: list[float] = []
    for i, line in enumerate(text.splitlines(), start=1):  # one value per line, or rows of values
        for tok in line.split("#", 1)[0].split():
            try:
                x = float(tok)
            except ValueError:
                raise ValueError(f"{path}, line {i}: {tok[:40]!r} is not a number") from None
            if not math.isfinite(x):
                raise ValueError(f"{path}, line {i}: value {tok!r} is not finite")
            values.append(x)
    if not values:
        raise ValueError(f"{path}: no values (empty file); expected numbers, one per line")
    return np.asarray(values, dtype=float)


def _find(folder: Path, stem: str) -> Path | None:
    for ext in (".txt", ".txt.gz", ".gz", ""):
        p = folder / f"{stem}{ext}"
        if p.is_file():
            return p
    return None


def _folder_sidecar(folder: Path) -> dict:
    for p in (folder / "run.toml", folder.with_suffix(".toml")):
        if p.is_file():
            return read_toml(p) | {"_path": str(p)}
    return {}


def _read_folder(folder: Path, name, rate_hz, masses, weights, weight_unit, level_order, a1):
    side = _folder_sidecar(folder)
    where = side.get("_path", str(folder))
    sidecar = side.get("_path", str(folder / "run.toml"))
    order_name, order_from = _order(level_order, side, where)
    lv = side.get("levels", {})
    a1_arg = _option(a1, "a1", A1_LEVELS, "a1")
    a1_side = _option(lv.get("a1") if isinstance(lv, Mapping) else None, "[levels] a1", A1_LEVELS, where)
    a1_level = a1_arg or a1_side or "roof"
    n = 0
    while _find(folder, f"a{n + 1}") is not None:
        n += 1
    if n == 0:
        raise ValueError(f"{folder}: no acceleration files a1, a2, ... (.txt or .txt.gz) in this folder")
    chans: dict[str, np.ndarray] = {}
    files: dict[str, Path] = {}
    for stem in [*(f"a{i}" for i in range(1, n + 1)), *(f"d{i}" for i in range(1, n + 1)), "u"]:
        p = _find(folder, stem)
        if p is None:
            raise ValueError(f"{folder}: file {stem}.txt(.gz) is missing "
                             f"(folder layout: a1..a{n}, d1..d{n}, u, du)")
        chans[stem], files[stem] = _load_column_file(p), p
    p = _find(folder, "du")
    if p is not None:
        chans["du"], files["du"] = _load_column_file(p), p
    lengths = {k: v.size for k, v in chans.items()}
    if len(set(lengths.values())) != 1:
        ref = chans["u"].size
        odd = next(k for k, v in lengths.items() if v != ref)
        raise ValueError(f"{folder}: file {files[odd].name} has {lengths[odd]} values but {files['u'].name} "
                         f"has {ref}; all channels must have the same length")
    rate = rate_hz if rate_hz is not None else side.get("rate_hz")
    if rate is None:
        raise MetadataError(
            f"{folder}: the sampling rate is not stated",
            f"give rate_hz= [Hz] or rate_hz = ... in {sidecar} (docs/shake_table_data.md; the raw BNCS "
            "runs: 200)", what="rate_hz", sidecar=sidecar)
    try:
        if isinstance(rate, bool):
            raise TypeError
        rate = float(rate)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: rate_hz = {rate!r} is invalid: expected a number [Hz]") from None
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"{where}: rate_hz = {rate!r} is invalid: expected a finite number > 0 Hz")
    side_names, side_masses = _sidecar_levels(side, where)
    m = _level_masses(masses, weights, weight_unit, side_masses, n, where, sidecar=sidecar)
    if side_names is not None and len(side_names) != n:
        raise ValueError(f"{where}: [levels] names has {len(side_names)} labels but the folder has {n} "
                         f"levels (a1..a{n})")
    if order_name == "roof-first":  # the lists were given roof first: put them bottom-up
        m = m[::-1].copy()
        side_names = None if side_names is None else side_names[::-1]
    # bottom-up: aN (base slab) ... a1 (roof), or a1 ... aN when a1 is the base slab
    order = list(range(n, 0, -1)) if a1_level == "roof" else list(range(1, n + 1))
    names = side_names or [f"a{i}" for i in order]
    nt = chans["u"].size
    return ShakeTableRun(
        name=name or str(side.get("name", folder.name)),
        time=np.arange(nt) / rate,
        table_accel=chans["u"],
        accel=np.column_stack([chans[f"a{i}"] for i in order]),
        disp=np.column_stack([chans[f"d{i}"] for i in order]),
        masses=m,
        level_names=tuple(names),
        table_disp=chans.get("du"),
        source=str(folder),
        meta={"layout": "folder", "rate_hz": rate,
              "rate_source": "the argument rate_hz" if rate_hz is not None else where,
              "level_order": order_name, "level_order_source": order_from, "a1": a1_level, "sidecar": sidecar,
              "masses_source": ("the argument masses" if masses is not None else
                                "the argument weights" if weights is not None else where)},
    )


def _csv_sidecar(path: Path) -> dict:
    stem = path.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    for p in (path.with_name(f"{stem}.toml"), path.with_name("shake_table.toml")):
        if p.is_file():
            return read_toml(p) | {"_path": str(p)}
    return {}


def _unit_of(col: str, kind: str, table: dict[str, float], side_units: Mapping[str, Any],
             where: str) -> float:
    """Factor to SI of a column ``<base>_<unit>`` (or without a suffix: the sidecar's [units])."""
    suffix = col.rsplit("_", 1)[-1]
    if suffix in table:
        return table[suffix]
    unit = side_units.get(kind)
    if unit is None:
        raise ValueError(f"{where}: column {col!r} has no {kind} unit suffix ({', '.join(table)}) and the "
                         f"sidecar has no [units] {kind}")
    if unit not in table:
        raise ValueError(f"{where}: [units] {kind} = {unit!r} is unknown; expected one of {', '.join(table)}")
    return table[unit]


def _read_csv(path: Path, name, masses, weights, weight_unit, level_order, rate_hz):
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError, EOFError, zlib.error) as exc:
        raise ValueError(f"{path}: cannot be read as CSV ({exc})") from None
    side = _csv_sidecar(path)
    where = str(path)
    units = side.get("units", {})
    if not isinstance(units, Mapping):
        raise ValueError(f"{side['_path']}: [units] must be a table (accel = ..., disp = ...), got {units!r}")
    cols = [str(c).strip() for c in df.columns]
    df.columns = cols

    def column(col: str) -> np.ndarray:
        s = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(s))
        if bad.size:
            v = df[col].iloc[bad[0]]
            shown = repr(v) if isinstance(v, str) else repr(float(v))
            raise ValueError(f"{where}: column {col!r}, row {bad[0] + 2}: value {shown} is not a finite "
                             "number")
        return s

    def pick(prefix: str, required: bool) -> str | None:
        hits = [c for c in cols if c == prefix or c.startswith(prefix + "_")]
        if not hits:
            if required:
                raise ValueError(f"{where}: column {prefix}_<unit> is missing; columns are {', '.join(cols)}")
            return None
        return hits[0]

    tcol = pick("time", True)
    tfac = {"s": 1.0, "ms": 1e-3}.get(tcol.rsplit("_", 1)[-1], None) if "_" in tcol else 1.0
    if tfac is None:
        raise ValueError(f"{where}: column {tcol!r}: unknown time unit; expected time_s or time_ms")
    agcol = pick("table_accel", True)
    tdcol = pick("table_disp", False)
    side_names, side_masses = _sidecar_levels(side, side.get("_path", where))
    order_name, order_from = _order(level_order, side, side.get("_path", where))
    lv = side.get("levels", {})
    if isinstance(lv, Mapping) and "a1" in lv:
        raise ValueError(f"{side['_path']}: [levels] a1 is for the folder layout (files a1..aN); a CSV "
                         "names its levels by column")
    found = []
    for c in cols:
        if "_accel_abs" in c:
            found.append(c.split("_accel_abs")[0])
    if side_names is None:
        if not found:
            raise ValueError(f"{where}: no <LEVEL>_accel_abs_<unit> columns; columns are {', '.join(cols)}")
        side_names = found  # file order, taken in the stated level order
    else:
        for lvl in side_names:
            for kind in ("accel_abs", "disp_rel"):
                if pick(f"{lvl}_{kind}", False) is None:
                    raise ValueError(f"{where}: no column {lvl}_{kind}_<unit> for level {lvl!r} of [levels] "
                                     f"names in {side['_path']}; columns are {', '.join(cols)}")
    accel, disp = [], []
    for lvl in side_names:
        ac = pick(f"{lvl}_accel_abs", True)
        dc = pick(f"{lvl}_disp_rel", True)
        accel.append(column(ac) * _unit_of(ac, "accel", ACCEL_UNITS, units, where))
        disp.append(column(dc) * _unit_of(dc, "disp", DISP_UNITS, units, where))
    m = _level_masses(masses, weights, weight_unit, side_masses, len(side_names), side.get("_path", where),
                      sidecar=side.get("_path", str(path.with_name(path.name.split(".")[0] + ".toml"))))
    if order_name == "roof-first":  # the lists were given roof first: put them bottom-up
        m = m[::-1].copy()
        side_names = side_names[::-1]
        accel, disp = accel[::-1], disp[::-1]
    stem = path.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    meta = {"layout": "csv", **{k: v for k, v in side.items() if k not in ("levels", "units", "_path")},
            "level_order": order_name, "level_order_source": order_from,
            "masses_source": ("the argument masses" if masses is not None else
                              "the argument weights" if weights is not None else side.get("_path", where))}
    time = column(tcol) * tfac
    t_rate = (time.size - 1) / (time[-1] - time[0]) if time.size > 1 and time[-1] > time[0] else math.nan
    stated = ((rate_hz, "the argument rate_hz"), (side.get("rate_hz"), f"rate_hz in {side.get('_path')}"))
    for value, given in stated:
        if value is not None and math.isfinite(t_rate) and not (
                isinstance(value, (int, float)) and abs(t_rate - float(value)) <= 1e-6 * t_rate):
            raise ValueError(f"{where}: {given} = {value!r} Hz disagrees with its column {tcol!r} "
                             f"({t_rate:.6g} Hz); a CSV's sampling rate is its time column")
    meta["rate_source"] = f"its column {tcol!r}"
    return ShakeTableRun(
        name=name or str(side.get("name", stem)),
        time=time,
        table_accel=column(agcol) * _unit_of(agcol, "accel", ACCEL_UNITS, units, where),
        accel=np.column_stack(accel),
        disp=np.column_stack(disp),
        masses=m,
        level_names=tuple(side_names),
        table_disp=(None if tdcol is None
                    else column(tdcol) * _unit_of(tdcol, "disp", DISP_UNITS, units, where)),
        source=str(path),
        meta=meta,
    )


def read_run(
    path: str | Path,
    *,
    name: str | None = None,
    rate_hz: float | None = None,
    masses: Sequence[float] | None = None,
    weights: Sequence[float] | None = None,
    weight_unit: str = "kN",
    level_order: str | None = None,
    a1: str | None = None,
    check: bool = True,
    cutoff_hz: float = 5.0,
    tol: float = 0.1,
) -> ShakeTableRun:
    """Read a shake-table run (folder layout or CSV layout, see the module docstring).

    Parameters
    ----------
    path : a folder of ``a1..aN``, ``d1..dN``, ``u``, ``du`` files, or a CSV (``.csv`` /
        ``.csv.gz``) with a TOML sidecar.
    name : label (default: the sidecar's ``name`` or the file/folder name).
    rate_hz : sampling rate of the folder layout [Hz] (default: ``rate_hz`` in its sidecar); for a
        CSV it must agree with the time column.
    masses, weights : level masses [t] or weights [``weight_unit``], in ``level_order``; override
        the sidecar.  Weights are divided by g = 9.81 m/s^2.
    level_order : ``"base-first"`` or ``"roof-first"``: how every list of levels runs (masses,
        weights, sidecar names, the CSV's columns when no names are given); overrides
        ``[levels] level_order`` of the sidecar; default base-first.
    a1 : folder layout: the level of the files ``a1``/``d1``, ``"roof"`` (default, the BNCS
        convention) or ``"base"``; overrides ``[levels] a1`` of the sidecar.
    check : run :func:`check_consistency` (``cutoff_hz``, ``tol``) and :func:`check_level_order`,
        warn on failures, and raise when the failure is that of a wrong sampling rate.

    The sidecar format, its keys and units: ``docs/shake_table_data.md``.

    Raises
    ------
    MissingMetadataError : the sampling rate or the level masses are not stated.
    ValueError : missing file/column, malformed value (names file, column/line and value),
        unknown unit, masses of the wrong count, a sampling rate the channels contradict
        (:meth:`ConsistencyReport.rate_looks_wrong`: "the sampling rate ... looks wrong").

    Warns
    -----
    ConsistencyWarning : a consistency check failed (the report is in ``run.consistency``).
    LevelOrderWarning : the levels look upside down, or the masses listed in the opposite order
        (:func:`check_level_order`).
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"shake-table run {str(p)!r} does not exist (a folder or a CSV file)")
    if p.is_dir():
        run = _read_folder(p, name, rate_hz, masses, weights, weight_unit, level_order, a1)
    else:
        if a1 is not None:
            raise ValueError(f"{p}: a1 is for the folder layout (files a1..aN); a CSV names its levels "
                             "by column")
        run = _read_csv(p, name, masses, weights, weight_unit, level_order, rate_hz)
    if check:
        if run.time.size <= _MIN_FILTER_SAMPLES:
            raise ValueError(f"{run.source}: {run.time.size} samples are too few for the consistency check "
                             f"(the low-pass needs more than {_MIN_FILTER_SAMPLES}); pass check=False")
        try:
            rep = check_consistency(run, cutoff_hz=cutoff_hz, tol=tol)
        except ValueError as exc:
            rate = (f" (rate_hz = {run.meta['rate_hz']!r} Hz from {run.meta['rate_source']})"
                    if "rate_source" in run.meta else "")
            raise ValueError(f"{run.source}{rate}: {exc}") from None
        run = replace(run, consistency=rep)
        if rep.rate_looks_wrong():
            raise _wrong_rate_error(run, rep)
        if not rep.ok:
            warnings.warn(f"run {run.name!r} ({run.source}): " + str(rep), ConsistencyWarning, stacklevel=2)
        for msg in check_level_order(run):
            warnings.warn(f"run {run.name!r} ({run.source}): {msg}", LevelOrderWarning, stacklevel=2)
    return run


def _wrong_rate_error(run: ShakeTableRun, rep: ConsistencyReport) -> MetadataError:
    src = run.meta.get("rate_source", "")
    folder = run.meta.get("layout") == "folder"
    stated = f"{run.rate_hz:.6g} Hz" + (f" ({src})" if src else "")
    n_pass = int(rep.table["passed"].sum())
    unit = "in m" if folder else "in the unit their column names"
    fact = (f"{run.source}: the sampling rate {stated} looks wrong: at {run.rate_hz:.6g} Hz the second "
            f"derivative of the displacements is {1 / rep.scale:.3g} times the measured accelerations "
            f"relative to the table (median of {len(rep.table)} channels, correlation >= "
            f"{rep.scale_correlation:.4f} after a {rep.cutoff_hz:g} Hz low-pass; {n_pass} of "
            f"{len(rep.table)} consistency checks pass), which a rate of about "
            f"{rep.implied_rate_hz:.3g} Hz would explain (or displacements not {unit})")
    if folder:
        sidecar = str(run.meta.get("sidecar") or Path(run.source) / "run.toml")
        hint = f"give the recorder's rate: rate_hz= or rate_hz in {sidecar} (docs/shake_table_data.md)"
        return MetadataError(fact, hint, what="rate_hz", sidecar=sidecar)
    return MetadataError(fact, "check the time column and the unit suffixes (docs/shake_table_data.md)",
                         what="time", sidecar="")


def write_run(run: ShakeTableRun, path: str | Path, *, float_format: str = "%.7g",
              extra: Mapping[str, Any] | None = None) -> Path:
    """Write ``run`` in the CSV layout (gzip if ``path`` ends in ``.gz``) and its TOML sidecar
    ``<stem>.toml`` (level names and masses [t], ``rate_hz`` and ``extra`` keys)."""
    p = Path(path)
    run.to_frame().to_csv(p, index=False, float_format=float_format,
                          compression="gzip" if p.suffix == ".gz" else None)
    stem = p.name
    for suf in (".gz", ".csv"):
        stem = stem.removesuffix(suf)
    lines = [f'name = "{run.name}"', f"rate_hz = {run.rate_hz:.12g}"]
    for k, v in (extra or {}).items():
        lines.append(f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"')
    lines += ["", "[levels]  # bottom-up: the base slab above the isolators first, the roof last",
              "names = [" + ", ".join(f'"{s}"' for s in run.level_names) + "]",
              "masses = [" + ", ".join(f"{m:.10g}" for m in run.masses) + "]", 'mass_unit = "t"', ""]
    p.with_name(f"{stem}.toml").write_text("\n".join(lines))
    return p


# ---------------------------------------------------------------------------------- bundled runs
def available_runs() -> tuple[str, ...]:
    """Names of the bundled BNCS runs (``CNP100``, ``ICA100``, ``ICA50``, ``LAC100``)."""
    return tuple(sorted(p.name.removesuffix(".csv.gz") for p in _DATA.glob("*.csv.gz")))


def load_run(name: str, *, check: bool = True) -> ShakeTableRun:
    """A bundled BNCS run (50 Hz, anti-alias filtered; see the PROVENANCE.md next to the data)."""
    names = available_runs()
    if name not in names:
        raise ValueError(f"unknown shake-table run {name!r}; bundled: {', '.join(names)}")
    return read_run(_DATA / f"{name}.csv.gz", check=check)


def open_run(spec: str | Path, **read: Any) -> ShakeTableRun:
    """A run from a bundled name (``"ICA50"``, :func:`available_runs`), a folder or a CSV, read by
    :func:`read_run` with the keyword arguments ``read`` (rate, masses, level order ...)."""
    s = str(spec)
    if s in available_runs() and not Path(s).exists():
        return read_run(_DATA / f"{s}.csv.gz", **read)
    if not Path(s).exists():
        raise ValueError(f"run {s!r} is neither a bundled run ({', '.join(available_runs())}) nor an "
                         "existing folder or CSV file")
    return read_run(s, **read)
