"""The bundled records, loaded by short name (``ground_motions.load("elcentro")``).

The files live in ``ground_motions/records/`` (byte-for-byte copies; provenance and licence
status in ``records/PROVENANCE.md``).  Loaded records are cached: a ``Record`` is immutable.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from .io import read
from .pairs import RecordPair
from .processing import baseline_correct
from .record import Record


@dataclass(frozen=True)
class _Entry:
    file: str
    read_kw: tuple[tuple[str, object], ...] = ()
    uncorrected: bool = False
    event: str = ""
    station: str = ""
    #: The two horizontal channels (component 1, component 2) of a three-channel file.
    pair: tuple[int, int] | None = None


#: Short name -> file (and reading options). Order is the order of ``available()``.
_CATALOGUE: dict[str, _Entry] = {
    "elcentro": _Entry(
        "RSN6_IMPVALL.I_I-ELC180.AT2",
        event="Imperial Valley-02, 1940-05-19, M6.95",
        station="El Centro Array #9",
    ),
    "sanfernando": _Entry(
        "RSN77_SFERN_PUL164.AT2",
        event="San Fernando, 1971-02-09, M6.61",
        station="Pacoima Dam (upper left abutment)",
    ),
    "rinaldi": _Entry(
        "Rinaldi228.AT2",
        event="Northridge-01, 1994-01-17, M6.69",
        station="Rinaldi Receiving Sta",
    ),
    "landers": _Entry(
        "RSN879_LANDERS_LCN260.AT2",
        event="Landers, 1992-06-28, M7.28",
        station="Lucerne",
    ),
    "lomaprieta": _Entry(
        "RSN738_LOMAP_NAS270.AT2",
        event="Loma Prieta, 1989-10-18, M6.93",
        station="Alameda Naval Air Stn Hanger",
    ),
    "kocaeli": _Entry(
        "RSN1155_KOCAELI_BUR000.AT2",
        event="Kocaeli (Turkey), 1999-08-17, M7.51",
        station="Bursa Tofas",
    ),
    "chichi": _Entry(
        "RSN1180_CHICHI_CHY002-W.AT2",
        event="Chi-Chi (Taiwan), 1999-09-20, M7.62",
        station="CHY002",
    ),
    "tabas": _Entry(
        "tabasFN.txt",
        (("fmt", "text"), ("dt", 0.02), ("units", "g")),
        event="Tabas (Iran), 1978-09-16, M7.35",
        station="Tabas",
    ),
    "santamonica": _Entry(
        "S_MONICA.V2",
        pair=(1, 3),  # 90 deg, 360 deg (channel 2 is UP)
        event="Northridge, 1994-01-17, M6.7",
        station="Santa Monica City Hall Grounds, CSMIP 24538",
    ),
    "ferndale": _Entry(
        "ce89486SampleInput.v2",
        pair=(1, 2),  # 180 deg, 90 deg (channel 3 is Up)
        event="Ferndale (offshore Cape Mendocino), 2022-12-20, M6.4",
        station="Fortuna - 701 S. Fortuna Blvd, CGS 89486",
    ),
    "ridgecrest": _Entry(
        "CICCC.RAW",
        uncorrected=True,
        pair=(1, 2),  # 90 deg, 360 deg (channel 3 is Up)
        event="Ridgecrest, 2019-07-06, M7.1",
        station="China Lake NWC - Christmas Canyon Rd (CI.CCC)",
    ),
}

#: Baseline correction applied to uncorrected bundled records (see ``processing``): the
#: Ridgecrest CCC file starts ~16 s before the origin time, so its first 10 s are pre-event
#: noise; 0.05 Hz is the corner gmprocess picks for M7 records at this distance.
RIDGECREST_CORRECTION = {"pre_event": 10.0, "highpass": 0.05, "order": 6}


def available() -> tuple[str, ...]:
    """Short names of the bundled records."""
    return tuple(_CATALOGUE)


def available_pairs() -> tuple[str, ...]:
    """Short names of the bundled records that carry both horizontal components."""
    return tuple(k for k, e in _CATALOGUE.items() if e.pair is not None)


def path(name: str) -> Path:
    """Path of a bundled record's file."""
    entry = _entry(name)
    return Path(str(resources.files("ground_motions.records").joinpath(entry.file)))


def _entry(name: str) -> _Entry:
    key = str(name).strip().lower()
    if key not in _CATALOGUE:
        raise ValueError(f"unknown record {name!r}; available: {', '.join(_CATALOGUE)}")
    return _CATALOGUE[key]


def load(name: str, *, channel: int | None = None, corrected: bool = True) -> Record:
    """Load a bundled record by short name (see :func:`available`).

    Parameters
    ----------
    name
        ``elcentro``, ``sanfernando``, ``rinaldi``, ``landers``, ``lomaprieta``, ``kocaeli``,
        ``chichi``, ``tabas``, ``santamonica``, ``ferndale`` or ``ridgecrest``.
    channel
        For the three-channel files (``santamonica``, ``ferndale``, ``ridgecrest``): 1..3.
        Default: the first horizontal channel.
    corrected
        ``ridgecrest`` is an uncorrected V1 file: by default it is baseline-corrected with
        :data:`RIDGECREST_CORRECTION`; ``corrected=False`` returns the raw samples.

    Returns
    -------
    Record
        Acceleration in m/s^2; ``name`` is the short name (``name.chN`` for a non-default
        channel).
    """
    rec = _load(str(name).strip().lower(), None if channel is None else int(channel), bool(corrected))
    # the parsed record is cached; each caller gets its own metadata dict (and array copy)
    return Record(rec.name, rec.dt, rec.accel, copy.deepcopy(rec.meta))


@lru_cache(maxsize=64)
def _load(key: str, channel: int | None, corrected: bool) -> Record:
    entry = _entry(key)
    rec = read(path(key), channel=channel, **dict(entry.read_kw))
    label = key if channel is None else f"{key}.ch{channel}"
    meta = {**rec.meta, "short_name": key, "event": entry.event, "station": entry.station}
    if key == "tabas":
        meta["component"] = "FN"
    if entry.uncorrected:
        meta["uncorrected_source"] = True
        rec = Record(label, rec.dt, rec.accel, meta)
        if corrected:
            rec = baseline_correct(rec, **RIDGECREST_CORRECTION)
        return rec
    return Record(label, rec.dt, rec.accel, meta)


def load_pair(name: str, *, corrected: bool = True) -> RecordPair:
    """Load both horizontal components of a bundled record (see :func:`available_pairs`).

    Parameters
    ----------
    name
        ``santamonica`` (channels 1 and 3: 90 and 360 deg), ``ferndale`` (channels 1 and 2: 180
        and 90 deg) or ``ridgecrest`` (channels 1 and 2: 90 and 360 deg).
    corrected
        ``ridgecrest`` is an uncorrected V1 file: by default each component is baseline-corrected
        with :data:`RIDGECREST_CORRECTION` (as :func:`load` does); ``corrected=False`` gives the
        raw samples.

    Returns
    -------
    RecordPair
        Named after the short name; the components are the records ``load(name, channel=k)``
        returns. Ridgecrest's channels hold 35430 and 35402 samples: the shorter is zero-padded
        at its end (``RecordPair.trimmed()`` cuts both to 35402 instead).
    """
    key = str(name).strip().lower()
    entry = _entry(key)
    if entry.pair is None:
        raise ValueError(
            f"record {name!r} has one horizontal component bundled; pairs: {', '.join(available_pairs())}"
        )
    first, second = (load(key, channel=c, corrected=corrected) for c in entry.pair)
    return RecordPair(first, second, key)
