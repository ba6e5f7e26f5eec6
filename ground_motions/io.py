"""Readers for accelerogram files: PEER ``.AT2``, CSMIP ``.V2`` / ``.V1`` (``.RAW``), text, CSV.

All readers return a :class:`~ground_motions.record.Record` in m/s^2 and check what the file
says about itself: the number of values against the declared count (the last, partial line is
kept), a finite, positive, uniform time step, and numeric, finite values.  Every error is a
``ValueError`` naming the file, the line (1-based) and the offending value.

Formats
-------
``at2``
    PEER NGA / PEER-SMD.  Line 2: ``event, date, station, component``; line 3 states the units
    (``UNITS OF G``); line 4 is either ``NPTS= 5372, DT= .0100 SEC,`` (NGA-West2; the old
    PEER-SMD variant appends filter poles) or ``4096 0.0100 NPTS, DT`` (NGA-West1 tools).
    Values follow, whitespace separated (E15.7).
``v2``
    CGS/CSMIP corrected Volume 2, old CDMG layout (``3000 POINTS OF ACCEL DATA EQUALLY SPACED AT
    .020 SEC. (UNITS: CM/SEC/SEC)``, 8F10.3) and the 2018 "Avol" layout (``10100 points of accel
    data equally spaced at 0.010 sec, in cm/sec2. (8f10.5)``).  Values are fixed-width fields
    (they may touch, e.g. ``-0.0147353-0.0147984``), so they are cut by column, never split on
    blanks.  Channels are separated by ``/&`` lines; velocity and displacement blocks are skipped.
``v1``
    CSMIP uncorrected Volume 1 (Avol layout: ``35430 Accelerogram points at 100 pts/sec in units
    of g. Format: (8f9.6)``).  No baseline or instrument correction is applied here: see
    :func:`ground_motions.processing.baseline_correct`.
``text``
    One column (acceleration; ``dt`` required) or two columns (time [s], acceleration).
    Blank lines and lines starting with ``#`` are skipped.  ``units`` is required.
``csv``
    A header row naming the columns with unit suffixes: optional ``time_s`` and one or more of
    ``accel_g``, ``accel_mps2``, ``accel_cmps2``, ``accel_mmps2`` (``channel`` picks among the
    acceleration columns, default the first).
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from .record import G, Record

#: Factors from accepted unit spellings to m/s^2.
UNITS: dict[str, float] = {
    "g": G,
    "m/s^2": 1.0,
    "m/s2": 1.0,
    "mps2": 1.0,
    "cm/s^2": 0.01,
    "cm/s2": 0.01,
    "cmps2": 0.01,
    "cm/sec/sec": 0.01,
    "cm/sec2": 0.01,
    "gal": 0.01,
    "mm/s^2": 0.001,
    "mm/s2": 0.001,
    "mmps2": 0.001,
}

FORMATS = ("at2", "v2", "v1", "text", "csv")
_EXT = {".at2": "at2", ".v2": "v2", ".v1": "v1", ".raw": "v1", ".csv": "csv"}
_VERTICAL = {"UP", "DOWN", "DN", "VERT", "VERTICAL", "V", "Z", "HNZ"}
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"


def unit_factor(units: str, *, where: str = "units") -> float:
    """Factor converting ``units`` to m/s^2 (``ValueError`` listing the accepted spellings)."""
    key = str(units).strip().lower().replace(" ", "")
    if key not in UNITS:
        raise ValueError(f"{where}: unknown acceleration units {units!r}; expected one of {sorted(UNITS)}")
    return UNITS[key]


def _check_dt(dt: float, path: Path, line: int | None, given: float | None) -> float:
    where = f"{path}" + (f", line {line}" if line else "")
    if not math.isfinite(dt) or dt <= 0.0:
        raise ValueError(f"{where}: time step dt = {dt!r} s must be finite and > 0")
    if given is not None and not math.isclose(float(given), dt, rel_tol=1e-6):
        raise ValueError(f"{where}: the file says dt = {dt} s but dt={given} was passed")
    return dt


def _float(token: str, path: Path, line: int) -> float:
    try:
        x = float(token.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise ValueError(f"{path}, line {line}: value {token.strip()!r} is not a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{path}, line {line}: value {token.strip()!r} is not finite")
    return x


def _values_split(lines: list[str], start: int, npts: int, path: Path) -> tuple[list[float], int]:
    """Whitespace-separated values from ``lines[start:]`` until ``npts`` are read."""
    out: list[float] = []
    i = start
    while len(out) < npts and i < len(lines):
        for tok in lines[i].split():
            out.append(_float(tok, path, i + 1))
        i += 1
    return out, i


def _values_fixed(lines: list[str], start: int, npts: int, width: int, path: Path) -> tuple[list[float], int]:
    """Fixed-width values (``width`` columns each) from ``lines[start:]`` until ``npts`` are read."""
    out: list[float] = []
    i = start
    while len(out) < npts and i < len(lines):
        text = lines[i].rstrip("\r\n")
        if text.startswith("/&"):
            break
        for j in range(0, len(text), width):
            tok = text[j : j + width]
            if tok.strip():
                out.append(_float(tok, path, i + 1))
        i += 1
    return out, i


def _to_si(a: np.ndarray, factor: float, units: str, path: Path) -> np.ndarray:
    """``a * factor`` (to m/s^2), or a ValueError naming the first value that overflows."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.asarray(a, dtype=np.float64) * factor
    bad = np.flatnonzero(~np.isfinite(out))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{path}: value {float(a[i])!r} {units} (sample {i}) overflows when converted to "
                         "m/s^2")
    return out


