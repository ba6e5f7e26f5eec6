"""Uniaxial test data for rubber fits: CSV (``time_s``, ``stretch``, ``stress_MPa`` or ``stress_kPa``,
nominal stress F/A0) and the MATLAB v5 struct of the bundled VHB 4910 data (``data.xdata`` =
[time s, stretch], ``data.ydata`` = nominal stress kPa)."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).with_name("data")
VHB4910 = DATA_DIR / "vhb4910_data.mat"
_SCALE = {"stress_MPa": 1.0, "stress_kPa": 1e-3, "stress_Pa": 1e-6}


@dataclass(frozen=True)
class Test:
    """One uniaxial test: sample times (s), stretches and nominal stress (MPa)."""

    name: str
    time: np.ndarray
    stretch: np.ndarray
    stress: np.ndarray

    def __post_init__(self) -> None:
        n = np.asarray(self.time).shape
        if np.asarray(self.stretch).shape != n or np.asarray(self.stress).shape != n or len(n) != 1:
            raise ValueError(f"{self.name}: time, stretch and stress must be 1-D arrays of equal length")
        if n[0] < 2:
            raise ValueError(f"{self.name}: expected at least 2 samples, got {n[0]}")
        for key in ("time", "stretch", "stress"):
            a = np.asarray(getattr(self, key), dtype=float)
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise ValueError(f"{self.name}: {key}[{bad[0]}] = {a[bad[0]]!r} is not finite")
        t = np.asarray(self.time)
        bad = np.nonzero(np.diff(t) <= 0)[0]
        if bad.size:
            raise ValueError(f"{self.name}: column time_s not strictly increasing at row {bad[0] + 3} "
                             "(header = row 1)")
        if not np.any(np.asarray(self.stress) != 0):
            raise ValueError(f"{self.name}: stress is zero everywhere")


def _read_csv(path: Path) -> Test:
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text CSV file (byte {exc.start} is not UTF-8 text: a "
                         "binary file, or another encoding)") from None
    except csv.Error as exc:
        raise ValueError(f"{path}: malformed CSV: {exc}") from None
    if not rows:
        raise ValueError(f"{path}: empty file; expected a header (time_s, stretch, stress_MPa) and data rows")
    head = [h.strip() for h in rows[0]]
    for need in ("time_s", "stretch"):
        if need not in head:
            raise ValueError(f"{path}: missing column {need!r} (have {head})")
    scol = [h for h in head if h in _SCALE]
    if len(scol) != 1:
        raise ValueError(f"{path}: expected exactly one stress column of {sorted(_SCALE)} (have {head})")
    cols = {"time_s": head.index("time_s"), "stretch": head.index("stretch"), scol[0]: head.index(scol[0])}
    out = {k: [] for k in cols}
    for i, r in enumerate(rows[1:], start=2):
        for k, j in cols.items():
            try:
                v = float(r[j])
            except (IndexError, ValueError):
                raise ValueError(f"{path}: row {i}, column {k!r}: "
                                 f"{(r[j] if j < len(r) else '<missing>')!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{path}: row {i}, column {k!r}: non-finite value {v}")
            if k == "stretch" and v <= 0:
                raise ValueError(f"{path}: row {i}, column 'stretch': {v} is not a positive stretch")
            out[k].append(v)
    return Test(path.name, np.array(out["time_s"]), np.array(out["stretch"]),
                np.array(out[scol[0]]) * _SCALE[scol[0]])


def _mat_arrays(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(data.xdata, data.ydata) of a MATLAB file; ValueError on anything else."""
    from scipy.io import loadmat

    try:
        d = loadmat(str(path))["data"]
        x = np.asarray(d["xdata"][0][0], dtype=float)
        y = np.asarray(d["ydata"][0][0], dtype=float).ravel()
    except Exception as exc:
        raise ValueError(f"{path}: expected a MATLAB struct 'data' with xdata [time, stretch] and "
                         f"ydata [stress kPa] ({exc})") from None
    return x, y


