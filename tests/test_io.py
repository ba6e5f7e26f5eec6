"""Reading shear tests: units come from column names (or are given), errors name file, column, row."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _shared import shared
from hypothesis import given, settings
from hypothesis import strategies as st

import rrfrei
from rrfrei.io import DISP_UNITS, FORCE_UNITS, ShearTest, load_test, read_test

TIMBER_PARTS = ("data", "hysteresis", "clt_connection_tannert_spc1", "SPC1.csv")


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_bundled_protocol1_is_the_shared_file_in_SI_units():
    """load_test converts mm to m and keeps kN and s; geometry and vertical load come from the sidecar."""
    t = load_test("protocol1")
    raw = pd.read_csv(Path(rrfrei.__file__).parent / "data" / "isolator_synthetic" / "protocol1.csv")
    assert len(t) == 2401 == len(raw)
    np.testing.assert_array_equal(t.disp, raw["disp_mm"].to_numpy() * 1e-3)
    np.testing.assert_array_equal(t.force, raw["force_kN"].to_numpy())
    np.testing.assert_array_equal(t.time, raw["time_s"].to_numpy())
    assert t.has_time
    assert t.geometry == {"d2": 0.080, "tr": 0.002, "n": 15.0}
    assert t.vertical_load == pytest.approx(19.25)
    assert t.disp_range == pytest.approx((-0.030, 0.030))


@pytest.mark.parametrize("name", ["protocol1", "protocol2", "protocol3", "protocol4"])
def test_every_bundled_test_loads_with_its_documented_length(name):
    expected = {"protocol1": 2401, "protocol2": 1441, "protocol3": 1681, "protocol4": 601}
    assert len(load_test(name)) == expected[name]


def test_unknown_bundled_name_lists_the_available_ones():
    with pytest.raises(ValueError, match="protocol1"):
        load_test("protocol9")


def test_timber_file_force_first_with_a_units_row_reads_by_naming_columns():
    """Real lab file: force FIRST, second header row 'kN,mm', no time -> pseudo-time, has_time False."""
    TIMBER = shared(*TIMBER_PARTS)
    t = read_test(TIMBER, disp_col="Lead Actuator Displacment", force_col="Lead Actuator Force")
    raw = pd.read_csv(TIMBER, skiprows=[1])
    assert len(t) == 33028 == len(raw)
    np.testing.assert_allclose(t.disp, raw.iloc[:, 1].to_numpy() * 1e-3)  # mm -> m
    np.testing.assert_allclose(t.force, raw.iloc[:, 0].to_numpy())  # kN
    assert not t.has_time
    np.testing.assert_array_equal(t.time, np.arange(len(t)))


def test_columns_by_position_with_explicit_units(tmp_path):
    rows = "\n".join(f"{0.5 * i},{i % 7}" for i in range(20))
    p = _write(tmp_path / "raw.csv", "a,b\n" + rows + "\n")
    t = read_test(p, disp_col=1, force_col=0, disp_unit="in", force_unit="kip")
    np.testing.assert_allclose(t.disp, np.arange(20) % 7 * 0.0254)
    np.testing.assert_allclose(t.force, 0.5 * np.arange(20) * 4.4482216152605)


@settings(deadline=None, max_examples=25)
@given(du=st.sampled_from(sorted(DISP_UNITS)), fu=st.sampled_from(["N", "kN", "MN", "lbf", "kip"]),
       scale=st.floats(0.1, 100.0))
def test_unit_suffixes_convert_to_metres_and_kilonewtons(tmp_path_factory, du, fu, scale):
    """Whatever the suffix, the values in SI-kN equal the file's values times the unit factor."""
    u = scale * np.sin(np.linspace(0, 6, 30))
    f = 3 * u + 1.0
    p = tmp_path_factory.mktemp("u") / "t.csv"
    pd.DataFrame({"time_s": np.arange(30) * 0.1, f"disp_{du}": u, f"force_{fu}": f}).to_csv(p, index=False)
    t = read_test(p)
    np.testing.assert_allclose(t.disp, u * DISP_UNITS[du], rtol=1e-12)
    np.testing.assert_allclose(t.force, f * FORCE_UNITS[fu.lower()], rtol=1e-12)


def test_vertical_load_column_is_read_in_kN(tmp_path):
    df = pd.DataFrame({"time_s": np.arange(12.0), "disp_mm": np.arange(12.0), "force_N": np.ones(12),
                       "vertical_kN": np.full(12, 19.25)})
    df.to_csv(tmp_path / "v.csv", index=False)
    assert read_test(tmp_path / "v.csv").vertical_load == pytest.approx(19.25)


def test_sidecar_toml_gives_geometry_and_geometry_argument_overrides(tmp_path):
    pd.DataFrame({"time_s": np.arange(12.0), "disp_mm": np.arange(12.0), "force_kN": np.ones(12)}).to_csv(
        tmp_path / "s.csv", index=False)
    _write(tmp_path / "s.csv.toml", "vertical_load_kN = 5.0\n[geometry]\ndiameter = 0.1\ntr = 0.003\nn = 4\n")
    t = read_test(tmp_path / "s.csv")
    assert t.geometry == {"d2": 0.1, "tr": 0.003, "n": 4.0}  # 'diameter' is an alias of d2
    assert t.vertical_load == 5.0
    assert read_test(tmp_path / "s.csv", geometry={"d2": 0.2}).geometry == {"d2": 0.2}


@pytest.mark.parametrize(
    "text, match",
    [
        ("time_s,disp_mm,force_kN\n" + "0,0,0\n" * 3 + "0.2,abc,1\n" + "0.3,1,1\n" * 8,
         r"row 5, column 'disp_mm'"),
        ("time_s,disp_mm,force_kN\n" + "".join(f"{i},{i},{'nan' if i == 6 else 1}\n" for i in range(12)),
         r"row 8, column 'force_kN'"),
        ("time_s,disp_mm,force_kN\n0,1,1\n1,2,2\n", "at least 10"),
        ("time_s,disp_mm,force_kN\n" + "".join(f"{i},3.0,1\n" for i in range(12)), "constant"),
        ("time_s,disp_furlong,force_kN\n" + "".join(f"{i},{i},1\n" for i in range(12)), "furlong"),
        ("t_s,x,force_kN\n" + "".join(f"{i},{i},1\n" for i in range(12)), "no disp column"),
        ("time_s,disp_mm,force_kN\n" + "".join(f"{i % 5},{i},1\n" for i in range(12)), "does not increase"),
    ],
    ids=["text", "nan", "short", "no-range", "unit", "no-disp", "time"],
)
def test_malformed_files_raise_naming_file_column_and_row(tmp_path, text, match):
    p = _write(tmp_path / "bad.csv", text)
    with pytest.raises(ValueError, match=match) as exc:
        read_test(p)
    assert "bad.csv" in str(exc.value)


def test_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_test(tmp_path / "nope.csv")


def test_shear_test_is_frozen_and_validates_in_memory_data():
    t = ShearTest("m", np.arange(12.0), np.linspace(0, 1, 12), np.zeros(12))
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.name = "x"
    with pytest.raises(ValueError):
        t.disp[0] = 1.0  # read-only arrays
    with pytest.raises(ValueError, match="not finite at sample 3"):
        ShearTest("m", np.arange(12.0), np.r_[0, 1, 2, np.inf, np.arange(8.0)], np.zeros(12))