def _check_count(values: list[float], npts: int, path: Path, line: int, what: str) -> np.ndarray:
    if len(values) != npts:
        raise ValueError(
            f"{path}, line {line}: header declares NPTS = {npts} {what} but {len(values)} values were read"
        )
    return np.asarray(values, dtype=np.float64)


# --------------------------------------------------------------------------- AT2
_AT2_NEW = re.compile(rf"NPTS\s*=\s*(\d+)\s*,?\s*DT\s*=\s*({_NUM})", re.I)
_AT2_OLD = re.compile(rf"^\s*(\d+)\s+({_NUM})\s+NPTS\s*,?\s*DT", re.I)


def _read_at2(path: Path, lines: list[str], dt_given: float | None, units: str | None) -> Record:
    if len(lines) < 5:
        raise ValueError(f"{path}: an AT2 file needs 4 header lines and data, found {len(lines)} lines")
    m = _AT2_NEW.search(lines[3]) or _AT2_OLD.search(lines[3])
    if m is None:
        raise ValueError(
            f"{path}, line 4: expected 'NPTS= n, DT= dt SEC' or 'n dt NPTS, DT', got {lines[3].strip()!r}"
        )
    npts = int(m.group(1))
    dt = _check_dt(_float(m.group(2), path, 4), path, 4, dt_given)
    head = lines[2].upper()
    if units is None:
        if "UNITS OF G" in head:
            units = "g"
        elif "CM/S" in head:
            units = "cm/s^2"
        else:
            raise ValueError(f"{path}, line 3: cannot tell the units from {lines[2].strip()!r}; pass units=")
    factor = unit_factor(units, where=str(path))
    values, _ = _values_split(lines, 4, 1 << 62, path)
    a = _check_count(values, npts, path, 4, "values")
    parts = [p.strip() for p in lines[1].split(",")]
    meta = {"format": "at2", "source_units": units, "npts": npts, "channel": 1, "header": lines[1].strip()}
    if len(parts) >= 4:
        meta.update(event=parts[0], date=parts[1], station=", ".join(parts[2:-1]), component=parts[-1])
    else:
        meta.update(event=lines[1].strip(), station="", component="")
    if "POLE" in lines[3].upper():
        meta["filter"] = lines[3].split("SEC,", 1)[-1].strip()
    return Record(path.stem, dt, _to_si(a, factor, units, path), meta)


# --------------------------------------------------------------------------- CSMIP V1/V2
_V2_DATA = re.compile(
    rf"^\s*(\d+)\s+points\s+of\s+accel\s+data\s+equally\s+spaced\s+at\s+({_NUM})\s*sec"
    r"(?P<rest>.*)$",
    re.I,
)
_V1_DATA = re.compile(
    rf"^\s*(\d+)\s+accelerogram\s+points\s+at\s+({_NUM})\s*pts/sec\s+in\s+units\s+of\s+(\S+?)\.?\s"
    r"(?P<rest>.*)$",
    re.I,
)
_FORTRAN = re.compile(r"\(\s*(\d+)\s*f\s*(\d+)\s*\.\s*(\d+)\s*\)", re.I)
_CHAN = re.compile(r"^\s*chan\s+(\d+)\s*:\s*(\S+)(?:\s+deg)?", re.I)


