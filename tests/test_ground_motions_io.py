"""Readers and bundled records: every number checked here is printed in the source file itself
(header peaks, first/last samples) or in the shared PROVENANCE table, never by our own reader."""

from __future__ import annotations

import dataclasses
import fnmatch
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pytest
from _shared import shared
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions as gm
from ground_motions.catalogue import path as record_path

G = 9.80665
RECORDS = Path(gm.__file__).parent / "records"

# PGA [g] and npts from the PROVENANCE table (computed there with an independent numpy loader).
PROVENANCE = {
    "elcentro": (0.281, 5372, 0.010),
    "sanfernando": (1.219, 4172, 0.010),
    "rinaldi": (0.874, 1991, 0.010),
    "landers": (0.725, 9625, 0.005),
    "lomaprieta": (0.209, 5916, 0.005),
    "kocaeli": (0.101, 27711, 0.005),
    "chichi": (0.110, 37500, 0.004),
    "tabas": (0.900, 2500, 0.020),
    "santamonica": (0.883, 3000, 0.020),
    "ferndale": (0.396, 10100, 0.010),
    "ridgecrest": (0.567, 35430, 0.010),
}


@pytest.mark.parametrize("name", sorted(PROVENANCE))
def test_bundled_record_has_the_published_npts_dt_and_pga(name):
    pga_g, npts, dt = PROVENANCE[name]
    rec = gm.load(name)
    assert rec.npts == npts
    assert rec.dt == pytest.approx(dt, rel=1e-12)
    # the table rounds to 3 decimals; ridgecrest is compared after its baseline correction,
    # which moves the peak by < 1 %
    tol = 0.01 if name == "ridgecrest" else 0.6e-3
    assert rec.pga / G == pytest.approx(pga_g, abs=tol * (pga_g if name == "ridgecrest" else 1.0))
    assert not rec.accel.flags.writeable
    assert rec.meta["event"] and rec.meta["station"] and rec.meta["file"]


def test_available_lists_the_eleven_records_and_unknown_names_are_rejected_with_the_list():
    assert gm.available() == tuple(PROVENANCE) or set(gm.available()) == set(PROVENANCE)
    with pytest.raises(ValueError, match="elcentro.*ridgecrest"):
        gm.load("northridge")


def test_at2_first_and_last_sample_are_the_files_own_values():
    """El Centro: first value .9984852E-03 g, last value (a partial line of 2) -.1790158E-03 g."""
    rec = gm.load("elcentro")
    assert rec.accel[0] == pytest.approx(0.9984852e-3 * G, rel=1e-12)
    assert rec.accel[-1] == pytest.approx(-0.1790158e-3 * G, rel=1e-12)
    assert rec.meta["component"] == "180" and rec.meta["source_units"] == "g"


def test_rinaldi_old_peer_smd_header_with_filter_poles_is_read():
    rec = gm.load("rinaldi")
    assert "POLE" in rec.meta["filter"]
    assert rec.accel[-1] == pytest.approx(0.5856269e-2 * G, rel=1e-12)


def test_at2_with_the_ngawest1_header_form_reads_the_same_values(tmp_path):
    lines = record_path("elcentro").read_text().splitlines(keepends=True)
    lines[3] = "5372    0.0100    NPTS, DT\n"
    p = tmp_path / "elc_old.AT2"
    p.write_text("".join(lines))
    rec = gm.read(p)
    np.testing.assert_array_equal(rec.accel, gm.load("elcentro").accel)
    assert rec.dt == 0.01


def test_old_cdmg_v2_peak_matches_its_header():
    """S_MONICA.V2 ch1 header: 'PEAK ACCELERATION = -865.965 CM/SEC/SEC AT 9.800 SEC'."""
    rec = gm.load("santamonica")
    assert rec.meta["channel"] == 1 and rec.meta["component"] == "90"
    i = int(np.argmax(np.abs(rec.accel)))
    assert i * rec.dt == pytest.approx(9.800)
    assert rec.accel[i] == pytest.approx(-8.65965, abs=1e-5)


