"""Property-based fuzzing of the file readers (issue 16, "readers get property-based fuzzing").

Every reader at the public boundary is fed inputs derived from a valid seed file of its format:
truncated at any byte, bytes flipped / inserted / deleted, a number (or a word: key, string,
column name, unit) replaced by garbage, NaN, inf, nothing or a value of another TOML type, lines
dropped / duplicated / swapped / blanked, binary noise, an empty file, the header alone, non-UTF-8
bytes, UTF-16.  The property: the reader either returns a result whose invariants hold (finite
arrays of consistent lengths, increasing time, positive dt, ...) -- a mutation may well leave a
valid file -- or raises a plain ``ValueError`` whose message names the file and says what is
wrong.  Any other exception (``UnicodeDecodeError``, ``IndexError``, ``KeyError``, ``TypeError``,
``tomllib.TOMLDecodeError``, an error from SciPy without the file name, ...) fails.

The default tier runs ``FAST`` examples per format; ``pytest -m slow`` runs ``SLOW`` per format.
A few hand-made cases pin the exact messages.
"""

from __future__ import annotations

import gzip
import math
import re
import tempfile
import tomllib
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
from _tiers import Tier, run_examples, tiers
from hypothesis import strategies as st

import ground_motions
import rrfrei
import structures
from ground_motions.io import read as read_record
from rrfrei.io import read_test
from rubber.io import read_test as read_rubber
from structures.building.shear_building import load_building
from structures.shake_table import ConsistencyWarning, read_run

FAST = 80
SLOW = 500

SYNTH = Path(rrfrei.__file__).parent / "data" / "isolator_synthetic"
RECORDS = Path(ground_motions.__file__).parent / "records"
BUILDINGS = Path(structures.__file__).parent / "building" / "buildings"


# ------------------------------------------------------------------------------------- seeds
def _lines(path: Path, n: int) -> list[str]:
    with path.open(encoding="utf-8", newline="") as fh:
        return [next(fh) for _ in range(n)]


def _shear_csv() -> bytes:
    """The first 40 samples of the bundled protocol1 test (time_s, disp_mm, force_kN)."""
    return "".join(_lines(SYNTH / "protocol1.csv", 41)).encode()


def _shear_csv_units_row() -> bytes:
    """The same samples with bare column names, a units row and a vertical-load column."""
    rows = [ln.strip().split(",") for ln in _lines(SYNTH / "protocol1.csv", 41)[1:]]
    body = "".join(f"{t},{d},{f},{19.25 + 0.01 * i:.2f}\n" for i, (t, d, f) in enumerate(rows))
    return ("Time,Disp,Force,Vertical\ns,mm,kN,kN\n" + body).encode()


def _geometry_toml() -> bytes:
    return (SYNTH / "geometry.toml").read_bytes()


def _at2() -> bytes:
    """The PEER NGA header of the bundled El Centro record and its first 40 values (NPTS = 40)."""
    head = _lines(RECORDS / "RSN6_IMPVALL.I_I-ELC180.AT2", 12)
    head[3] = head[3].replace("NPTS=   5372", "NPTS=     40")
    return "".join(head).encode()


def _csmip(name: str, data_line: int, old: str, new: str, width: int, first: int = 1) -> bytes:
    """One channel of a CSMIP file (its header from line ``first``, the data line ``data_line``,
    both 1-based) cut to 40 values, then the ``/&`` end line."""
    lines = _lines(RECORDS / name, data_line + math.ceil(40 / 8))
    head = lines[first - 1:]
    k = data_line - first
    assert old in head[k], head[k]
    head[k] = head[k].replace(old, new)
    last = head[-1].rstrip("\r\n")
    eol = head[-1][len(last):]
    head[-1] = last[: width * (40 % 8 or 8)] + eol
    return ("".join(head) + "/&  ----------  End of data for channel  1  ----------" + eol).encode()


