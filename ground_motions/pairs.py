"""Two horizontal components recorded together: the :class:`RecordPair` model and its readers.

An isolated building is analysed for both horizontal components at once (ASCE 7-22 Section
17.3.2 calls for *pairs* of horizontal components; Section 17.6.3.4 applies them
simultaneously), so the two components must share one clock: the same time step and the same
start.  A :class:`RecordPair` holds two :class:`~ground_motions.record.Record` s of equal
``dt``; where the recorded lengths differ (the Ridgecrest CCC channels hold 35430 and 35402
samples) the shorter one is **padded with zeros at its end** (every recorded sample of both is
kept; the pad is ground at rest after the record, and ``npts_recorded`` keeps the recorded
lengths so :meth:`RecordPair.trimmed` can cut back to the shorter one instead).

Orientation
-----------
``azimuths`` are the components' directions in degrees clockwise from north, parsed from the
component names where the file gives them (``180``, ``90 Deg``, ``360``, ``N``, ``W``, ...) or
``None``.  Two known azimuths must be orthogonal (they differ by 90 deg, within 0.5 deg).  A
rotation by ``theta`` turns both axes from component 1 towards component 2::

    a1' =  a1 cos(theta) + a2 sin(theta)
    a2' = -a1 sin(theta) + a2 cos(theta)

so ``a1'`` is the ground acceleration along the azimuth ``az1 + s theta`` with ``s = +1`` when
component 2 points 90 deg clockwise of component 1 and ``s = -1`` when it points 90 deg
counter-clockwise (both occur in the bundled files).  This is the combination of Boore (2010),
BSSA 100(4), 1830-1835, Eq. (1), applied to the accelerations (the SDOF response is linear in
the input, so rotating the record and rotating the response agree; :mod:`ground_motions.rotd`).

Readers
-------
:func:`read_pair` reads two files (two AT2 files of one station, or any format
:func:`ground_motions.read` reads) or the two horizontal channels of one multi-channel V1/V2
file; ``ground_motions.load_pair`` (in :mod:`ground_motions.catalogue`) loads the three
bundled records that carry both components.  Every problem is a ``ValueError`` naming the
file(s): different ``dt``, a vertical component, the same file twice, one file with a single
horizontal channel, components of different stations, components that are not orthogonal.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .io import _VERTICAL
from .io import read as _read
from .record import G, Record

#: Tolerance [deg] on the 90 deg between two components' azimuths.
ORTHOGONAL_TOL_DEG = 0.5

_LETTER_AZIMUTH = {
    "N": 0.0, "NS": 0.0, "N-S": 0.0, "NORTH": 0.0, "HNN": 0.0, "HHN": 0.0, "BHN": 0.0,
    "E": 90.0, "EW": 90.0, "E-W": 90.0, "EAST": 90.0, "HNE": 90.0, "HHE": 90.0, "BHE": 90.0,
    "S": 180.0, "SOUTH": 180.0,
    "W": 270.0, "WEST": 270.0,
}
_TRAILING_DEGREES = re.compile(r"(?<![\d.])(\d{1,3}(?:\.\d+)?)\s*(?:DEG(?:REES)?)?$")
_VERTICAL_SUFFIX = ("UP", "DWN", "DOWN", "VER", "VERT", "HNZ", "HHZ", "BHZ")


def component_azimuth(component: str) -> float | None:
    """Azimuth [deg clockwise from north, in [0, 360)] named by a component label, or ``None``.

    ``"180"``, ``"90 Deg"``, ``"360"`` (-> 0), ``"ELC270"``, ``"N"``, ``"E-W"``, ``"HNE"`` are
    understood; labels without a direction (``"FN"``, ``"FP"``, ``"L"``, ``""``) and numbered
    components (``"H1"``, ``"HN2"``: one digit after letters) give ``None``.
    """
    text = str(component or "").strip().upper()
    if not text:
        return None
    if text in _LETTER_AZIMUTH:
        return _LETTER_AZIMUTH[text]
    m = _TRAILING_DEGREES.search(text)
    if m is None:
        return None
    head = text[: m.start()].strip()
    if head and len(m.group(1).split(".")[0]) < 2:
        return None  # "H1", "HN2": numbered components of unknown orientation, not azimuths
    value = float(m.group(1))
    return None if value > 360.0 else value % 360.0


def is_vertical(component: str) -> bool:
    """True when a component label names the vertical (``UP``, ``Down``, ``HNZ``, ``...-UP``)."""
    text = str(component or "").strip().upper()
    if text in _VERTICAL:
        return True
    return any(text.endswith(s) for s in _VERTICAL_SUFFIX)


def _angle_between(a: float, b: float) -> float:
    """``(b - a)`` folded into ``(-180, 180]`` degrees."""
    d = (b - a) % 360.0
    return d - 360.0 if d > 180.0 else d


def _fmt_deg(x: float) -> str:
    return f"{x:.6g}"


def _check_components(a: Record, b: Record, where: str, which: Callable[[Record], str]) -> None:
    """Refuse a pair of components that cannot be one pair: a vertical one (ValueError that names
    it by ``which(rec)``) or two time steps more than 1e-9 apart (ValueError after ``where``).
    Both the constructor of :class:`RecordPair` and the file reader :func:`read_pair` (which
    names the file and channel) check through here."""
    for rec in (a, b):
        if is_vertical(rec.meta.get("component", "")):
            raise ValueError(
                f"{which(rec)} is a vertical component ({rec.meta.get('component')!r}); a pair "
                "holds two horizontal components"
            )
    if not math.isclose(a.dt, b.dt, rel_tol=1e-9):
        raise ValueError(
            f"{where}: the components have different time steps ({a.name}: dt = {a.dt:g} s, "
            f"{b.name}: dt = {b.dt:g} s); resample one first (Record.resampled)"
        )


def _common_name(a: str, b: str) -> str:
    prefix = os.path.commonprefix([a, b]).rstrip("-_. ")
    if prefix:
        if prefix.endswith(".ch"):
            prefix = prefix[:-3]
        return prefix
    return f"{a}+{b}"


@dataclass(frozen=True, eq=False)
class RecordPair:
    """Two orthogonal horizontal components of one ground motion, on one clock.

    Parameters
    ----------
    first, second
        The components (``accel`` [m/s^2]); their ``dt`` [s] must agree (relative 1e-9).  When
        their lengths differ, the shorter is padded with zeros at its end (``meta['padded']``
        holds the number of added samples).
    name
        Label of the pair; default the common part of the components' names.
    azimuths
        ``(az1, az2)`` [deg clockwise from north] or ``None`` each; default parsed from the
        components' ``meta['component']`` (:func:`component_azimuth`).  Two known azimuths
        must be 90 deg apart.
    npts_recorded
        Recorded lengths before padding; set by the constructor (pass only to rebuild a pair).

    Attributes
    ----------
    accel
        ``(npts, 2)`` read-only array [m/s^2]: column 0 is ``first``, column 1 ``second``.

    Notes
    -----
    The components are assumed to start at the same instant: true for the channels of one
    CSMIP file (one trigger time) and for PEER NGA pairs; for other pairs of files it is the
    caller's responsibility.  Pairs compare by identity (``eq=False``), like records.
    """

    first: Record
    second: Record
    name: str = ""
    azimuths: tuple[float | None, float | None] | None = None
    npts_recorded: tuple[int, int] | None = None
    accel: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        a, b = self.first, self.second
        for label, rec in (("first", a), ("second", b)):
            if not isinstance(rec, Record):
                raise ValueError(
                    f"RecordPair {self.name!r}: {label} must be a ground_motions.Record, got "
                    f"{type(rec).__name__}"
                )
        _check_components(a, b, f"RecordPair {self.name or _common_name(a.name, b.name)!r}",
                          lambda rec: f"RecordPair: {rec.name!r}")
        name = str(self.name) if self.name else _common_name(a.name, b.name)
        recorded = self.npts_recorded or (a.npts, b.npts)
        n = max(a.npts, b.npts)
        if a.npts < n:
            a = a._replace(accel=np.concatenate((a.accel, np.zeros(n - a.npts))), padded=n - a.npts)
        if b.npts < n:
            b = Record(b.name, a.dt, np.concatenate((b.accel, np.zeros(n - b.npts))),
                       {**b.meta, "padded": n - b.npts})
        elif b.dt != a.dt:  # equal within 1e-9: one clock
            b = Record(b.name, a.dt, b.accel, b.meta)
        az = self.azimuths
        if az is None:
            az = (component_azimuth(a.meta.get("component", "")),
                  component_azimuth(b.meta.get("component", "")))
        else:
            if len(az) != 2:
                raise ValueError(f"RecordPair {name!r}: azimuths must be two values (or None), got {az!r}")
            az = tuple(None if x is None else float(x) % 360.0 for x in az)
            for x in az:
                if x is not None and not math.isfinite(x):
                    raise ValueError(f"RecordPair {name!r}: azimuth {x!r} is not finite")
        if az[0] is not None and az[1] is not None:
            d = abs(abs(_angle_between(az[0], az[1])) - 90.0)
            if d > ORTHOGONAL_TOL_DEG:
                raise ValueError(
                    f"RecordPair {name!r}: components {a.name!r} (azimuth {_fmt_deg(az[0])} deg) and "
                    f"{b.name!r} (azimuth {_fmt_deg(az[1])} deg) are not orthogonal; a pair needs "
                    "two horizontal components 90 deg apart"
                )
        acc = np.column_stack((a.accel, b.accel))
        acc.setflags(write=False)
        object.__setattr__(self, "first", a)
        object.__setattr__(self, "second", b)
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "azimuths", az)
        object.__setattr__(self, "npts_recorded", (int(recorded[0]), int(recorded[1])))
        object.__setattr__(self, "accel", acc)

    def __reduce__(self):
        return (RecordPair, (self.first, self.second, self.name, self.azimuths, self.npts_recorded))

    # ------------------------------------------------------------------ derived quantities
    @property
    def dt(self) -> float:
        """Time step [s]."""
        return self.first.dt

    @property
    def npts(self) -> int:
        """Number of samples (after padding)."""
        return self.first.npts

    @property
    def time(self) -> np.ndarray:
        """Sample times ``i * dt`` [s]."""
        return self.first.time

    @property
    def duration(self) -> float:
        """Time of the last sample [s]."""
        return self.first.duration

    @property
    def components(self) -> tuple[str, str]:
        """The components' labels from their files (``meta['component']``; ``''`` if none)."""
        return (str(self.first.meta.get("component", "")), str(self.second.meta.get("component", "")))

    @property
    def pga(self) -> tuple[float, float]:
        """Peak ground acceleration of each component [m/s^2]."""
        return (self.first.pga, self.second.pga)

    @property
    def peak_resultant(self) -> float:
        """Peak of the plan resultant ``max_t sqrt(a1^2 + a2^2)`` [m/s^2]."""
        return float(np.max(np.hypot(self.accel[:, 0], self.accel[:, 1])))

    @property
    def scale_factor(self) -> float:
        """The product of the factors applied by :meth:`scaled` (1 for an unscaled pair)."""
        return float(self.first.meta.get("scale_factor", 1.0))

    @property
    def rotation_deg(self) -> float:
        """The total rotation applied by :meth:`rotated` [deg]."""
        return float(self.first.meta.get("rotated_deg", 0.0))

    # ------------------------------------------------------------------ transformed copies
    def _rebuild(self, first: Record, second: Record, azimuths) -> RecordPair:
        return RecordPair(first, second, self.name, azimuths, self.npts_recorded)

    def scaled(self, factor: float) -> RecordPair:
        """Both components times one ``factor`` (ASCE 7-22 17.3.3: one factor per pair)."""
        f = float(factor)
        if not math.isfinite(f):
            raise ValueError(f"RecordPair {self.name!r}: scale factor must be finite, got {factor!r}")
        return self._rebuild(self.first.scaled(f), self.second.scaled(f), self.azimuths)

    def rotated(self, theta_deg: float) -> RecordPair:
        """Both axes turned by ``theta_deg`` from component 1 towards component 2 (module docstring).

        The new components' azimuths (when known) are ``az + s theta``; ``meta['component']``
        becomes the new azimuth (``"<az> deg"``) or ``"<old>+<theta>deg"``, and
        ``meta['rotated_deg']`` accumulates the rotation.
        """
        t = float(theta_deg)
        if not math.isfinite(t):
            raise ValueError(f"RecordPair {self.name!r}: rotation angle must be finite, got {theta_deg!r}")
        c, s = math.cos(math.radians(t)), math.sin(math.radians(t))
        a1, a2 = self.accel[:, 0], self.accel[:, 1]
        new = (c * a1 + s * a2, -s * a1 + c * a2)
        az1, az2 = self.azimuths
        if az1 is not None and az2 is not None:
            sign = 1.0 if _angle_between(az1, az2) > 0.0 else -1.0
            azimuths = ((az1 + sign * t) % 360.0, (az2 + sign * t) % 360.0)
        else:
            azimuths = (None, None)
        out = []
        for rec, acc, az in zip((self.first, self.second), new, azimuths):
            label = (f"{_fmt_deg(az)} deg" if az is not None
                     else f"{rec.meta.get('component', '')}+{_fmt_deg(t)}deg")
            total = (float(rec.meta.get("rotated_deg", 0.0)) + t) % 360.0
            out.append(rec._replace(accel=acc, component=label, rotated_deg=total))
        return self._rebuild(out[0], out[1], azimuths)

    def with_leading_zero(self) -> RecordPair:
        """A copy starting from rest: one ``a = 0`` sample prepended to both components when either
        starts away from zero (else ``self``); see :meth:`Record.with_leading_zero`."""
        if self.accel[0, 0] == 0.0 and self.accel[0, 1] == 0.0:
            return self
        recs = [r._replace(accel=np.concatenate(([0.0], r.accel)), leading_zero=True)
                for r in (self.first, self.second)]
        n1, n2 = self.npts_recorded
        return RecordPair(recs[0], recs[1], self.name, self.azimuths, (n1 + 1, n2 + 1))

    def resampled(self, dt: float) -> RecordPair:
        """Both components resampled at step ``dt`` [s] (linear interpolation, :meth:`Record.resampled`)."""
        a, b = self.first.resampled(dt), self.second.resampled(dt)
        ratio = self.dt / a.dt
        recorded = tuple(int(math.floor((n - 1) * ratio * (1.0 + 1e-12))) + 1 for n in self.npts_recorded)
        return RecordPair(a, b, self.name, self.azimuths, recorded)

    def trimmed(self) -> RecordPair:
        """A copy cut to the shorter recorded length (no zero padding)."""
        n = min(self.npts_recorded)
        if n == self.npts:
            return self
        cut = [Record(r.name, r.dt, r.accel[:n], {k: v for k, v in r.meta.items() if k != "padded"})
               for r in (self.first, self.second)]
        return RecordPair(cut[0], cut[1], self.name, self.azimuths, (n, n))

    def __repr__(self) -> str:
        az = ", ".join("?" if x is None else _fmt_deg(x) for x in self.azimuths)
        return (
            f"RecordPair(name={self.name!r}, dt={self.dt:g} s, npts={self.npts}, azimuths=({az}) deg, "
            f"pga=({self.first.pga / G:.3f}, {self.second.pga / G:.3f}) g)"
        )