def test_new_v2_touching_fixed_width_values_are_cut_by_column():
    """ce89486 ch1 line 438 reads '-172.58609-301.63885-359.26904-381.81464-388.16556'; the header
    gives 'Peak acceleration = -388.166 cm/sec/sec at 35.020 sec'."""
    rec = gm.load("ferndale")
    i = int(round(35.02 / rec.dt))
    np.testing.assert_allclose(
        rec.accel[i - 4 : i + 1], np.array([-172.58609, -301.63885, -359.26904, -381.81464, -388.16556]) / 100
    )
    assert rec.pga == pytest.approx(3.8816556, rel=1e-12)
    assert rec.accel[-1] == pytest.approx(-0.00443 / 100, rel=1e-12)  # line 1309, last of the block


def test_multichannel_channels_and_the_uncorrected_v1_peak():
    """CICCC.RAW ch1 header: 'Max = -.567 g, at 39.410 sec' (real header: -.5666587)."""
    raw = gm.load("ridgecrest", corrected=False)
    assert raw.meta["source_units"] == "g" and raw.npts == 35430
    assert raw.accel[3941] / G == pytest.approx(-0.5666587, abs=1e-6)
    assert gm.load("ridgecrest", channel=2).npts == 35402
    assert gm.load("ridgecrest", channel=3).meta["component"] == "UP"
    assert gm.load("santamonica", channel=2).meta["component"] == "UP"
    with pytest.raises(ValueError, match="channels 1..3"):
        gm.load("ferndale", channel=4)


def test_default_channel_is_the_first_horizontal_one(tmp_path):
    """With the vertical channel moved first, the default is the next (horizontal) channel."""
    text = record_path("santamonica").read_bytes().decode()
    parts = text.split("/&")
    ends = [p.split("\n", 1) for p in parts[1:]]  # the rest of each '/&' line, then the next channel
    ch1 = parts[0] + "/&" + ends[0][0] + "\n"
    ch2 = ends[0][1] + "/&" + ends[1][0] + "\n"
    ch3 = ends[1][1] + "/&" + ends[2][0]
    p = tmp_path / "swapped.V2"
    p.write_bytes((ch2 + ch1 + ch3).encode())
    rec = gm.read(p)
    assert rec.meta["channel"] == 2 and rec.meta["component"] == "90"
    np.testing.assert_array_equal(rec.accel, gm.load("santamonica").accel)


def test_tabas_text_needs_dt_and_units():
    p = record_path("tabas")
    rec = gm.read(p, dt=0.02, units="g")
    assert rec.accel[0] == pytest.approx(0.039111 * G) and rec.accel[-1] == pytest.approx(0.004970 * G)
    with pytest.raises(ValueError, match="pass dt="):
        gm.read(p, units="g")
    with pytest.raises(ValueError, match="pass units="):
        gm.read(p, dt=0.02)
    with pytest.raises(ValueError, match="unknown acceleration units 'furlongs'"):
        gm.read(p, dt=0.02, units="furlongs")


def test_two_column_text_takes_dt_from_the_time_column_and_rejects_a_jump(tmp_path):
    p = tmp_path / "two.txt"
    p.write_text("# t a\n0.0 0.0\n0.01 1.0\n0.02 2.0\n0.03 -1.0\n")
    rec = gm.read(p, units="cm/s^2")
    assert rec.dt == pytest.approx(0.01) and rec.accel.tolist() == pytest.approx([0, 0.01, 0.02, -0.01])
    p.write_text("0.0 0.0\n0.01 1.0\n0.03 2.0\n0.04 -1.0\n")
    with pytest.raises(ValueError, match=r"line 3: non-uniform time step: t = 0.03"):
        gm.read(p, units="g")


def test_csv_with_unit_suffixed_columns(tmp_path):
    p = tmp_path / "rec.csv"
    p.write_text("time_s,accel_cmps2,accel_g\n0,0,0\n0.005,10,0.1\n0.010,-20,0.2\n")
    rec = gm.read(p)
    assert rec.dt == pytest.approx(0.005) and rec.accel.tolist() == pytest.approx([0, 0.1, -0.2])
    assert gm.read(p, channel=2).accel[-1] == pytest.approx(0.2 * G)
    p.write_text("time_s,accel_furlongs\n0,0\n0.01,1\n")
    with pytest.raises(ValueError, match="no acceleration column"):
        gm.read(p)
    p.write_text("accel_mps2\n0\n1\n")
    with pytest.raises(ValueError, match="pass dt="):
        gm.read(p)
    assert gm.read(p, dt=0.01).accel.tolist() == [0.0, 1.0]