def _csmip_two_channels() -> bytes:
    """Channels 1 (180 deg) and 2 (90 deg) of the bundled Avol file, 40 values each."""
    return (_csmip("ce89486SampleInput.v2", 46, " 10100 points", "    40 points", 10)
            + _csmip("ce89486SampleInput.v2", 3884, " 10100 points", "    40 points", 10, first=3839))


def _text_record() -> bytes:
    return "".join(_lines(RECORDS / "tabasFN.txt", 40)).encode()


def _gm_csv() -> bytes:
    t = np.arange(30) * 0.01
    a = 0.1 * np.sin(2 * np.pi * 2.0 * t)
    return ("time_s,accel_g\n" + "".join(f"{x:.2f},{y:.6f}\n" for x, y in zip(t, a))).encode()


def _building() -> bytes:
    return (BUILDINGS / "three_story.toml").read_bytes()


def _rubber_csv() -> bytes:
    t = np.linspace(0.0, 3.0, 31)
    lam = 1.0 + 0.5 * np.sin(np.pi * t / 3.0)
    s = 0.2 * (lam - 1.0 / lam**2)
    rows = "".join(f"{a:.4f},{b:.6f},{c:.6f}\n" for a, b, c in zip(t, lam, s))
    return ("time_s,stretch,stress_MPa\n" + rows).encode()


def _rubber_mat() -> bytes:
    from scipy.io import savemat

    t = np.linspace(0.0, 3.0, 20)
    lam = 1.0 + 0.5 * np.sin(np.pi * t / 3.0)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "seed.mat"
        savemat(p, {"data": {"xdata": np.column_stack([t, lam]), "ydata": 200.0 * (lam - 1.0 / lam**2)}})
        return p.read_bytes()


_RATE = 50.0
_NT = 150


def _run_channels() -> dict[str, np.ndarray]:
    """A consistent two-level run: a_i = d_i'' + a_g exactly (sines), 150 samples at 50 Hz."""
    t = np.arange(_NT) / _RATE
    w = 2 * np.pi * 0.5
    ag = 0.5 * np.sin(w * t)
    d0, d1 = 0.01 * np.sin(w * t), 0.012 * np.sin(w * t)
    return {"t": t, "ag": ag, "d0": d0, "d1": d1,
            "a0": -w * w * d0 + ag, "a1": -w * w * d1 + ag}


def _run_csv() -> bytes:
    c = _run_channels()
    rows = "".join(f"{c['t'][i]:.2f},{c['ag'][i]:.7g},{c['a0'][i]:.7g},{c['d0'][i]:.7g},"
                   f"{c['a1'][i]:.7g},{c['d1'][i]:.7g}\n" for i in range(_NT))
    head = ("time_s,table_accel_mps2,base_accel_abs_mps2,base_disp_rel_m,roof_accel_abs_mps2,"
            "roof_disp_rel_m\n")
    return (head + rows).encode()


def _run_toml() -> bytes:
    return b'name = "fuzz"\n\n[levels]\nnames = ["base", "roof"]\nmasses = [10.0, 8.0]\nmass_unit = "t"\n'


def _column(key: str) -> bytes:
    return "".join(f"{x:.7g}\n" for x in _run_channels()[key]).encode()


def _folder_toml() -> bytes:
    return (b'rate_hz = 50.0\n\n[levels]\nnames = ["base", "roof"]\nweights = [98.1, 78.48]\n'
            b'weight_unit = "kN"\n')


# ------------------------------------------------------------------------------ invariants
def _finite(*arrays) -> None:
    for a in arrays:
        assert np.all(np.isfinite(np.asarray(a, dtype=float)))


def _check_shear(t) -> None:
    n = len(t.disp)
    assert n >= rrfrei.io.MIN_POINTS and t.time.shape == t.force.shape == t.disp.shape == (n,)
    _finite(t.time, t.disp, t.force)
    if t.has_time:
        assert np.all(np.diff(t.time) > 0)
    assert np.ptp(t.disp) > 0
    assert t.vertical_load is None or math.isfinite(t.vertical_load)
    assert all(math.isfinite(v) and v >= 0 for v in t.geometry.values())


