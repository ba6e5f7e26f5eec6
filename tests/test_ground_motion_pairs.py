"""Pairs of horizontal components (issue 14, point 3): one clock, one scale factor, rotation.

An isolated building is analysed under both horizontal components at once, so the two must
share one clock (dt and start), be the two *horizontal* components of one recording, 90 deg
apart, and be scaled by one factor.  The readers refuse anything else with a ``ValueError``
naming the file; they are fuzzed like every other reader (``tests/test_reader_fuzz.py``).
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from _tiers import Tier, run_examples, tiers
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions as gm
from ground_motions.catalogue import path as record_path
from ground_motions.pairs import component_azimuth, is_vertical
from tests.test_reader_fuzz import (
    FAST,
    Format,
    _at2,
    _csmip_two_channels,
    _fuzz,
    _seed,
    _write,
    mutated,
)

G = gm.G


# ------------------------------------------------------------------------- bundled pairs
#: short name -> (channels, components, PGA of each [g] from PROVENANCE.md, recorded npts)
BUNDLED = {
    "santamonica": ((1, 3), ("90", "360"), (0.883, 0.370), (3000, 3000)),
    "ferndale": ((1, 2), ("180", "90"), (0.396, 0.267), (10100, 10100)),
    "ridgecrest": ((1, 2), ("90", "360"), (0.567, 0.471), (35430, 35402)),
}


def test_the_three_bundled_pairs_are_the_records_that_carry_both_horizontal_components():
    assert gm.available_pairs() == ("santamonica", "ferndale", "ridgecrest")


@pytest.mark.parametrize("name", list(BUNDLED))
def test_a_bundled_pair_is_its_two_horizontal_channels_on_one_clock(name):
    channels, components, pga_g, recorded = BUNDLED[name]
    pair = gm.load_pair(name)
    assert pair.name == name and pair.components == components
    assert pair.npts_recorded == recorded and pair.npts == max(recorded)
    assert pair.accel.shape == (pair.npts, 2) and not pair.accel.flags.writeable
    for k, (ch, rec) in enumerate(zip(channels, (pair.first, pair.second))):
        alone = gm.load(name, channel=ch)
        assert not is_vertical(alone.meta["component"]) and rec.dt == alone.dt
        np.testing.assert_array_equal(pair.accel[: alone.npts, k], alone.accel)
        np.testing.assert_array_equal(pair.accel[alone.npts:, k], 0.0)
        # the table rounds to 3 decimals; ridgecrest is compared after its baseline correction
        tol = 0.01 * pga_g[k] if name == "ridgecrest" else 0.6e-3
        assert rec.pga / G == pytest.approx(pga_g[k], abs=tol)
    az1, az2 = pair.azimuths
    assert abs(abs((az2 - az1 + 180.0) % 360.0 - 180.0) - 90.0) < 1e-9


def test_ridgecrest_keeps_every_recorded_sample_and_pads_the_shorter_channel_with_zeros():
    pair = gm.load_pair("ridgecrest")
    assert pair.second.meta["padded"] == 35430 - 35402
    np.testing.assert_array_equal(pair.second.accel[35402:], 0.0)
    cut = pair.trimmed()
    assert cut.npts == 35402 and cut.npts_recorded == (35402, 35402)
    np.testing.assert_array_equal(cut.accel, pair.accel[:35402])
    raw = gm.load_pair("ridgecrest", corrected=False)
    np.testing.assert_array_equal(raw.first.accel, gm.load("ridgecrest", corrected=False).accel)
    assert not np.array_equal(raw.first.accel, pair.first.accel)  # the correction is kept


def test_a_record_with_one_bundled_component_is_refused_by_load_pair():
    with pytest.raises(ValueError, match="'elcentro' has one horizontal component.*santamonica, ferndale, "
                                         "ridgecrest"):
        gm.load_pair("elcentro")
    with pytest.raises(ValueError, match="unknown record 'nope'"):
        gm.load_pair("nope")


# ------------------------------------------------------------------------- the model
def _pair(n: int = 64, dt: float = 0.01, seed: int = 0) -> gm.RecordPair:
    rng = np.random.default_rng(seed)
    a = gm.Record("x.180", dt, rng.normal(size=n), {"component": "180"})
    b = gm.Record("x.270", dt, rng.normal(size=n), {"component": "270"})
    return gm.RecordPair(a, b)


def test_the_pair_is_named_after_its_components_and_reads_their_azimuths():
    p = _pair()
    assert p.name == "x" and p.azimuths == (180.0, 270.0) and p.dt == 0.01 and p.npts == 64
    assert "azimuths=(180, 270) deg" in repr(p)
    q = pickle.loads(pickle.dumps(p))
    np.testing.assert_array_equal(q.accel, p.accel)
    assert q.azimuths == p.azimuths and not q.accel.flags.writeable


def test_one_scale_factor_multiplies_both_components():
    p = _pair()
    s = p.scaled(2.0).scaled(1.5)
    np.testing.assert_array_equal(s.accel, 3.0 * p.accel)
    assert s.scale_factor == 3.0 and s.first.meta["scale_factor"] == s.second.meta["scale_factor"] == 3.0
    with pytest.raises(ValueError, match="scale factor must be finite"):
        p.scaled(float("nan"))


@settings(max_examples=60, deadline=None)
@given(theta=st.floats(-720.0, 720.0, allow_nan=False), seed=st.integers(0, 2**16))
def test_a_rotation_keeps_the_plan_resultant_at_every_instant_and_is_undone_by_its_opposite(theta, seed):
    p = _pair(seed=seed)
    r = p.rotated(theta)
    np.testing.assert_allclose(np.hypot(*r.accel.T), np.hypot(*p.accel.T), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(r.rotated(-theta).accel, p.accel, rtol=0, atol=1e-12)
    assert r.rotation_deg == pytest.approx(theta % 360.0, abs=1e-9) or r.rotation_deg == pytest.approx(
        360.0, abs=1e-9)


def test_a_quarter_turn_takes_component_2_into_1_and_minus_1_into_2():
    p = _pair()
    r = p.rotated(90.0)
    np.testing.assert_allclose(r.accel[:, 0], p.accel[:, 1], atol=1e-15)
    np.testing.assert_allclose(r.accel[:, 1], -p.accel[:, 0], atol=1e-15)
    assert r.azimuths == (270.0, 0.0)


def test_rotated_component_1_is_the_ground_motion_along_its_new_azimuth():
    """Santa Monica: component 1 points east (90), component 2 north (360), i.e. 90 deg
    counter-clockwise of 1: turning by 30 deg gives azimuth 60, whose motion is
    a_E sin 60 + a_N cos 60."""
    p = gm.load_pair("santamonica")
    r = p.rotated(30.0)
    assert r.azimuths == pytest.approx((60.0, 330.0))
    east, north = p.accel[:, 0], p.accel[:, 1]
    np.testing.assert_allclose(r.accel[:, 0], east * math.sin(math.radians(60)) + north * math.cos(
        math.radians(60)), atol=1e-12)
    assert r.first.meta["component"] == "60 deg" and r.first.meta["rotated_deg"] == 30.0


@settings(max_examples=40, deadline=None)
@given(n1=st.integers(1, 60), n2=st.integers(1, 60))
def test_components_of_different_lengths_keep_every_sample_and_end_in_zeros(n1, n2):
    rng = np.random.default_rng(n1 * 61 + n2)
    a, b = rng.normal(size=n1), rng.normal(size=n2)
    p = gm.RecordPair(gm.Record("a", 0.02, a), gm.Record("b", 0.02, b))
    n = max(n1, n2)
    assert p.npts == n and p.npts_recorded == (n1, n2)
    np.testing.assert_array_equal(p.accel[:n1, 0], a)
    np.testing.assert_array_equal(p.accel[:n2, 1], b)
    np.testing.assert_array_equal(p.accel[n1:, 0], 0.0)
    np.testing.assert_array_equal(p.accel[n2:, 1], 0.0)
    t = p.trimmed()
    assert t.npts == min(n1, n2) and "padded" not in t.first.meta and "padded" not in t.second.meta


def test_a_pair_starts_from_rest_and_resamples_both_components_on_one_clock():
    p = _pair()
    z = p.with_leading_zero()
    assert z.npts == p.npts + 1 and np.all(z.accel[0] == 0.0) and z.npts_recorded == (65, 65)
    np.testing.assert_array_equal(z.accel[1:], p.accel)
    assert z.with_leading_zero() is z
    r = p.resampled(0.005)
    assert r.dt == 0.005 and r.npts == 2 * p.npts - 1 and r.azimuths == p.azimuths
    np.testing.assert_array_equal(r.accel[::2], p.accel)
    ridge = gm.load_pair("ridgecrest").resampled(0.005)
    assert ridge.npts_recorded == (2 * 35430 - 1, 2 * 35402 - 1) and ridge.trimmed().npts == 2 * 35402 - 1


def test_a_pair_refuses_different_steps_a_vertical_component_and_non_orthogonal_azimuths():
    a = gm.Record("a", 0.01, np.ones(10), {"component": "180"})
    with pytest.raises(ValueError, match=r"different time steps \(a: dt = 0.01 s, b: dt = 0.02 s\)"):
        gm.RecordPair(a, gm.Record("b", 0.02, np.ones(10), {"component": "90"}))
    with pytest.raises(ValueError, match="'up' is a vertical component"):
        gm.RecordPair(a, gm.Record("up", 0.01, np.ones(10), {"component": "UP"}))
    with pytest.raises(ValueError, match=r"azimuth 180 deg\) and 'c' \(azimuth 135 deg\) are not orthogonal"):
        gm.RecordPair(a, gm.Record("c", 0.01, np.ones(10), {"component": "135"}))
    with pytest.raises(ValueError, match="first must be a ground_motions.Record"):
        gm.RecordPair(np.ones(10), a)
    h1h2 = gm.RecordPair(gm.Record("r.H1", 0.01, np.ones(10), {"component": "H1"}),
                         gm.Record("r.H2", 0.01, np.ones(10), {"component": "H2"}))
    assert h1h2.azimuths == (None, None)  # numbered components: orientation unknown, still a pair
    unknown = gm.RecordPair(a, gm.Record("fn", 0.01, np.ones(10), {"component": "FN"}))
    assert unknown.azimuths == (180.0, None)
    assert unknown.rotated(10.0).azimuths == (None, None)


@pytest.mark.parametrize(("label", "azimuth"), [
    ("180", 180.0), ("90 Deg", 90.0), ("360", 0.0), ("ELC270", 270.0), ("W", 270.0), ("N", 0.0),
    ("E-W", 90.0), ("HNE", 90.0), ("FN", None), ("", None), ("L", None), ("999", None), ("H1", None),
    ("HN2", None), ("5", 5.0), ("LCN260", 260.0), ("BUR000", 0.0),
])
def test_component_labels_name_azimuths_clockwise_from_north(label, azimuth):
    assert component_azimuth(label) == azimuth


@pytest.mark.parametrize("label", ["UP", "Up", "Down", "HNZ", "I-ELCUP", "DWN", "V"])
def test_vertical_labels_are_recognised(label):
    assert is_vertical(label)


# ------------------------------------------------------------------------- read_pair
def _at2_component(component: str, *, dt: str | None = None, station: str | None = None) -> bytes:
    """The El Centro AT2 seed (40 values) with another component / dt / station."""
    lines = _at2().decode().splitlines(keepends=True)
    parts = lines[1].rstrip("\r\n").split(",")
    eol = lines[1][len(lines[1].rstrip("\r\n")):]
    parts[-1] = f" {component}"
    if station is not None:
        parts[2] = f" {station}"
    lines[1] = ",".join(parts) + eol
    if dt is not None:
        lines[3] = lines[3].replace(".0100", dt)
    return "".join(lines).encode()


def test_two_at2_files_of_one_station_make_a_pair(tmp_path):
    _write(tmp_path, {"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270")})
    p = gm.read_pair(tmp_path / "a.AT2", tmp_path / "b.AT2")
    assert p.azimuths == (180.0, 270.0) and p.npts == 40 and p.dt == 0.01
    np.testing.assert_array_equal(p.accel[:, 0], gm.read(tmp_path / "a.AT2").accel)


def test_one_multichannel_file_gives_its_two_horizontal_channels():
    p = gm.read_pair(record_path("santamonica"))
    assert p.components == ("90", "360") and p.name == "S_MONICA"
    np.testing.assert_array_equal(p.accel, gm.load_pair("santamonica").accel)
    q = gm.read_pair(record_path("ferndale"), channels=(2, 1))
    assert q.components == ("90", "180")


PAIR_CASES = [
    ({"a.AT2": _at2_component("180")}, ("a.AT2", "a.AT2"), r"a\.AT2: the same file was given twice"),
    ({"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270", dt=".0200")}, ("a.AT2", "b.AT2"),
     r"a\.AT2 and .*b\.AT2: the components have different time steps \(.*dt = 0.01 s, .*dt = 0.02 s\)"),
    ({"a.AT2": _at2_component("180"), "b.AT2": _at2_component("UP")}, ("a.AT2", "b.AT2"),
     r"b\.AT2: channel 1 is a vertical component \('UP'\)"),
    ({"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270", station="Elsewhere")},
     ("a.AT2", "b.AT2"), r"a\.AT2 and .*b\.AT2: the files name different stations"),
    ({"a.AT2": _at2_component("180"), "b.AT2": _at2_component("225")}, ("a.AT2", "b.AT2"),
     r"a\.AT2 and .*b\.AT2: .*are not orthogonal"),
    ({"a.AT2": _at2_component("180")}, ("a.AT2", None),
     r"a\.AT2: the file holds one horizontal component; a pair needs two: pass a second file"),
    ({"r.v2": _csmip_two_channels().replace(b"Chan  2:  90 Deg", b"Chan  2: Up     ")}, ("r.v2", None),
     r"r\.v2: the file holds one horizontal component"),
    ({"r.v2": _csmip_two_channels()}, ("r.v2", None, (1, 1)), r"r\.v2: channels=\(1, 1\) names the same "
     "channel twice"),
    ({"r.v2": _csmip_two_channels()}, ("r.v2", None, (1, 5)), r"r\.v2: channel=5 but the file has channels "
     r"1\.\.2"),
]


@pytest.mark.parametrize(("files", "args", "expected"), PAIR_CASES,
                         ids=[f"case{i}" for i in range(len(PAIR_CASES))])
def test_read_pair_refuses_what_is_not_a_pair_naming_the_file(tmp_path, files, args, expected):
    _write(tmp_path, files)
    a, b = tmp_path / args[0], None if args[1] is None else tmp_path / args[1]
    kw = {"channels": args[2]} if len(args) > 2 else {}
    with pytest.raises(ValueError, match=expected) as exc:
        gm.read_pair(a, b, **kw)
    assert type(exc.value) is ValueError


def test_components_of_different_stations_can_be_paired_on_request(tmp_path):
    _write(tmp_path, {"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270", station="Elsewhere")})
    p = gm.read_pair(tmp_path / "a.AT2", tmp_path / "b.AT2", check_station=False, name="synthetic")
    assert p.name == "synthetic"


# ------------------------------------------------------------------------- fuzzing
def _check_pair(p) -> None:
    assert isinstance(p, gm.RecordPair) and math.isfinite(p.dt) and p.dt > 0
    assert p.accel.shape == (max(p.npts_recorded), 2) and np.all(np.isfinite(p.accel))
    assert all(r.npts == p.npts for r in (p.first, p.second))


PAIR_FORMATS = [
    Format("pair-at2-first", "a.AT2",
           lambda: {"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270")},
           lambda d: gm.read_pair(d / "a.AT2", d / "b.AT2"), _check_pair),
    Format("pair-at2-second", "b.AT2",
           lambda: {"a.AT2": _at2_component("180"), "b.AT2": _at2_component("270")},
           lambda d: gm.read_pair(d / "a.AT2", d / "b.AT2"), _check_pair),
    Format("pair-v2-one-file", "r.v2", lambda: {"r.v2": _csmip_two_channels()},
           lambda d: gm.read_pair(d / "r.v2"), _check_pair),
]


@pytest.mark.parametrize("fmt", PAIR_FORMATS, ids=[f.id for f in PAIR_FORMATS])
def test_every_pair_seed_is_valid(tmp_path, fmt):
    _write(tmp_path, fmt.files())
    fmt.check(fmt.read(tmp_path))


@pytest.mark.parametrize("tier", tiers(Tier(FAST), Tier(500)))
@pytest.mark.parametrize("fmt", PAIR_FORMATS, ids=[f.id for f in PAIR_FORMATS])
def test_fuzzed_pair_files_are_read_or_refused_with_a_value_error_naming_the_file(tmp_path, fmt, tier):
    """The reader fuzz of ``test_reader_fuzz`` on the pair formats: a mutated target file (the
    others intact) is read into a valid pair or refused with a ValueError naming the file."""
    run_examples(tier, lambda blob: _fuzz(fmt, blob, tmp_path), blob=mutated(_seed(fmt)[fmt.target]))