@pytest.mark.parametrize(
    ("content", "kw", "message"),
    [
        ("", {}, "empty file"),
        ("0.1\nnan\n0.2\n", {"dt": 0.01, "units": "g"}, r"line 2: value 'nan' is not finite"),
        ("0.1\n0.2x\n", {"dt": 0.01, "units": "g"}, r"line 2: value '0.2x' is not a number"),
        ("0.1\n0.2\n", {"dt": 0.0, "units": "g"}, r"dt = 0.0 s must be finite and > 0"),
        ("0.1\n0.2\n", {"dt": -0.01, "units": "g"}, r"must be finite and > 0"),
    ],
)
def test_bad_text_input_is_a_value_error_naming_file_line_and_value(tmp_path, content, kw, message):
    p = tmp_path / "bad.txt"
    p.write_text(content)
    with pytest.raises(ValueError, match=message) as err:
        gm.read(p, **kw)
    assert "bad.txt" in str(err.value)


def test_at2_with_a_missing_line_or_a_contradicting_dt_is_rejected(tmp_path):
    lines = record_path("landers").read_text().splitlines(keepends=True)
    p = tmp_path / "short.AT2"
    p.write_text("".join(lines[:-1]))
    with pytest.raises(ValueError, match=r"short.AT2, line 4: header declares NPTS = 9625 values but 9620"):
        gm.read(p)
    with pytest.raises(ValueError, match="the file says dt = 0.005"):
        gm.read(record_path("landers"), dt=0.01)
    bad_dt = lines.copy()
    bad_dt[3] = "NPTS=   9625, DT=   .0000 SEC,\n"
    p.write_text("".join(bad_dt))
    with pytest.raises(ValueError, match=r"short.AT2, line 4: time step dt = 0.0 s must be finite and > 0"):
        gm.read(p)
    lines[7] = lines[7].replace("E", "Q", 1)
    p.write_text("".join(lines))
    with pytest.raises(ValueError, match=r"line 8: value '.*Q.*' is not a number"):
        gm.read(p)


# --------------------------------------------------------------------------- Record
def test_record_is_frozen_and_its_samples_read_only():
    rec = gm.load("rinaldi")
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.dt = 0.02
    with pytest.raises(ValueError):
        rec.accel[0] = 1.0
    with pytest.raises(ValueError, match="dt must be a finite number > 0"):
        gm.Record("x", float("nan"), [0.0, 1.0])
    with pytest.raises(ValueError, match=r"accel\[1\] = nan is not finite"):
        gm.Record("x", 0.01, [0.0, np.nan])


def test_records_pickle_read_only_and_loaded_metadata_is_not_shared():
    rec = gm.load("rinaldi")
    back = pickle.loads(pickle.dumps(rec))
    np.testing.assert_array_equal(back.accel, rec.accel)
    assert not back.accel.flags.writeable and back.meta == rec.meta and back.dt == rec.dt
    rec.meta["note"] = "changed by a caller"
    assert "note" not in gm.load("rinaldi").meta


def test_record_helpers_time_duration_scaled_and_leading_zero():
    rec = gm.load("rinaldi")
    assert rec.time[-1] == pytest.approx(rec.duration) == pytest.approx(19.9)
    assert rec.scaled(2.0).pga == pytest.approx(2 * rec.pga)
    assert rec.scaled(2.0).scaled(0.5).meta["scale_factor"] == 1.0
    z = rec.with_leading_zero()
    assert rec.accel[0] != 0 and z.accel[0] == 0.0 and z.npts == rec.npts + 1
    np.testing.assert_array_equal(z.accel[1:], rec.accel)
    assert z.with_leading_zero() is z


@settings(deadline=None, max_examples=25)
@given(k=st.integers(1, 5), n=st.integers(2, 60), seed=st.integers(0, 2**31 - 1))
def test_resampling_a_piecewise_linear_signal_on_a_finer_grid_keeps_every_old_sample(k, n, seed):
    """Linear interpolation onto dt/k reproduces the original samples and the segment midpoints."""
    a = np.random.default_rng(seed).normal(size=n)
    rec = gm.Record("r", 0.02, a)
    fine = rec.resampled(0.02 / k)
    assert fine.npts == (n - 1) * k + 1
    np.testing.assert_allclose(fine.accel[::k], a, atol=1e-12)
    np.testing.assert_allclose(fine.resampled(0.02).accel, a, atol=1e-12)