def _check_record(r) -> None:
    assert math.isfinite(r.dt) and r.dt > 0
    assert r.accel.ndim == 1 and r.accel.size >= 1 and r.accel.size == r.meta["npts"]
    _finite(r.accel)


def _check_building(b) -> None:
    n = b.n_stories
    assert n >= 1 and len(b.story_stiffness) == len(b.story_heights) == n
    for x in (*b.story_masses, *b.story_stiffness, *b.story_heights, b.base_mass):
        assert math.isfinite(x) and x > 0
    assert 0 <= b.damping_ratio < 1
    assert b.isolator.count >= 1 and math.isfinite(b.isolator.length_scale)
    if b.isolator.params is not None:
        _finite(list(b.isolator.params.values()))


def _check_rubber(t) -> None:
    n = t.time.size
    assert n >= 2 and t.stretch.shape == t.stress.shape == (n,)
    _finite(t.time, t.stretch, t.stress)
    assert np.all(np.diff(t.time) > 0) and np.all(t.stretch > 0)


def _check_run(r) -> None:
    n = r.time.size
    assert n >= 10 and r.table_accel.shape == (n,)
    assert r.accel.shape == r.disp.shape == (n, r.masses.size) and len(r.level_names) == r.masses.size
    _finite(r.time, r.table_accel, r.accel, r.disp, r.masses)
    assert np.all(np.diff(r.time) > 0) and math.isfinite(r.dt) and r.dt > 0 and np.all(r.masses > 0)
    if r.table_disp is not None:
        assert r.table_disp.shape == (n,)
        _finite(r.table_disp)


# ------------------------------------------------------------------------------- formats
@dataclass(frozen=True)
class Format:
    """One fuzz target: ``target`` (the fuzzed file, relative path) among ``files`` written into a
    fresh folder; ``read(folder)`` calls the reader, ``check(result)`` asserts the invariants of a
    success."""

    id: str
    target: str
    files: Callable[[], dict[str, bytes]]
    read: Callable[[Path], object]
    check: Callable[[object], None]