# --------------------------------------------------------------------------- readers
def _horizontal_channels(path: Path, read_kw: dict) -> list[Record]:
    """Every horizontal channel of a multi-channel file, in file order."""
    first = _read(path, channel=1, **read_kw)
    n = int(first.meta.get("n_channels", 0))
    if n == 0 and first.meta.get("format") == "csv":
        recs = [first]
        k = 2
        while True:
            try:
                recs.append(_read(path, channel=k, **read_kw))
            except ValueError as exc:
                if "acceleration columns" in str(exc):
                    break
                raise
            k += 1
    else:
        recs = [first] + [_read(path, channel=k, **read_kw) for k in range(2, n + 1)]
    return [r for r in recs if not is_vertical(r.meta.get("component", ""))]


def _check_same_station(a: Record, b: Record, pa: Path, pb: Path) -> None:
    for key in ("station", "event"):
        x, y = str(a.meta.get(key, "")).strip(), str(b.meta.get(key, "")).strip()
        if x and y and x.lower() != y.lower():
            raise ValueError(
                f"{pa} and {pb}: the files name different {key}s ({x!r} and {y!r}); a pair holds two "
                "components of one recording (pass check_station=False to pair them anyway)"
            )


def read_pair(
    path_a: str | Path,
    path_b: str | Path | None = None,
    *,
    channels: tuple[int, int] | None = None,
    name: str | None = None,
    check_station: bool = True,
    **read_kw,
) -> RecordPair:
    """Read the two horizontal components of one ground motion.

    Parameters
    ----------
    path_a, path_b
        Two files, one component each (e.g. ``RSN6_IMPVALL.I_I-ELC180.AT2`` and
        ``...ELC270.AT2``), or ``path_a`` alone: a multi-channel V1/V2 file (or a CSV with two
        acceleration columns) whose two horizontal channels are taken.
    channels
        ``(channel of the first, channel of the second)``, 1-based: for two multi-channel files,
        the channel read from each (default each file's first horizontal channel); for one
        file, the two channels (default its two horizontal ones, refused when it has more).
    name
        The pair's name; default the common part of the components' names.
    check_station
        Refuse two files whose headers name different stations or events (default).
    **read_kw
        Passed to :func:`ground_motions.read` for both files (``fmt``, ``dt``, ``units``).

    Returns
    -------
    RecordPair
        Components in ``m/s^2`` on one clock (the shorter zero-padded at its end).

    Raises
    ------
    ValueError
        Naming the file(s): unreadable file (from :func:`ground_motions.read`), the same file
        twice, a file with fewer or more than two horizontal channels, a vertical component,
        different time steps, different stations, components not 90 deg apart.
    """
    if "channel" in read_kw:
        raise ValueError(f"{path_a}: read_pair takes channels=(a, b), not channel=")
    pa = Path(path_a)
    if channels is not None:
        try:
            ca, cb = (int(c) for c in channels)
        except (TypeError, ValueError):
            raise ValueError(
                f"{pa}: channels must be two 1-based channel numbers, got {channels!r}"
            ) from None
    if path_b is None:
        if channels is not None:
            a = _read(pa, channel=ca, **read_kw)
            b = _read(pa, channel=cb, **read_kw)
            if ca == cb:
                raise ValueError(f"{pa}: channels=({ca}, {cb}) names the same channel twice")
        else:
            horiz = _horizontal_channels(pa, read_kw)
            if len(horiz) != 2:
                what = "one horizontal component" if len(horiz) == 1 else f"{len(horiz)} horizontal channels"
                raise ValueError(
                    f"{pa}: the file holds {what}; a pair needs two: pass a second file"
                    + (" or channels=(a, b)" if len(horiz) > 2 else "")
                )
            a, b = horiz
        pb = pa
    else:
        pb = Path(path_b)
        if pa.resolve() == pb.resolve():
            raise ValueError(f"{pa}: the same file was given twice; a pair needs two components")
        a = _read(pa, **({"channel": ca} if channels is not None else {}), **read_kw)
        b = _read(pb, **({"channel": cb} if channels is not None else {}), **read_kw)
        if check_station:
            _check_same_station(a, b, pa, pb)
    where = f"{pa}" if pb == pa else f"{pa} and {pb}"
    source = {id(a): pa, id(b): pb}
    _check_components(a, b, where,
                      lambda rec: f"{source[id(rec)]}: channel {rec.meta.get('channel', 1)}")
    try:
        return RecordPair(a, b, name or "")
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