def _mat_arrays_isolated(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_mat_arrays` in a forked child process.

    ``scipy.io.loadmat`` can crash the interpreter (segmentation fault in its compiled MAT5
    reader) on some corrupted files; found by fuzzing (tests/test_reader_fuzz.py).  A crash in
    the child becomes a ValueError naming the file.  Without ``os.fork`` (Windows) the file is
    read in this process.
    """
    import os
    import pickle

    if not hasattr(os, "fork"):
        return _mat_arrays(path)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: read, send the result or the error, leave without cleanup handlers
        code = 0
        try:
            import faulthandler

            faulthandler.disable()  # a crash here is reported by the parent, not dumped to stderr
            os.close(r)
            try:
                out = ("ok", _mat_arrays(path))
            except ValueError as exc:
                out = ("error", str(exc))
            with os.fdopen(w, "wb") as f:
                f.write(pickle.dumps(out))
        except BaseException:  # noqa: BLE001 - nothing may escape a forked child
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    with os.fdopen(r, "rb") as f:
        data = f.read()
    _, status = os.waitpid(pid, 0)
    if not data:
        how = f"signal {os.WTERMSIG(status)}" if os.WIFSIGNALED(status) else f"exit {os.WEXITSTATUS(status)}"
        raise ValueError(f"{path}: not a readable MATLAB file (the MAT-file reader crashed: {how})")
    kind, value = pickle.loads(data)
    if kind == "error":
        raise ValueError(value)
    return value


def _read_mat(path: Path) -> Test:
    x, y = _mat_arrays_isolated(path)
    if x.ndim != 2 or x.shape[1] != 2 or x.shape[0] != y.size:
        raise ValueError(f"{path}: data.xdata shape {x.shape} and data.ydata size {y.size} do not match")
    for key, a in (("xdata", x), ("ydata", y)):
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            idx = tuple(int(i) for i in bad[0])
            raise ValueError(f"{path}: data.{key}{list(idx)} = {a[idx]!r} is not finite")
    if np.any(x[:, 1] <= 0):
        i = int(np.flatnonzero(x[:, 1] <= 0)[0])
        raise ValueError(f"{path}: data.xdata[{i}, 1] = {x[i, 1]!r} is not a positive stretch")
    return Test(path.name, x[:, 0].copy(), x[:, 1].copy(), y * 1e-3)


def read_test(path: str | Path) -> Test:
    """Read a uniaxial test (.csv or .mat) -> :class:`Test` (stress in MPa, nominal).

    Raises ValueError naming the file, column and row of bad input.
    """
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{p}: is a directory; expected a .csv or .mat test file")
    if not p.is_file():
        raise ValueError(f"{p}: no such file")
    if p.suffix.lower() == ".mat":
        return _read_mat(p)
    return _read_csv(p)


_WRITE_SCALE = {"MPa": 1.0, "kPa": 1e3}
"""Factor from the model's MPa to each stress unit :func:`write_test` can write."""


def write_test(path: str | Path, test: Test, *, unit: str = "MPa") -> None:
    """Write a :class:`Test` as CSV with columns ``time_s, stretch, stress_<unit>`` (nominal stress
    in ``unit``: "MPa" or "kPa", the lab's format for soft elastomers)."""
    if unit not in _WRITE_SCALE:
        raise ValueError(f"unit = {unit!r}: expected one of {', '.join(_WRITE_SCALE)}")
    k = _WRITE_SCALE[unit]
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "stretch", f"stress_{unit}"])
        for a, b, c in zip(test.time, test.stretch, test.stress):
            w.writerow([repr(float(a)), repr(float(b)), repr(float(c) * k)])


def load_vhb4910() -> Test:
    """The bundled VHB 4910 load-unload test (Miles et al. 2015; MIT, see rubber/data/LICENSE_vhb4910.md)."""
    return _read_mat(VHB4910)