FORMATS = [
    Format("shear-csv", "t.csv", lambda: {"t.csv": _shear_csv(), "geometry.toml": _geometry_toml()},
           lambda d: read_test(d / "t.csv"), _check_shear),
    Format("shear-csv-units-row", "t.csv", lambda: {"t.csv": _shear_csv_units_row()},
           lambda d: read_test(d / "t.csv"), _check_shear),
    Format("shear-geometry-toml", "geometry.toml",
           lambda: {"t.csv": _shear_csv(), "geometry.toml": _geometry_toml()},
           lambda d: read_test(d / "t.csv"), _check_shear),
    Format("at2", "r.AT2", lambda: {"r.AT2": _at2()}, lambda d: read_record(d / "r.AT2"), _check_record),
    Format("v2-cdmg", "r.V2",
           lambda: {"r.V2": _csmip("S_MONICA.V2", 46, " 3000 POINTS", "   40 POINTS", 10)},
           lambda d: read_record(d / "r.V2"), _check_record),
    Format("v2-avol", "r.v2",
           lambda: {"r.v2": _csmip("ce89486SampleInput.v2", 46, " 10100 points", "    40 points", 10)},
           lambda d: read_record(d / "r.v2"), _check_record),
    Format("v2-two-channels", "r.v2", lambda: {"r.v2": _csmip_two_channels()},
           lambda d: read_record(d / "r.v2"), _check_record),
    Format("v1-raw", "r.RAW",
           lambda: {"r.RAW": _csmip("CICCC.RAW", 28, " 35430 Accelerogram", "    40 Accelerogram", 9)},
           lambda d: read_record(d / "r.RAW"), _check_record),
    Format("gm-text", "r.txt", lambda: {"r.txt": _text_record()},
           lambda d: read_record(d / "r.txt", dt=0.02, units="g"), _check_record),
    Format("gm-csv", "r.csv", lambda: {"r.csv": _gm_csv()}, lambda d: read_record(d / "r.csv"),
           _check_record),
    Format("building-toml", "b.toml", lambda: {"b.toml": _building()},
           lambda d: load_building(d / "b.toml"), _check_building),
    Format("rubber-csv", "u.csv", lambda: {"u.csv": _rubber_csv()}, lambda d: read_rubber(d / "u.csv"),
           _check_rubber),
    Format("rubber-mat", "u.mat", lambda: {"u.mat": _rubber_mat()}, lambda d: read_rubber(d / "u.mat"),
           _check_rubber),
    Format("shake-csv", "run.csv", lambda: {"run.csv": _run_csv(), "run.toml": _run_toml()},
           lambda d: read_run(d / "run.csv"), _check_run),
    Format("shake-csv-gz", "run.csv.gz", lambda: {"run.csv.gz": gzip.compress(_run_csv(), mtime=0),
                                                  "run.toml": _run_toml()},
           lambda d: read_run(d / "run.csv.gz"), _check_run),
    Format("shake-folder-gz", "run/u.txt.gz",
           lambda: {"run/" + k + ".txt": _column(c) for k, c in
                    (("a1", "a1"), ("a2", "a0"), ("d1", "d1"), ("d2", "d0"))}
           | {"run/u.txt.gz": gzip.compress(_column("ag"), mtime=0), "run/run.toml": _folder_toml()},
           lambda d: read_run(d / "run"), _check_run),
    Format("shake-csv-toml", "run.toml", lambda: {"run.csv": _run_csv(), "run.toml": _run_toml()},
           lambda d: read_run(d / "run.csv"), _check_run),
    Format("shake-folder-column", "run/u.txt",
           lambda: {"run/" + k + ".txt": _column(c) for k, c in
                    (("a1", "a1"), ("a2", "a0"), ("d1", "d1"), ("d2", "d0"), ("u", "ag"))}
           | {"run/run.toml": _folder_toml()},
           lambda d: read_run(d / "run", check=True), _check_run),
    Format("shake-folder-toml", "run/run.toml",
           lambda: {"run/" + k + ".txt": _column(c) for k, c in
                    (("a1", "a1"), ("a2", "a0"), ("d1", "d1"), ("d2", "d0"), ("u", "ag"))}
           | {"run/run.toml": _folder_toml()},
           lambda d: read_run(d / "run"), _check_run),
]


# ------------------------------------------------------------------------------- mutations
#: What a number may become: garbage, non-finite, empty, and values of other TOML types.
GARBAGE = ["", " ", "nan", "NaN", "-nan", "inf", "-Infinity", "1e999", "-1e400", "abc", "1.2.3", "--1",
           "0x1A", "1,5", "1e", ".", "+", "\x00", "é", "1_000", "\u0663", "true", "[]", "[1, [2]]", "{}",
           '"x"', "'", "1979-05-27", "0", "-1", "1e-300", "1.7e308", "-1.7e308", "12345678901234567890"]
_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?")
_WORD = re.compile(rb'"[^"\n]*"|[A-Za-z_]+')  # a TOML string, a key, a column name, a unit


def _split_lines(data: bytes) -> list[bytes]:
    return data.splitlines(keepends=True)


