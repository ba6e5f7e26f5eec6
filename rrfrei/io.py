"""Reading cyclic shear tests: :func:`read_test` -> :class:`ShearTest`.

A test file is a CSV whose column names carry their units::

    time_s, disp_mm, force_kN[, vertical_kN]

Accepted suffixes: time ``_s``, ``_ms``, ``_min``; displacement ``_m``, ``_cm``, ``_mm``, ``_in``;
force (also vertical load) ``_N``, ``_kN``, ``_MN``, ``_lbf``, ``_kip``.  Files that do not follow
this convention are read by naming the columns (by name or 0-based position) and their units; a
second header row made only of unit names (``kN,mm``) is recognised and used for the units.

Bearing geometry (outer diameter ``d2``, layer thickness ``tr``, number of layers ``n``, ...; m)
comes from a sidecar TOML next to the CSV (``<file>.toml``, ``<stem>.toml`` or ``geometry.toml``)
or from ``geometry=``; it fixes the geometry parameters of laws such as ``elastomeric_x``.

Internally everything is SI-kN: displacement [m], force [kN], time [s].
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rrfrei._inputs import read_toml

__all__ = ["ShearTest", "concat_tests", "read_test", "load_test", "bundled_tests", "MIN_POINTS", "read_toml"]

MIN_POINTS = 10
"""Fewest samples a test may have."""

DISP_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254}
FORCE_UNITS = {"n": 1e-3, "kn": 1.0, "mn": 1e3, "lbf": 4.4482216152605e-3, "kip": 4.4482216152605}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "min": 60.0}

GEOMETRY_ALIASES = {"diameter": "d2", "outer_diameter": "d2", "inner_diameter": "d1",
                    "layer_thickness": "tr", "layers": "n", "n_layers": "n", "cover": "tc"}

_BUNDLED = ("protocol1", "protocol2", "protocol3", "protocol4")


@dataclass(frozen=True, eq=False)
class ShearTest:
    """A cyclic (or monotonic) shear test of one bearing.

    Attributes
    ----------
    name : short label (file stem by default).
    time : (n,) time [s]; the sample index when the file has no time (``has_time`` False).
    disp : (n,) shear displacement [m].
    force : (n,) shear force [kN].
    has_time : whether ``time`` is real time.  Without it, rate effects cannot be judged.
    vertical_load : design/axial vertical load [kN] (constant), or None.
    geometry : bearing geometry in m (keys are law parameter names: d1, d2, tr, n, tc, ...).
    source : file path, or "" for tests built in memory.
    meta : anything else (column names, units, notes).
    preceding : earlier tests of the same specimen, in chronological order, that a model
        simulates (but does not score) before this one, so the state a bearing carries from one
        run to the next (scragging, degradation, plastic offset) is in its prediction
        (:func:`rrfrei.gap.model.IsolatorFit.predict`); set it with :meth:`after`.  Nested
        histories are flattened (each earlier test's own ``preceding`` comes first).  Not part of
        the samples: never written to CSV (:meth:`to_frame`), not compared.
    """

    name: str
    time: np.ndarray
    disp: np.ndarray
    force: np.ndarray
    has_time: bool = True
    vertical_load: float | None = None
    geometry: dict = field(default_factory=dict)
    source: str = ""
    meta: dict = field(default_factory=dict)
    preceding: tuple = field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        for key in ("time", "disp", "force"):
            arr = np.ascontiguousarray(np.asarray(getattr(self, key), dtype=float))
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        where = f" in {self.source}" if self.source else f" of test {self.name!r}"
        n = self.disp.size
        if self.disp.ndim != 1 or self.force.shape != self.disp.shape or self.time.shape != self.disp.shape:
            raise ValueError(
                f"time, disp and force{where} must be 1-D of equal length; got shapes "
                f"{self.time.shape}, {self.disp.shape}, {self.force.shape}"
            )
        if n < MIN_POINTS:
            raise ValueError(f"test{where} has {n} samples; at least {MIN_POINTS} are needed")
        for key in ("time", "disp", "force"):
            arr = getattr(self, key)
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise ValueError(f"{key}{where} is not finite at sample {bad[0]} (value {arr[bad[0]]})")
        if not np.ptp(self.disp) > 0:
            raise ValueError(f"displacement{where} is constant ({self.disp[0]} m): no displacement range")
        if self.has_time:
            dt = np.diff(self.time)
            if np.any(dt <= 0):
                i = int(np.flatnonzero(dt <= 0)[0])
                raise ValueError(
                    f"time{where} must increase strictly; sample {i + 1} has {self.time[i + 1]} s "
                    f"after {self.time[i]} s"
                )
        object.__setattr__(self, "geometry", _check_geometry(dict(self.geometry), where))
        if self.preceding:
            object.__setattr__(self, "preceding", _flatten_preceding(self.preceding, where))
            _merge_geometry([*self.preceding, self])

    def after(self, *earlier: ShearTest) -> ShearTest:
        """A copy of this test run after ``earlier`` (chronological order) on the same specimen.

        Raises
        ------
        ValueError
            an element is not a :class:`ShearTest`, or its geometry disagrees with this test's.
        """
        return replace(self, preceding=tuple(earlier))

    def __len__(self) -> int:
        return int(self.disp.size)

    @property
    def disp_range(self) -> tuple[float, float]:
        """(min, max) displacement [m]."""
        return float(self.disp.min()), float(self.disp.max())

    def to_frame(self) -> pd.DataFrame:
        """Columns ``time_s``, ``disp_m``, ``force_kN``."""
        return pd.DataFrame({"time_s": self.time, "disp_m": self.disp, "force_kN": self.force})


def _flatten_preceding(preceding, where: str) -> tuple[ShearTest, ...]:
    if isinstance(preceding, ShearTest) or not isinstance(preceding, Sequence):
        raise ValueError(f"preceding{where} must be a tuple of ShearTest (earliest first), got "
                         f"{type(preceding).__name__}")
    out: list[ShearTest] = []
    for k, t in enumerate(preceding):
        if not isinstance(t, ShearTest):
            raise ValueError(f"preceding[{k}]{where} must be a ShearTest, got {type(t).__name__}")
        out.extend(t.preceding)
        out.append(replace(t, preceding=()) if t.preceding else t)
    return tuple(out)


def _merge_geometry(tests: Sequence[ShearTest]) -> dict[str, float]:
    """The union of the tests' geometries; a key given twice must have one value."""
    geo: dict[str, float] = {}
    owner: dict[str, str] = {}
    for t in tests:
        for k, v in t.geometry.items():
            if k in geo and geo[k] != v:
                raise ValueError(f"geometry of test {t.name!r} disagrees with test {owner[k]!r}: "
                                 f"{k} = {v} m, expected {geo[k]} m (one specimen)")
            geo.setdefault(k, v)
            owner.setdefault(k, t.name)
    return geo


def concat_tests(tests: Sequence[ShearTest], name: str | None = None) -> ShearTest:
    """Join tests of one specimen into one test, in the order given.

    Each part's time is shifted so that it starts one sampling interval (its own first step)
    after the previous part ends; ``has_time`` only when every part has real time (else the time
    is the sample index).  The geometry is the union of the parts' (a key given by two parts must
    agree); the vertical load is the parts' common value (None when they differ); the result's
    ``preceding`` is the first part's, and ``meta["parts"]`` lists ``(name, samples)``.

    Parameters
    ----------
    tests : one or more :class:`ShearTest`, earliest first.
    name : label (default: the parts' names joined by ``+``).

    Raises
    ------
    ValueError
        no tests, an element that is not a ShearTest, or disagreeing geometry.
    """
    tests = [] if isinstance(tests, ShearTest) else list(tests)
    if not tests:
        raise ValueError("concat_tests: tests must be a non-empty sequence of ShearTest")
    for k, t in enumerate(tests):
        if not isinstance(t, ShearTest):
            raise ValueError(f"concat_tests: tests[{k}] must be a ShearTest, got {type(t).__name__}")
    geo = _merge_geometry(tests)
    has_time = all(t.has_time for t in tests)
    if has_time:
        parts = [tests[0].time]
        for t in tests[1:]:
            step = float(t.time[1] - t.time[0])
            parts.append(t.time - t.time[0] + parts[-1][-1] + step)
        time = np.concatenate(parts)
    else:
        time = np.arange(sum(len(t) for t in tests), dtype=float)
    loads = {t.vertical_load for t in tests}
    return ShearTest(
        name=name if name is not None else "+".join(t.name for t in tests),
        time=time,
        disp=np.concatenate([t.disp for t in tests]),
        force=np.concatenate([t.force for t in tests]),
        has_time=has_time,
        vertical_load=loads.pop() if len(loads) == 1 else None,
        geometry=geo,
        meta={"parts": [(t.name, len(t)) for t in tests]},
        preceding=tests[0].preceding,
    )


def _check_geometry(geometry: Mapping[str, Any], where: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for key, value in geometry.items():
        name = GEOMETRY_ALIASES.get(str(key), str(key))
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"geometry{where}: {key} = {value!r} is not a number") from None
        if not math.isfinite(x) or x < 0:
            raise ValueError(f"geometry{where}: {key} = {value!r} must be finite and >= 0")
        out[name] = x
    return out


# ---------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------
def _split_unit(name: str) -> tuple[str, str | None]:
    """``"disp_mm"`` -> ("disp", "mm"); ``"force [kN]"`` -> ("force", "kN")."""
    s = name.strip()
    m = re.match(r"^(?P<base>.*?)\s*[\[\(](?P<unit>[^\]\)]+)[\]\)]\s*$", s)
    if m:
        return m.group("base").strip(), m.group("unit").strip()
    if "_" in s:
        base, unit = s.rsplit("_", 1)
        return base.strip(), unit.strip()
    return s, None


def _unit_factor(unit: str, table: dict[str, float], what: str, where: str) -> float:
    key = unit.strip().lower()
    if key not in table:
        raise ValueError(
            f"{where}: unknown {what} unit {unit!r}; expected one of {', '.join(sorted(table))}"
        )
    return table[key]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _find_column(names: list[str], requested, kinds: tuple[str, ...], what: str, where: str,
                 required: bool) -> int | None:
    if requested is not None:
        if isinstance(requested, (int, np.integer)):
            if not 0 <= int(requested) < len(names):
                raise ValueError(f"{where}: {what} column {requested} is out of range (0..{len(names) - 1})")
            return int(requested)
        stripped = [n.strip() for n in names]
        if str(requested).strip() in stripped:
            return stripped.index(str(requested).strip())
        raise ValueError(f"{where}: no {what} column named {requested!r}; columns are {stripped}")
    hits = [i for i, n in enumerate(names) if _split_unit(n)[0].lower() in kinds]
    if len(hits) > 1:
        raise ValueError(
            f"{where}: several {what} columns {[names[i] for i in hits]}; choose one with {what}_col="
        )
    if not hits:
        if required:
            raise ValueError(
                f"{where}: no {what} column found among {[n.strip() for n in names]}; name it "
                f"{kinds[0]}_<unit> or pass {what}_col= and {what}_unit="
            )
        return None
    return hits[0]


def read_test(
    path: str | Path,
    *,
    disp_col: str | int | None = None,
    force_col: str | int | None = None,
    time_col: str | int | None = None,
    disp_unit: str | None = None,
    force_unit: str | None = None,
    skiprows: int | None = None,
    name: str | None = None,
    geometry: Mapping[str, float] | str | Path | None = None,
) -> ShearTest:
    """Read a shear test from a CSV file.

    Parameters
    ----------
    path : CSV file.  The first row holds column names; an optional second row of unit names
        only (e.g. ``kN,mm``) is recognised.
    disp_col, force_col, time_col : column name or 0-based position; default: found from the
        names (``disp_*``, ``force_*``, ``time_*``).
    disp_unit, force_unit : units of those columns when the name does not carry them
        (``m``, ``cm``, ``mm``, ``in``; ``N``, ``kN``, ``MN``, ``lbf``, ``kip``).
    skiprows : number of rows to skip after the header (e.g. an unrecognised units row).
    name : label (default: file stem).
    geometry : mapping of geometry values [m] (``d2``/``diameter``, ``tr``, ``n``, ``d1``, ``tc``)
        or a TOML file; default: the sidecar TOML, if any.

    Returns
    -------
    ShearTest with displacement [m], force [kN] and time [s] (or sample index and
    ``has_time=False`` when there is no time column).

    Raises
    ------
    FileNotFoundError
        the file does not exist.
    ValueError
        malformed file (or sidecar TOML), or a directory: the message names the file, the column
        and the row.

    Examples
    --------
    >>> t = read_test("SPC1.csv", disp_col="Lead Actuator Displacment",  # doctest: +SKIP
    ...               force_col="Lead Actuator Force")  # units from the second header row
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    where = str(path)
    if path.is_dir():
        raise ValueError(f"{where}: is a directory; expected a CSV file")
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{where}: not a text CSV file (byte {exc.start} is not UTF-8 text: "
                         "a binary file, or another encoding)") from None
    except csv.Error as exc:
        raise ValueError(f"{where}: malformed CSV: {exc}") from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{where}: the file is empty")
    header = [c.strip() for c in rows[0]]
    body = rows[1:]
    first_data_row = 2  # 1-based file row of body[0] (blank lines dropped)
    units_row: list[str] | None = None
    if body and not any(_is_number(c) for c in body[0] if c.strip()):
        units_row = [c.strip() for c in body[0]]
        body = body[1:]
        first_data_row += 1
    if skiprows:
        body = body[int(skiprows):]
        first_data_row += int(skiprows)

    idx_d = _find_column(header, disp_col, ("disp", "displacement", "d", "u"), "disp", where, True)
    idx_f = _find_column(header, force_col, ("force", "f", "shear"), "force", where, True)
    idx_t = _find_column(header, time_col, ("time", "t"), "time", where, False)
    idx_v = _find_column(header, None, ("vertical", "axial", "p"), "vertical", where, False)

    def unit_of(idx: int, given: str | None, what: str) -> str:
        if given is not None:
            return given
        if units_row is not None and idx < len(units_row) and units_row[idx]:
            return units_row[idx].strip("[]() ")
        _, unit = _split_unit(header[idx])
        if unit is None:
            raise ValueError(f"{where}: column {header[idx]!r} carries no unit; pass {what}_unit=")
        return unit

    fd = _unit_factor(unit_of(idx_d, disp_unit, "disp"), DISP_UNITS, "displacement", f"{where}, column "
                      f"{header[idx_d]!r}")
    ff = _unit_factor(unit_of(idx_f, force_unit, "force"), FORCE_UNITS, "force",
                      f"{where}, column {header[idx_f]!r}")
    ft = None
    if idx_t is not None:
        ft = _unit_factor(unit_of(idx_t, None, "time"), TIME_UNITS, "time",
                          f"{where}, column {header[idx_t]!r}")
    fv = None
    if idx_v is not None:
        fv = _unit_factor(unit_of(idx_v, None, "vertical"), FORCE_UNITS, "force",
                          f"{where}, column {header[idx_v]!r}")

    cols = [i for i in (idx_t, idx_d, idx_f, idx_v) if i is not None]
    data = np.empty((len(body), max(cols) + 1))
    for r, row in enumerate(body):
        for c in cols:
            if c >= len(row):
                raise ValueError(
                    f"{where}, row {first_data_row + r}, column {header[c]!r}: missing (the row has "
                    f"{len(row)} fields, the header {len(header)})"
                )
            text = row[c].strip()
            try:
                x = float(text)
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                raise ValueError(
                    f"{where}, row {first_data_row + r}, column {header[c]!r}: {text!r} is not a "
                    f"finite number"
                )
            data[r, c] = x
    if len(body) < MIN_POINTS:
        raise ValueError(f"{where}: {len(body)} data rows; at least {MIN_POINTS} are needed")
    disp = data[:, idx_d] * fd
    force = data[:, idx_f] * ff
    if idx_t is not None:
        time = data[:, idx_t] * ft
        dt = np.diff(time)
        if np.any(dt <= 0):
            i = int(np.flatnonzero(dt <= 0)[0]) + 1
            raise ValueError(
                f"{where}, row {first_data_row + i}, column {header[idx_t]!r}: time "
                f"{data[i, idx_t]} does not increase (previous {data[i - 1, idx_t]})"
            )
        has_time = True
    else:
        time = np.arange(disp.size, dtype=float)
        has_time = False
    if not np.ptp(disp) > 0:
        raise ValueError(f"{where}, column {header[idx_d]!r}: displacement is constant; no range to fit")
    vertical = None
    if idx_v is not None:
        vertical = float(np.mean(data[:, idx_v] * fv))

    geo: dict[str, float] = {}
    meta: dict[str, Any] = {"columns": {"disp": header[idx_d], "force": header[idx_f]}}
    if idx_t is not None:
        meta["columns"]["time"] = header[idx_t]
    sidecar = _sidecar(path) if geometry is None else None
    if isinstance(geometry, (str, Path)):
        sidecar = Path(geometry)
    if sidecar is not None:
        g, v, notes = _read_geometry_toml(sidecar)
        geo.update(g)
        if vertical is None:
            vertical = v
        meta.update(notes)
        meta["geometry_file"] = str(sidecar)
    elif isinstance(geometry, Mapping):
        geo.update(geometry)
    return ShearTest(
        name=name or path.stem,
        time=time,
        disp=disp,
        force=force,
        has_time=has_time,
        vertical_load=vertical,
        geometry=geo,
        source=str(path),
        meta=meta,
    )


def _sidecar(path: Path) -> Path | None:
    for cand in (path.with_name(path.name + ".toml"), path.with_suffix(".toml"),
                 path.with_name("geometry.toml")):
        if cand.exists():
            return cand
    return None


def _read_geometry_toml(path: Path) -> tuple[dict[str, float], float | None, dict]:
    """``[geometry]`` table (m) and optional ``vertical_load_kN``; other top-level keys -> meta."""
    data = read_toml(path)
    geo = data.get("geometry", {})
    if not isinstance(geo, dict):
        raise ValueError(f"{path}: [geometry] must be a table of numbers in m")
    geo = _check_geometry(geo, f" in {path}")
    vertical = data.get("vertical_load_kN")
    if vertical is not None:
        if isinstance(vertical, bool) or not isinstance(vertical, (int, float)):
            raise ValueError(f"{path}: vertical_load_kN = {vertical!r} is not a number")
        vertical = float(vertical)
        if not math.isfinite(vertical):
            raise ValueError(f"{path}: vertical_load_kN = {vertical!r} must be a finite number [kN]")
    notes = {k: v for k, v in data.items() if k not in ("geometry", "vertical_load_kN")}
    return geo, vertical, notes


def bundled_tests() -> tuple[str, ...]:
    """Names of the bundled tests (SYNTHETIC RR-FREI-like tests, see their README)."""
    return _BUNDLED


def load_test(name: str) -> ShearTest:
    """Load a bundled test: ``"protocol1"`` .. ``"protocol4"``.

    These are SYNTHETIC RR-FREI-like tests (80 mm diameter, 15 layers of 2 mm, design vertical
    load 19.25 kN), made by an independent model with noise; see
    ``rrfrei/data/isolator_synthetic/README.md``.
    """
    key = str(name).strip().removesuffix(".csv")
    if key not in _BUNDLED:
        raise ValueError(f"unknown bundled test {name!r}; available: {', '.join(_BUNDLED)}")
    root = resources.files("rrfrei") / "data" / "isolator_synthetic"
    with resources.as_file(root / f"{key}.csv") as p:
        test = read_test(p, name=key)
    return test