# --------------------------------------------------------------------------- package data
def test_bundled_files_are_byte_copies_of_the_shared_set_and_covered_by_package_data():
    files = sorted(p for p in RECORDS.iterdir() if p.suffix not in (".py", ".md") and p.is_file())
    files = [p for p in files if not p.name.startswith(".") and p.name != "__pycache__"]
    assert len(files) == 11
    pyproject = tomllib.loads((Path(gm.__file__).parents[1] / "pyproject.toml").read_text())
    globs = pyproject["tool"]["setuptools"]["package-data"]["*"]
    source = shared("data", "ground_motions")
    for p in files + [RECORDS / "PROVENANCE.md"]:
        assert any(fnmatch.fnmatchcase(p.name, g) for g in globs), p.name
        if p.suffix != ".md":
            assert p.read_bytes() == (source / p.name).read_bytes(), p.name


def test_uncorrected_ridgecrest_drifts_metres_and_the_correction_removes_it():
    """Integrating the raw V1 record gives a displacement that grows like t^2 (offset in g); the
    baseline-corrected record ends at rest (within 1 mm and 1 mm/s)."""
    raw = gm.load("ridgecrest", corrected=False)
    cor = gm.load("ridgecrest")
    _, d_raw = gm.integrate(raw.accel - raw.accel[:1000].mean(), raw.dt)  # demeaned only
    v_cor, d_cor = gm.integrate(cor.accel, cor.dt)
    assert abs(d_raw[-1]) > 10.0  # about 14.6 m of spurious drift
    assert abs(d_cor[-1]) < 1e-3 and abs(v_cor[-1]) < 1e-3
    assert np.max(np.abs(d_cor)) < 0.5  # a plausible peak displacement for a 0.57 g record
    assert cor.meta["baseline"]["highpass_hz"] == 0.05


@settings(deadline=None, max_examples=25)
@given(
    coeffs=st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=2),
    seed=st.integers(0, 2**31 - 1),
)
def test_an_offset_and_a_linear_drift_in_acceleration_are_removed_exactly(coeffs, seed):
    """An acceleration baseline c0 + c1 t is piecewise linear, so its trapezoidal double integral
    is exactly c0 t^2/2 + c1 t^3/6, inside the fitted space t^2..t^order: the correction returns
    what it returns without the baseline (demean and polynomial steps; no taper or filter).
    (Higher-degree baselines are removed only up to the O(dt^2) trapezoid error.)"""
    rng = np.random.default_rng(seed)
    n, dt, order = 800, 0.01, 6
    t = np.arange(n) * dt
    signal = rng.normal(size=n)
    baseline = np.polynomial.polynomial.polyval(t / t[-1], coeffs)
    kw = {"order": order, "highpass": None, "taper": 0.0}
    clean = gm.baseline_correct(gm.Record("s", dt, signal), **kw).accel
    dirty = gm.baseline_correct(gm.Record("s", dt, signal + baseline), **kw).accel
    np.testing.assert_allclose(dirty, clean, atol=1e-9 * (1 + np.max(np.abs(baseline))))
    zero = gm.baseline_correct(gm.Record("b", dt, baseline), **kw).accel
    np.testing.assert_allclose(zero, 0.0, atol=1e-9 * (1 + np.max(np.abs(baseline))))


@settings(deadline=None, max_examples=25)
@given(
    values=st.lists(st.floats(-50.0, 50.0, allow_subnormal=False), min_size=2, max_size=200),
    dt=st.sampled_from([0.001, 0.004, 0.005, 0.01, 0.02]),
    units=st.sampled_from(["g", "mps2", "cmps2"]),
)
def test_csv_and_text_written_with_repr_read_back_exactly(tmp_path_factory, values, dt, units):
    d = tmp_path_factory.mktemp("rt")
    a = np.array(values)
    rows = "\n".join(f"{i * dt!r},{x!r}" for i, x in enumerate(values))
    (d / "r.csv").write_text(f"time_s,accel_{units}\n{rows}\n")
    (d / "r.txt").write_text("\n".join(repr(x) for x in values))  # no newline after the last value
    factor = {"g": G, "mps2": 1.0, "cmps2": 0.01}[units]
    rec_csv = gm.read(d / "r.csv")
    rec_txt = gm.read(d / "r.txt", dt=dt, units={"g": "g", "mps2": "m/s^2", "cmps2": "cm/s^2"}[units])
    for rec in (rec_csv, rec_txt):
        assert rec.npts == a.size and rec.dt == pytest.approx(dt, rel=1e-9)
        np.testing.assert_array_equal(rec.accel, a * factor)