@st.composite
def _one_mutation(draw, data: bytes) -> bytes:
    n = len(data)
    op = draw(st.sampled_from([
        "truncate", "flip", "insert", "delete", "number", "number", "number", "drop_line",
        "duplicate_line", "swap_lines", "noise", "empty", "header", "non_utf8", "utf16", "blank_line",
        "word",
    ]))
    if op == "truncate":
        return data[: draw(st.integers(0, n))]
    if op == "flip" and n:
        out = bytearray(data)
        for _ in range(draw(st.integers(1, 4))):
            out[draw(st.integers(0, n - 1))] = draw(st.integers(0, 255))
        return bytes(out)
    if op == "insert":
        i = draw(st.integers(0, n))
        return data[:i] + draw(st.binary(min_size=1, max_size=8)) + data[i:]
    if op == "delete" and n:
        i = draw(st.integers(0, n - 1))
        return data[:i] + data[i + draw(st.integers(1, 16)):]
    if op in ("number", "word"):
        hits = list((_NUMBER if op == "number" else _WORD).finditer(data))
        if hits:
            m = draw(st.sampled_from(hits))
            return data[: m.start()] + draw(st.sampled_from(GARBAGE)).encode() + data[m.end():]
        return data
    lines = _split_lines(data)
    if op in ("drop_line", "duplicate_line", "swap_lines", "header", "blank_line") and lines:
        i = draw(st.integers(0, len(lines) - 1))
        if op == "drop_line":
            return b"".join(lines[:i] + lines[i + 1:])
        if op == "duplicate_line":
            return b"".join(lines[: i + 1] + lines[i:])
        if op == "blank_line":
            return b"".join(lines[:i] + [b"\n"] + lines[i:])
        if op == "header":
            return b"".join(lines[: draw(st.integers(1, min(len(lines), 40)))])
        j = draw(st.integers(0, len(lines) - 1))
        lines[i], lines[j] = lines[j], lines[i]
        return b"".join(lines)
    if op == "noise":
        return draw(st.binary(min_size=1, max_size=300))
    if op == "empty":
        return b""
    if op == "non_utf8":
        i = draw(st.integers(0, n))
        bad = draw(st.sampled_from([b"\xff", b"\xe9", b"\x80\x81", b"\xc3", b"\xfe\xff"]))
        return data[:i] + bad + data[i:]
    if op == "utf16":
        return data.decode("utf-8", "replace").encode("utf-16")
    return data


@st.composite
def mutated(draw, seed: bytes) -> bytes:
    """``seed`` after one to three random mutations."""
    data = seed
    for _ in range(draw(st.integers(1, 3))):
        data = draw(_one_mutation(data))
    return data


# --------------------------------------------------------------------------------- property
def _write(folder: Path, files: dict[str, bytes]) -> None:
    for rel, blob in files.items():
        p = folder / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(blob)


def read_or_explain(fmt: Format, folder: Path):
    """Run the reader on ``folder``; a ValueError must be plain, name the fuzzed file and say more.

    Returns the result (its invariants checked) or the ValueError.
    """
    name = Path(fmt.target).name
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConsistencyWarning)
        # 1.7e308 is a legal value; the consistency check's squares of it overflow (reported as failed)
        warnings.filterwarnings("ignore", "overflow encountered|invalid value encountered", RuntimeWarning)
        try:
            result = fmt.read(folder)
        except ValueError as exc:
            msg = str(exc)
            assert not isinstance(exc, (UnicodeError, tomllib.TOMLDecodeError)), f"bare {type(exc).__name__}"
            assert name in msg, f"the message does not name {name!r}: {msg}"
            rest = msg.replace(str(folder), "").replace(name, "")
            assert len(re.findall(r"[a-zA-Z]{3,}", rest)) >= 2, f"the message says too little: {msg}"
            return exc
    fmt.check(result)
    return result


_SEEDS: dict[str, dict[str, bytes]] = {}


def _seed(fmt: Format) -> dict[str, bytes]:
    if fmt.id not in _SEEDS:
        _SEEDS[fmt.id] = fmt.files()
    return _SEEDS[fmt.id]


@pytest.mark.parametrize("fmt", FORMATS, ids=[f.id for f in FORMATS])
def test_every_seed_file_is_valid(tmp_path, fmt):
    _write(tmp_path, _seed(fmt))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConsistencyWarning)
        fmt.check(fmt.read(tmp_path))


def _fuzz(fmt: Format, blob: bytes, root: Path) -> None:
    folder = Path(tempfile.mkdtemp(dir=root))
    files = dict(_seed(fmt))
    files[fmt.target] = blob
    _write(folder, files)
    read_or_explain(fmt, folder)


@pytest.mark.parametrize("tier", tiers(Tier(FAST), Tier(SLOW)))
@pytest.mark.parametrize("fmt", FORMATS, ids=[f.id for f in FORMATS])
def test_fuzzed_files_are_read_or_refused_with_a_value_error_naming_the_file(tmp_path, fmt, tier):
    run_examples(tier, lambda blob: _fuzz(fmt, blob, tmp_path), blob=mutated(_seed(fmt)[fmt.target]))


