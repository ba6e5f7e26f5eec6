"""The ``Record`` model: one uniformly sampled ground-acceleration history in SI units.

Every reader and every bundled record returns a ``Record``; structures and propagation code use
only ``Record.dt`` [s] and ``Record.accel`` [m/s^2].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

#: Standard gravity [m/s^2] (CGPM 1901), used for every conversion from g.
G = 9.80665


class ReadOnlyArrays:
    """Mixin of the package's frozen result dataclasses (spectra, RotD spectra, scaled suites):
    the fields named in ``ARRAYS`` are stored as read-only float64 copies (:meth:`_freeze`, called
    from ``__post_init__``), and an instance pickles through its constructor, so an unpickled
    one (e.g. in a Dask worker) is read-only too."""

    ARRAYS: tuple[str, ...] = ()

    def _freeze(self) -> None:
        for f in self.ARRAYS:
            a = np.array(getattr(self, f), dtype=np.float64)
            a.setflags(write=False)
            object.__setattr__(self, f, a)

    def __reduce__(self):
        return (type(self), tuple(getattr(self, f.name) for f in fields(self)))


@dataclass(frozen=True, eq=False)
class Record:
    """A ground-acceleration history sampled at a constant step.

    Parameters
    ----------
    name
        Short label (a bundled record's name, or the file stem).
    dt
        Time step [s], finite and > 0.
    accel
        Ground acceleration [m/s^2]; stored as a read-only 1-D float64 copy. Sample ``i`` is at
        ``t = i * dt``.
    meta
        Free-form metadata from the source (``event``, ``station``, ``component``,
        ``source_units``, ``file``, ``npts``, ``channel``, ...).

    Notes
    -----
    Records compare by identity (``eq=False``): two arrays are not meaningfully "equal" as a
    boolean, so compare ``accel`` explicitly when needed.
    """

    name: str
    dt: float
    accel: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        dt = float(self.dt)
        if not math.isfinite(dt) or dt <= 0.0:
            raise ValueError(f"Record {self.name!r}: dt must be a finite number > 0 s, got {self.dt!r}")
        a = np.array(self.accel, dtype=np.float64, copy=True)
        if a.ndim != 1 or a.size == 0:
            raise ValueError(
                f"Record {self.name!r}: accel must be a non-empty 1-D array, got shape {a.shape}"
            )
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"Record {self.name!r}: accel[{i}] = {float(a[i])!r} is not finite")
        a.setflags(write=False)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "accel", a)
        object.__setattr__(self, "meta", dict(self.meta))

    def __reduce__(self):
        # through the constructor, so an unpickled record (e.g. in a Dask worker) is read-only too
        return (Record, (self.name, self.dt, self.accel, self.meta))

    # ------------------------------------------------------------------ derived quantities
    @property
    def npts(self) -> int:
        """Number of samples."""
        return int(self.accel.size)

    @property
    def time(self) -> np.ndarray:
        """Sample times ``i * dt`` [s]."""
        return np.arange(self.accel.size) * self.dt

    @property
    def duration(self) -> float:
        """Time of the last sample, ``(npts - 1) * dt`` [s]."""
        return (self.accel.size - 1) * self.dt

    @property
    def pga(self) -> float:
        """Peak ground acceleration ``max |a|`` [m/s^2]."""
        return float(np.max(np.abs(self.accel)))

    # ------------------------------------------------------------------ transformed copies
    def _replace(self, *, accel: np.ndarray, dt: float | None = None, **meta: Any) -> Record:
        return Record(self.name, self.dt if dt is None else dt, accel, {**self.meta, **meta})

    def scaled(self, factor: float) -> Record:
        """A copy with ``accel * factor`` (``meta['scale_factor']`` accumulates the product)."""
        f = float(factor)
        if not math.isfinite(f):
            raise ValueError(f"Record {self.name!r}: scale factor must be finite, got {factor!r}")
        return self._replace(accel=self.accel * f, scale_factor=self.meta.get("scale_factor", 1.0) * f)

    def with_leading_zero(self) -> Record:
        """A copy starting from rest: prepends ``a = 0`` when ``accel[0] != 0`` (else returns self).

        OpenSees' ``Path -values`` load starts with a zero ground acceleration at t = 0 and the
        time-history code requires ``ag[0] = 0``; prepending one sample shifts the record by
        ``dt`` but changes nothing else.
        """
        if self.accel[0] == 0.0:
            return self
        return self._replace(accel=np.concatenate(([0.0], self.accel)), leading_zero=True)

    def resampled(self, dt: float) -> Record:
        """A copy resampled at step ``dt`` [s] by linear interpolation over ``[0, duration]``.

        Linear interpolation is exact for the piecewise-linear signal the spectra and the
        time-history integrators assume between samples, so refining (``dt`` dividing the
        original step) does not change their input.
        """
        new = float(dt)
        if not math.isfinite(new) or new <= 0.0:
            raise ValueError(f"Record {self.name!r}: resampling dt must be a finite number > 0 s, got {dt!r}")
        n = int(math.floor(self.duration / new * (1.0 + 1e-12))) + 1
        t = np.arange(n) * new
        return self._replace(accel=np.interp(t, self.time, self.accel), dt=new, resampled_from_dt=self.dt)

    def __repr__(self) -> str:
        return (
            f"Record(name={self.name!r}, dt={self.dt:g} s, npts={self.npts}, "
            f"duration={self.duration:g} s, pga={self.pga / G:.3f} g)"
        )