def _split_channels(lines: list[str]) -> list[tuple[int, int]]:
    """(first, last+1) line ranges of the channels, separated by ``/&`` lines."""
    blocks, start = [], 0
    for i, ln in enumerate(lines):
        if ln.startswith("/&"):
            blocks.append((start, i))
            start = i + 1
    if any(ln.strip() for ln in lines[start:]):
        blocks.append((start, len(lines)))
    return blocks


def _csmip_channel(
    path: Path, lines: list[str], lo: int, hi: int, kind: str
) -> tuple[float, np.ndarray, dict]:
    meta: dict = {"format": kind}
    data_line = None
    for i in range(lo, hi):
        ln = lines[i]
        if "component" not in meta:
            mc = _CHAN.match(ln)
            if mc:
                meta["channel"] = int(mc.group(1))
                meta["component"] = mc.group(2).upper()
        if re.match(r"^\s*station\s+(no|id)\.", ln, re.I) and i + 1 < hi and "station" not in meta:
            meta["station"] = re.split(r"\s{3,}", lines[i + 1].strip())[0]
        if re.match(r"^\s*uncorrected\s+accelerogram", ln, re.I) and i + 1 < hi and "event" not in meta:
            meta["event"] = re.split(r"\s{3,}", lines[i + 1].strip())[0]
        m = (_V2_DATA if kind == "v2" else _V1_DATA).match(ln)
        if m:
            data_line = i
            break
    if data_line is None:
        what = (
            "'n points of accel data equally spaced at dt sec'" if kind == "v2" else "'n Accelerogram points'"
        )
        raise ValueError(f"{path}, lines {lo + 1}-{hi}: no {what} line found in this channel")
    npts = int(m.group(1))
    rest = m.group("rest")
    if kind == "v2":
        dt = _float(m.group(2), path, data_line + 1)
        low = rest.lower().replace(" ", "")
        if "cm/sec/sec" in low or "cm/sec2" in low or "cm/s2" in low:
            units = "cm/s^2"
        elif "unitsofg" in low or "ing." in low:
            units = "g"
        else:
            raise ValueError(f"{path}, line {data_line + 1}: cannot tell the units from {ln.strip()!r}")
        width = 10
    else:
        rate = _float(m.group(2), path, data_line + 1)
        if rate <= 0:
            raise ValueError(f"{path}, line {data_line + 1}: sampling rate {rate} pts/sec must be > 0")
        dt = 1.0 / rate
        units = m.group(3).lower()
        width = 9
    mf = _FORTRAN.search(rest)
    if mf:
        width = int(mf.group(2))
        if not 1 <= width <= 40:
            raise ValueError(f"{path}, line {data_line + 1}: field width {width} in the format "
                             f"{mf.group(0)!r} is invalid: expected 1..40 columns per value")
    dt = _check_dt(dt, path, data_line + 1, None)
    values, _ = _values_fixed(lines, data_line + 1, npts, width, path)
    a = _check_count(values, npts, path, data_line + 1, "accel values")
    meta.update(npts=npts, source_units=units)
    factor = unit_factor(units, where=f"{path}, line {data_line + 1}")
    return dt, _to_si(a, factor, units, path), meta


def _read_csmip(
    path: Path, lines: list[str], kind: str, dt_given: float | None, channel: int | None
) -> Record:
    blocks = _split_channels(lines)
    if not blocks:
        raise ValueError(f"{path}: no channel found")
    if channel is not None and not 1 <= int(channel) <= len(blocks):
        raise ValueError(f"{path}: channel={channel!r} but the file has channels 1..{len(blocks)}")
    if channel is None:
        chosen = None
        for k, (lo, hi) in enumerate(blocks):
            comp = next((_CHAN.match(lines[i]) for i in range(lo, hi) if _CHAN.match(lines[i])), None)
            if comp is None or comp.group(2).upper() not in _VERTICAL:
                chosen = k
                break
        if chosen is None:
            raise ValueError(f"{path}: no horizontal channel found; pass channel=1..{len(blocks)}")
    else:
        chosen = int(channel) - 1
    lo, hi = blocks[chosen]
    dt, a, meta = _csmip_channel(path, lines, lo, hi, kind)
    _check_dt(dt, path, None, dt_given)
    meta["channel"] = chosen + 1
    meta["n_channels"] = len(blocks)
    return Record(f"{path.stem}.ch{chosen + 1}", dt, a, meta)