# ------------------------------------------------------------------------ hand-made cases
def _by_id(fid: str) -> Format:
    return next(f for f in FORMATS if f.id == fid)


def _replace_line(data: bytes, index: int, new: bytes) -> bytes:
    lines = _split_lines(data)
    eol = lines[index][len(lines[index].rstrip(b"\r\n")):]
    lines[index] = new + eol
    return b"".join(lines)


def _shear_row(i: int, force: str) -> bytes:
    t, d, _ = _split_lines(_shear_csv())[i].decode().strip().split(",")
    return f"{t},{d},{force}".encode()


BINARY = bytes(range(256)) * 2

#: (format, how the target file is made from its seed, the expected message after "<file>")
CASES = [
    ("shear-csv", lambda s: b"", r"t\.csv: the file is empty"),
    ("shear-csv", lambda s: _split_lines(s)[0], r"t\.csv: 0 data rows; at least 10 are needed"),
    ("shear-csv", lambda s: _replace_line(s, 4, _shear_row(4, "nan")),
     r"t\.csv, row 5, column 'force_kN': 'nan' is not a finite number"),
    ("shear-csv", lambda s: BINARY, r"t\.csv: not a text CSV file \(byte 128 is not UTF-8 text"),
    ("shear-csv", lambda s: _replace_line(s, 7, b"0.35,1.2"),
     r"t\.csv, row 8, column 'force_kN': missing \(the row has 2 fields, the header 3\)"),
    ("shear-csv", lambda s: s[: s.rindex(b",") - 3],
     r"t\.csv, row 41, column 'force_kN': missing"),
    ("shear-geometry-toml", lambda s: s.replace(b"vertical_load_kN = 19.25", b"vertical_load_kN = nan"),
     r"geometry\.toml: vertical_load_kN = nan must be a finite number \[kN\]"),
    ("shear-geometry-toml", lambda s: s.replace(b"tr = 0.002", b"tr = -0.002"),
     r"geometry in .*geometry\.toml: tr = -0\.002 must be finite and >= 0"),
    ("shear-geometry-toml", lambda s: BINARY, r"geometry\.toml: not a UTF-8 TOML text file"),
    ("shear-geometry-toml", lambda s: s[: s.index(b"SYNTHETIC RR") + 5], r"geometry\.toml: not valid TOML"),
    ("at2", lambda s: b"", r"r\.AT2: no data \(empty file\)"),
    ("at2", lambda s: b"".join(_split_lines(s)[:4]),
     r"r\.AT2: an AT2 file needs 4 header lines and data, found 4 lines"),
    ("at2", lambda s: s.replace(b".9991426E-03", b"nan", 1), r"r\.AT2, line 5: value 'nan' is not finite"),
    ("at2", lambda s: BINARY, r"r\.AT2: byte 0 is a NUL: a binary \(or UTF-16\) file"),
    ("at2", lambda s: b"".join(_split_lines(s)[:-1]),
     r"r\.AT2, line 4: header declares NPTS = 40 values but 35 values were read"),
    ("at2", lambda s: s.rstrip()[:-3], r"r\.AT2, line 12: value '\.9949472E' is not a number"),
    ("at2", lambda s: s.replace(b".9984852E-03", b".99848E", 1), r"r\.AT2, line 5: value '\.99848E' is not a "
     "number"),
    ("at2", lambda s: s.replace(b".9984852E-03", b"1.7e308", 1),
     r"r\.AT2: value 1\.7e\+308 g \(sample 0\) overflows when converted to m/s\^2"),
    ("v2-cdmg", lambda s: s.replace(b"     2.321", b"       nan", 1),
     r"r\.V2, line 47: value 'nan' is not finite"),
    ("v2-cdmg", lambda s: b"".join(_split_lines(s)[:46]),
     r"r\.V2, line 46: header declares NPTS = 40 accel values but 0 values were read"),
    ("v2-avol", lambda s: s.replace(b"(8f10.5)", b"(8f0.5)"),
     r"r\.v2, line 46: field width 0 in the format '\(8f0\.5\)' is invalid"),
    ("v2-two-channels", lambda s: s.replace(b"Chan  1: 180 Deg", b"Chan  1: Up     ")
     .replace(b"Chan  2:  90 Deg", b"Chan  2: Up     "),
     r"r\.v2: no horizontal channel found; pass channel=1\.\.2"),
    ("gm-text", lambda s: b"", r"r\.txt: no data \(empty file\)"),
    ("gm-csv", lambda s: _split_lines(s)[0], r"r\.csv: header only, no data rows"),
    ("gm-csv", lambda s: _replace_line(s, 3, b"0.02,inf"), r"r\.csv, line 4: value 'inf' is not finite"),
    ("building-toml", lambda s: s.replace(b"[40.0, 40.0, 35.0]", b"[40.0, nan, 35.0]"),
     r"b\.toml': story_masses\[1\] = nan t is invalid: expected a finite number > 0"),
    ("building-toml", lambda s: s.replace(b'law = "plasticity"', b'law = "nope"'), r"b\.toml': .*nope"),
    ("building-toml", lambda s: s[: s.index(b"[isolator]")] + b"isolator = 3\n",
     r"b\.toml': isolator must be a table"),
    ("building-toml", lambda s: s.replace(b"k_init = 260.0", b"k_init = {}"),
     r"b\.toml': isolator.params.k_init = \{\} is not a number"),
    ("building-toml", lambda s: BINARY, r"b\.toml' is not UTF-8 TOML text \(byte 128"),
    ("rubber-csv", lambda s: b"", r"u\.csv: empty file; expected a header"),
    ("rubber-csv", lambda s: _split_lines(s)[0], r"u\.csv: expected at least 2 samples, got 0"),
    ("rubber-csv", lambda s: s.replace(b"0.2000,", b"0.2000,nan,", 1),
     r"u\.csv: row 4, column 'stretch': non-finite value nan"),
    ("rubber-csv", lambda s: BINARY, r"u\.csv: not a text CSV file"),
    ("rubber-mat", lambda s: s[: len(s) // 2], r"u\.mat: expected a MATLAB struct 'data'"),
    ("shake-csv", lambda s: s.replace(b"0.04,0.06266662,", b"0.04,nan,", 1),
     r"run\.csv: column 'table_accel_mps2', row 4: value nan is not a finite number"),
    ("shake-csv", lambda s: b"".join(_split_lines(s)[:13]),
     r"run\.csv: 12 samples are too few for the consistency check"),
    ("shake-csv-toml", lambda s: s.replace(b'names = ["base", "roof"]', b'names = "base"'),
     r"run\.toml: \[levels\] names = 'base' is invalid: expected a non-empty list of strings"),
    ("shake-csv-toml", lambda s: s.replace(b'["base", "roof"]', b'["base", "base"]'),
     r"run\.toml: \[levels\] names = \['base', 'base'\] repeats a label"),
    ("shake-csv-toml", lambda s: s.replace(b'"base"', b'"slab"'),
     r"run\.csv: no column slab_accel_abs_<unit> for level 'slab' of \[levels\] names in .*run\.toml"),
    ("shake-folder-toml", lambda s: s.replace(b'["base", "roof"]', b'["roof"]'),
     r"run\.toml: \[levels\] names has 1 labels but the folder has 2 levels"),
    ("shake-folder-toml", lambda s: s.replace(b"rate_hz = 50.0", b"rate_hz = 5.0"),
     r"run \(rate_hz = 5\.0 Hz from .*run\.toml\): cutoff_hz = 5\.0 is invalid: "
     r"expected 0 < cutoff < 2\.5 Hz"),
    ("shake-folder-column", lambda s: b"", r"u\.txt: no values \(empty file\)"),
    ("shake-folder-column", lambda s: _replace_line(s, 2, b"0.1 0.2x"),
     r"u\.txt, line 3: '0\.2x' is not a number"),
    ("shake-folder-toml", lambda s: s.replace(b"rate_hz = 50.0", b'rate_hz = "fast"'),
     r"run\.toml: rate_hz = 'fast' is invalid: expected a number \[Hz\]"),
]


@pytest.mark.parametrize(("fid", "make", "expected"), CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_hand_made_bad_files_name_the_file_and_the_problem(tmp_path, fid, make, expected):
    fmt = _by_id(fid)
    files = dict(_seed(fmt))
    files[fmt.target] = make(files[fmt.target])
    _write(tmp_path, files)
    with pytest.raises(ValueError, match=expected) as exc:
        fmt.read(tmp_path)
    assert type(exc.value) is ValueError


DIRECTORY_READERS = [
    ("shear-csv", read_test, r"t\.csv: is a directory; expected a CSV file"),
    ("at2", read_record, r"r\.AT2: is a directory; expected an accelerogram file"),
    ("rubber-csv", read_rubber, r"u\.csv: is a directory; expected a \.csv or \.mat test file"),
    ("building-toml", load_building, r"b\.toml' is a directory; expected a building TOML file"),
]


@pytest.mark.parametrize(("fid", "reader", "expected"), DIRECTORY_READERS,
                         ids=[c[0] for c in DIRECTORY_READERS])
def test_a_directory_instead_of_a_file_is_a_value_error_naming_it(tmp_path, fid, reader, expected):
    target = tmp_path / Path(_by_id(fid).target).name
    target.mkdir()
    with pytest.raises(ValueError, match=expected):
        reader(target)


def test_a_directory_instead_of_a_sidecar_is_a_value_error_naming_it(tmp_path):
    _write(tmp_path, {"t.csv": _shear_csv()})
    (tmp_path / "geometry.toml").mkdir()
    with pytest.raises(ValueError, match=r"geometry\.toml: is a directory; expected a TOML file"):
        read_test(tmp_path / "t.csv")


def test_the_property_refuses_errors_that_do_not_name_the_file_or_are_not_value_errors(tmp_path):
    def raising(exc):
        def read(folder):
            raise exc
        return replace(_by_id("shear-csv"), read=read)

    assert isinstance(read_or_explain(raising(ValueError(f"{tmp_path}/t.csv: row 3 is bad")), tmp_path),
                      ValueError)
    with pytest.raises(AssertionError, match="does not name 't.csv'"):
        read_or_explain(raising(ValueError("could not convert string to float: 'x'")), tmp_path)
    with pytest.raises(AssertionError, match="says too little"):
        read_or_explain(raising(ValueError(f"{tmp_path}/t.csv")), tmp_path)
    with pytest.raises(AssertionError, match="bare UnicodeDecodeError"):
        read_or_explain(raising(UnicodeDecodeError("utf-8", b"t.csv \xff", 6, 7, "invalid start byte")),
                        tmp_path)
    with pytest.raises(KeyError):
        read_or_explain(raising(KeyError("t.csv")), tmp_path)


def test_a_mat_file_that_crashes_the_matlab_reader_is_a_value_error_naming_the_file(tmp_path, monkeypatch):
    """scipy.io.loadmat segfaulted on a fuzzed .mat file (slow tier): rubber reads MAT files in a
    forked child, so a crash there is a ValueError naming the file, not the end of the process."""
    import os
    import signal

    import rubber.io as rio

    path = tmp_path / "crash.mat"
    bundled = Path(__file__).resolve().parents[1] / "rubber" / "data" / "vhb4910_data.mat"
    path.write_bytes(bundled.read_bytes())

    def segfault(p):
        os.kill(os.getpid(), signal.SIGSEGV)

    monkeypatch.setattr(rio, "_mat_arrays", segfault)
    with pytest.raises(ValueError, match=r"crash\.mat: not a readable MATLAB file \(the MAT-file reader "
                                         r"crashed: signal 11\)"):
        rio.read_test(path)
