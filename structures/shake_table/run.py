"""One shake-table run of a building on isolators: the channels at a constant sampling step,
validated on construction, and what follows from them alone (isolator force, story shears, drifts,
resampling, windows, the CSV layout)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ground_motions import Record
from structures.shake_table.consistency import ConsistencyReport
from structures.shake_table.filters import lowpass

__all__ = ["ShakeTableRun"]


@dataclass(frozen=True, eq=False)
class ShakeTableRun:
    """One shake-table run of a building on isolators (arrays read-only).

    Attributes
    ----------
    name : label (``"ICA50"``).
    time : (n,) time [s], constant step.
    table_accel : (n,) table acceleration [m/s^2].
    accel : (n, L) absolute level accelerations [m/s^2], bottom-up (column 0 = base slab above
        the isolators, last = roof).
    disp : (n, L) level displacements relative to the table [m], same order; ``disp[:, 0]`` is
        the isolator displacement.
    masses : (L,) level masses [t], same order.
    level_names : (L,) labels, same order.
    table_disp : (n,) table displacement [m] or None.
    source : file or folder read ("" when built in memory).
    meta : anything else (rate, decimation, units read).
    consistency : :class:`ConsistencyReport` from reading, or None.
    """

    name: str
    time: np.ndarray
    table_accel: np.ndarray
    accel: np.ndarray
    disp: np.ndarray
    masses: np.ndarray
    level_names: tuple[str, ...]
    table_disp: np.ndarray | None = None
    source: str = ""
    meta: dict = field(default_factory=dict)
    consistency: ConsistencyReport | None = None

    def __post_init__(self) -> None:
        where = f"run {self.name!r}" + (f" ({self.source})" if self.source else "")

        def arr(key, value, ndim):
            try:
                a = np.array(value, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"{where}: {key} must be numeric, got {type(value).__name__}") from None
            if a.ndim != ndim:
                raise ValueError(f"{where}: {key} must be {ndim}-D, got shape {a.shape}")
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                idx = tuple(int(i) for i in bad[0])
                raise ValueError(f"{where}: {key}{list(idx)} = {a[idx]!r} is not finite")
            a.setflags(write=False)
            object.__setattr__(self, key, a)
            return a

        t = arr("time", self.time, 1)
        n = t.size
        if n < 10:
            raise ValueError(f"{where}: {n} samples; at least 10 are needed")
        dt = np.diff(t)
        if not np.all(dt > 0):
            i = int(np.flatnonzero(dt <= 0)[0])
            raise ValueError(f"{where}: time must increase; sample {i + 1} is {t[i + 1]} s after {t[i]} s")
        h = (t[-1] - t[0]) / (n - 1)
        j = int(np.argmax(np.abs(dt - h)))
        if abs(dt[j] - h) > 1e-6 * h + 1e-9:
            raise ValueError(f"{where}: the time step must be constant (mean {h:g} s), but sample {j + 1} "
                             f"follows after {dt[j]:g} s")
        ag = arr("table_accel", self.table_accel, 1)
        a = arr("accel", self.accel, 2)
        d = arr("disp", self.disp, 2)
        m = arr("masses", self.masses, 1)
        if ag.size != n or a.shape[0] != n or d.shape[0] != n:
            raise ValueError(f"{where}: time, table_accel, accel and disp must have the same number of "
                             f"samples; got {n}, {ag.size}, {a.shape[0]}, {d.shape[0]}")
        nl = m.size
        if nl < 1 or a.shape[1] != nl or d.shape[1] != nl:
            raise ValueError(f"{where}: accel {a.shape}, disp {d.shape} and masses ({nl},) must agree on "
                             "the number of levels")
        for i, x in enumerate(m):
            if not x > 0:
                raise ValueError(f"{where}: masses[{i}] = {x:g} t is invalid: expected > 0")
        names = tuple(str(s) for s in self.level_names)
        if len(names) != nl or len(set(names)) != nl:
            raise ValueError(f"{where}: level_names {names!r} must be {nl} distinct labels (bottom-up)")
        object.__setattr__(self, "level_names", names)
        if self.table_disp is not None:
            td = arr("table_disp", self.table_disp, 1)
            if td.size != n:
                raise ValueError(f"{where}: table_disp has {td.size} samples, expected {n}")

    # ---- basic quantities
    @property
    def n_levels(self) -> int:
        return int(self.masses.size)

    @property
    def dt(self) -> float:
        """Sampling step [s]."""
        return float((self.time[-1] - self.time[0]) / (self.time.size - 1))

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.dt

    @property
    def isolator_disp(self) -> np.ndarray:
        """(n,) isolator displacement [m] (base slab relative to the table)."""
        return self.disp[:, 0]

    @property
    def isolator_force(self) -> np.ndarray:
        """(n,) force of the isolation system on the building [kN]: F = -sum_i m_i a_i."""
        return -(self.accel @ self.masses)

    def story_shear(self) -> np.ndarray:
        """(n, L-1) shear in each story [kN], story j between levels j-1 and j (j = 1..L-1):
        V_j = -sum_{i >= j} m_i a_i (the inertia of the levels above, with a minus)."""
        inertia = self.accel * self.masses
        return -np.cumsum(inertia[:, ::-1], axis=1)[:, ::-1][:, 1:]

    def drift(self) -> np.ndarray:
        """(n, L-1) story drifts d_j - d_{j-1} [m]."""
        return np.diff(self.disp, axis=1)

    def record(self):
        """The table acceleration as a ``ground_motions.Record`` (to drive a model)."""
        return Record(self.name, self.dt, np.asarray(self.table_accel), meta={"source": self.source})

    # ---- transformations
    def decimate(self, rate_hz: float) -> ShakeTableRun:
        """The run resampled to ``rate_hz`` (an integer divisor of the current rate).

        Anti-alias first: zero-phase 8th-order Butterworth low-pass at 0.4 x the new rate (80 % of
        the new Nyquist frequency) on every channel, then every q-th sample.  Zero phase keeps
        the channels' mutual relations (a_i = d_i'' + a_g) intact.
        """
        q_float = self.rate_hz / float(rate_hz)
        q = int(round(q_float))
        if q < 1 or abs(q - q_float) > 1e-6 * q_float:
            raise ValueError(f"rate_hz = {rate_hz!r} is invalid for run {self.name!r}: expected the run's "
                             f"rate {self.rate_hz:g} Hz divided by an integer")
        if q == 1:
            return self
        cut = 0.4 * rate_hz

        def dec(x):
            return np.ascontiguousarray(lowpass(np.asarray(x), cut, self.rate_hz, order=8)[::q])

        meta = dict(self.meta, decimated_from_hz=self.rate_hz, anti_alias_hz=cut)
        return replace(self, time=self.time[::q].copy(), table_accel=dec(self.table_accel),
                       accel=dec(self.accel), disp=dec(self.disp),
                       table_disp=None if self.table_disp is None else dec(self.table_disp),
                       meta=meta, consistency=None)

    def window(self, start_s: float, end_s: float) -> ShakeTableRun:
        """The samples with start_s <= t <= end_s (time kept as is)."""
        keep = (self.time >= start_s) & (self.time <= end_s)
        idx = np.flatnonzero(keep)
        if idx.size < 10:
            raise ValueError(f"window [{start_s}, {end_s}] s of run {self.name!r} holds {idx.size} samples; "
                             "at least 10 are needed")
        s = slice(idx[0], idx[-1] + 1)
        return replace(self, time=self.time[s], table_accel=self.table_accel[s], accel=self.accel[s],
                       disp=self.disp[s], table_disp=None if self.table_disp is None else self.table_disp[s],
                       consistency=None)

    def to_frame(self) -> pd.DataFrame:
        """The CSV layout: ``time_s``, ``table_accel_mps2``, (``table_disp_m``,) then per level
        ``<LEVEL>_accel_abs_mps2`` and ``<LEVEL>_disp_rel_m``."""
        cols: dict[str, np.ndarray] = {"time_s": self.time, "table_accel_mps2": self.table_accel}
        if self.table_disp is not None:
            cols["table_disp_m"] = self.table_disp
        for i, name in enumerate(self.level_names):
            cols[f"{name}_accel_abs_mps2"] = self.accel[:, i]
            cols[f"{name}_disp_rel_m"] = self.disp[:, i]
        return pd.DataFrame(cols)