# --------------------------------------------------------------------------- text / CSV
def _uniform_dt(t: np.ndarray, path: Path, first_line: list[int]) -> float:
    if t.size < 2:
        raise ValueError(f"{path}: a time column needs at least 2 samples to define dt")
    d = np.diff(t)
    dt = float(np.median(d))
    _check_dt(dt, path, first_line[0], None)
    bad = np.flatnonzero(np.abs(d - dt) > 1e-4 * dt + 1e-9)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{path}, line {first_line[i + 1]}: non-uniform time step: t = {float(t[i + 1])!r} after "
            f"{float(t[i])!r} (step {float(d[i])!r} s, median step {dt!r} s)"
        )
    if abs(t[0]) > 1e-6 * dt + 1e-12:
        raise ValueError(
            f"{path}, line {first_line[0]}: the time column must start at 0, got {float(t[0])!r}"
        )
    return dt


def _read_text(path: Path, lines: list[str], dt_given: float | None, units: str | None) -> Record:
    rows: list[list[float]] = []
    where: list[int] = []
    for i, ln in enumerate(lines):
        s = ln.strip()
        if not s or s.startswith("#"):
            continue
        toks = s.replace(",", " ").split()
        if len(toks) > 2:
            raise ValueError(f"{path}, line {i + 1}: expected 1 or 2 columns, got {len(toks)}: {s[:60]!r}")
        rows.append([_float(t, path, i + 1) for t in toks])
        where.append(i + 1)
        if len(rows[-1]) != len(rows[0]):
            raise ValueError(
                f"{path}, line {i + 1}: {len(rows[-1])} columns but line {where[0]} has {len(rows[0])}"
            )
    if not rows:
        raise ValueError(f"{path}: no data (empty file)")
    if units is None:
        raise ValueError(
            f"{path}: a text record does not state its units; pass units= (one of {sorted(UNITS)})"
        )
    factor = unit_factor(units, where=str(path))
    arr = np.asarray(rows)
    if arr.shape[1] == 2:
        dt = _uniform_dt(arr[:, 0], path, where)
        _check_dt(dt, path, None, dt_given)
        a = arr[:, 1]
    else:
        if dt_given is None:
            raise ValueError(f"{path}: a one-column text record has no time step; pass dt= [s]")
        dt = _check_dt(float(dt_given), path, None, None)
        a = arr[:, 0]
    meta = {"format": "text", "source_units": units, "npts": a.size, "channel": 1}
    return Record(path.stem, dt, _to_si(a, factor, units, path), meta)


_CSV_ACCEL = re.compile(r"^accel(?:_(g|mps2|cmps2|mmps2))?$", re.I)


def _read_csv(
    path: Path, text: str, dt_given: float | None, units: str | None, channel: int | None
) -> Record:
    reader = csv.reader(text.splitlines())
    rows = [(i + 1, r) for i, r in enumerate(reader) if any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{path}: no data (empty file)")
    header_line, header = rows[0]
    names = [h.strip() for h in header]
    acc_cols = [k for k, n in enumerate(names) if _CSV_ACCEL.match(n)]
    if not acc_cols:
        raise ValueError(
            f"{path}, line {header_line}: no acceleration column in {names}; expected e.g. accel_g, "
            "accel_mps2, accel_cmps2"
        )
    if channel is not None and not 1 <= int(channel) <= len(acc_cols):
        raise ValueError(f"{path}: channel={channel!r} but the file has {len(acc_cols)} acceleration columns")
    col = acc_cols[0 if channel is None else int(channel) - 1]
    suffix = _CSV_ACCEL.match(names[col]).group(1)
    if suffix is None and units is None:
        raise ValueError(f"{path}, line {header_line}: column {names[col]!r} has no unit suffix; pass units=")
    if suffix is not None and units is not None and unit_factor(units) != UNITS[suffix.lower()]:
        raise ValueError(f"{path}: units={units!r} contradicts the column name {names[col]!r}")
    src_units = units if suffix is None else suffix.lower()
    factor = unit_factor(src_units, where=str(path))
    tcol = names.index("time_s") if "time_s" in names else None
    if tcol is None and any(n.lower().startswith("time") for n in names):
        bad = next(n for n in names if n.lower().startswith("time"))
        raise ValueError(f"{path}, line {header_line}: time column {bad!r} must be named time_s (seconds)")
    data = rows[1:]
    if not data:
        raise ValueError(f"{path}: header only, no data rows")
    a = np.empty(len(data))
    t = np.empty(len(data))
    where = []
    for k, (ln, r) in enumerate(data):
        if len(r) != len(names):
            raise ValueError(f"{path}, line {ln}: {len(r)} fields but the header has {len(names)}")
        a[k] = _float(r[col], path, ln)
        if tcol is not None:
            t[k] = _float(r[tcol], path, ln)
        where.append(ln)
    if tcol is not None:
        dt = _uniform_dt(t, path, where)
        _check_dt(dt, path, None, dt_given)
    else:
        if dt_given is None:
            raise ValueError(f"{path}: no time_s column; pass dt= [s]")
        dt = _check_dt(float(dt_given), path, None, None)
    meta = {
        "format": "csv",
        "source_units": src_units,
        "npts": a.size,
        "channel": acc_cols.index(col) + 1,
        "column": names[col],
    }
    return Record(path.stem, dt, _to_si(a, factor, src_units, path), meta)


# --------------------------------------------------------------------------- public
def detect_format(path: str | Path, head: str = "") -> str:
    """Guess the format from the extension, then from the first line of ``head``."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext in _EXT:
        return _EXT[ext]
    first = head.lstrip().splitlines()[0].upper() if head.strip() else ""
    if first.startswith("PEER"):
        return "at2"
    if first.startswith("CORRECTED ACCELEROGRAM"):
        return "v2"
    if first.startswith("UNCORRECTED ACCELEROGRAM"):
        return "v1"
    return "text"


def read(
    path: str | Path,
    *,
    fmt: str | None = None,
    dt: float | None = None,
    units: str | None = None,
    channel: int | None = None,
    name: str | None = None,
) -> Record:
    """Read an accelerogram file into a :class:`Record` (acceleration in m/s^2).

    Parameters
    ----------
    path
        The file.
    fmt
        One of ``"at2"``, ``"v2"``, ``"v1"``, ``"text"``, ``"csv"``; guessed from the extension
        (``.AT2``, ``.V2``, ``.V1``/``.RAW``, ``.csv``) or the first line when ``None``.
    dt
        Time step [s]. Required for one-column text and CSV without ``time_s``; elsewhere it
        must agree with the file (``ValueError`` otherwise).
    units
        Source units (``"g"``, ``"m/s^2"``, ``"cm/s^2"``, ...). Required for text files; for the
        other formats the file states them.
    channel
        1-based channel of a multi-channel V1/V2 file, or acceleration column of a CSV. Default:
        the first horizontal channel (a channel whose component is not ``UP``/``Down``/...).
    name
        Record name; default the file stem (``stem.chN`` for V1/V2).

    Returns
    -------
    Record
        ``meta`` holds ``format``, ``file``, ``npts``, ``channel``, ``source_units`` and, where
        the header has them, ``event``, ``station``, ``component``.

    Raises
    ------
    ValueError
        Empty file, wrong value count, non-numeric or non-finite value, non-positive or
        non-uniform dt, unknown units; the message names the file, line and value.
    """
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{p}: is a directory; expected an accelerogram file")
    raw = p.read_bytes()
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise ValueError(f"{p}: byte {nul} is a NUL: a binary (or UTF-16) file, not a text accelerogram")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    if not text.strip():
        raise ValueError(f"{p}: no data (empty file)")
    kind = (fmt or detect_format(p, text[:200])).lower()
    if kind not in FORMATS:
        raise ValueError(f"{p}: unknown format {fmt!r}; expected one of {FORMATS}")
    if channel is not None and kind in ("at2", "text") and int(channel) != 1:
        raise ValueError(f"{p}: a {kind} file has a single channel, got channel={channel!r}")
    lines = text.splitlines()
    try:
        if kind == "at2":
            rec = _read_at2(p, lines, dt, units)
        elif kind in ("v1", "v2"):
            if units is not None:
                raise ValueError(f"{p}: a {kind.upper()} file states its units; do not pass units={units!r}")
            rec = _read_csmip(p, lines, kind, dt, channel)
        elif kind == "text":
            rec = _read_text(p, lines, dt, units)
        else:
            rec = _read_csv(p, text, dt, units, channel)
    except ValueError as exc:
        if str(p) in str(exc):
            raise
        # e.g. a value that overflows to inf once converted to m/s^2 (Record's own check)
        raise ValueError(f"{p}: {exc}") from None
    meta = {"file": p.name, **rec.meta}
    meta.setdefault("event", "")
    meta.setdefault("station", "")
    meta.setdefault("component", "")
    return Record(name or rec.name, rec.dt, rec.accel, meta)
