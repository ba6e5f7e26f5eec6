"""`rrfrei propagate --bidirectional`, run as a user runs it (subprocesses).

* on two bundled pairs with a few posterior draws and bounds, the command writes the tables the API
  computes (the nominal rows are :func:`structures.propagation.plan_propagate.propagate_pairs`' table), the
  code's answers with one row per bound and pair plus the design rows, and one orbit plot per pair;
* a record with one component, a single file, a law without a plan form and --bounds without
  --bidirectional are one-line user errors (exit 2) that say what to give instead.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from structures.propagation.plan_propagate import propagate_pairs

ROOT = Path(__file__).resolve().parents[1]
RRFREI = [sys.executable, "-m", "rrfrei.app", "propagate"]
ENV = {**os.environ, "MPLBACKEND": "Agg"}


def _run(argv, cwd=ROOT):
    return subprocess.run([*RRFREI, *argv], capture_output=True, text=True, cwd=cwd, env=ENV)


@pytest.fixture(scope="module")
def posterior(tmp_path_factory):
    """A short (not converged, on purpose) plasticity calibration: the three-story example's law."""
    import warnings

    from rrfrei.calibration import calibrate
    from rrfrei.io import load_test

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(load_test("protocol1"), "plasticity", steps=20, walkers=32, progress=False, seed=0)
    return cal.to_netcdf(tmp_path_factory.mktemp("plan_cli") / "posterior.nc")


def test_bundled_pairs_give_the_answers_tables_and_orbits(posterior, tmp_path):
    out = tmp_path / "out"
    proc = _run(["--posterior", str(posterior), "--building", "three_story",
                 "--records", "santamonica,ferndale", "--bidirectional", "--bounds", "0.85,1.15",
                 "--samples", "3", "--seed", "2", "--out", str(out), "--json", "--no-progress"])
    assert proc.returncode == 0, proc.stderr[-3000:]
    body = json.loads(proc.stdout)
    des = body["bidirectional"]["design_answers"]
    assert des["pairs"] == ["santamonica", "ferndale"] and des["rule"] == "maximum"
    gov = des["design"]["governing"]
    assert gov["plan_disp_max_m"] >= max(gov["disp_x_max_m"], gov["disp_y_max_m"])
    assert gov["plan_disp_max_m"] == pytest.approx(max(des["design"][b]["plan_disp_max_m"]
                                                       for b in ("nominal", "lower", "upper")))
    for name in ("responses.parquet", "summary.csv", "design_answers.csv", "design_draws.csv",
                 "design_distribution.csv", "orbit_santamonica.png", "orbit_ferndale.png",
                 "distribution_iso_disp_peak_m.png"):
        assert (out / name).stat().st_size > 0, name
    answers = pd.read_csv(out / "design_answers.csv")
    assert len(answers) == 3 * 2 + 4  # (nominal, lower, upper) x 2 pairs + 3 bounds and the governing row
    table = pd.read_parquet(out / "responses.parquet")
    assert set(table["bound"]) == {"nominal", "lower", "upper"} and len(table) == 3 * 2 * 3
    draws = pd.read_csv(out / "design_draws.csv")
    assert len(draws) == 3 * 3 and (draws["rule"] == "maximum").all()
    api = propagate_pairs(posterior, "three_story", ["santamonica", "ferndale"], n_samples=3, seed=2,
                          progress=False)
    nominal = table[table["bound"] == "nominal"].drop(columns="bound").reset_index(drop=True)
    pd.testing.assert_frame_equal(nominal, api.table)


@pytest.mark.parametrize("records, extra, words", [
    ("elcentro", [], ["one horizontal component", "santamonica"]),
    ("some_dir/RSN1_H1.AT2", [], ["one file", "'+'"]),
    ("santamonica", ["--bounds", "1.2,1.3"], ["bounds must be LMIN,LMAX"]),
])
def test_records_that_are_not_pairs_are_one_line_errors(tmp_path, records, extra, words):
    proc = _run(["--posterior", str(tmp_path / "p.nc"), "--building", "three_story", "--records", records,
                 "--bidirectional", *extra, "--out", str(tmp_path / "o")])
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    for w in words:
        assert w in proc.stderr


def test_a_law_without_a_plan_form_and_bounds_without_pairs_are_refused(tmp_path):
    toml = tmp_path / "b.toml"
    text = (ROOT / "structures" / "building" / "buildings" / "three_story.toml").read_text()
    toml.write_text(text.replace('law = "plasticity"', 'law = "plasticity+rate"') + "rate_c = 0.1\n")
    proc = _run(["--posterior", str(tmp_path / "p.nc"), "--building", str(toml), "--records", "santamonica",
                 "--bidirectional", "--out", str(tmp_path / "o")])
    assert proc.returncode == 2 and "no coupled bidirectional form" in proc.stderr, proc.stderr
    assert "plasticity, bouc_wen" in proc.stderr
    proc = _run(["--posterior", str(tmp_path / "p.nc"), "--building", "three_story", "--records", "elcentro",
                 "--bounds", "0.85,1.15", "--out", str(tmp_path / "o")])
    assert proc.returncode == 2 and "need --bidirectional" in proc.stderr, proc.stderr


def test_asce7_scaling_scales_each_pair_by_its_factor_before_the_runs(posterior, tmp_path):
    """--asce7: the pairs are scaled per 17.3.3 first (one factor per pair, the API's), then run."""
    import warnings

    import ground_motions as gm

    out = tmp_path / "out"
    proc = _run(["--posterior", str(posterior), "--building", "three_story",
                 "--records", "santamonica,ferndale", "--bidirectional", "--asce7", "1.0,0.6,8,1.2,1.8",
                 "--samples", "2", "--out", str(out), "--no-progress"])
    assert proc.returncode == 0, proc.stderr[-3000:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        suite = gm.scale_pairs_asce7([gm.load_pair("santamonica"), gm.load_pair("ferndale")],
                                     gm.mcer_target(1.0, 0.6, 8.0), 1.2, 1.8)
    scaling = pd.read_csv(out / "asce7_scaling.csv")
    assert list(scaling["pair"]) == ["santamonica", "ferndale"]
    pd.testing.assert_series_equal(scaling["factor"], pd.Series(suite.factors, name="factor"), rtol=1e-12)
    assert "fewer than 7 pairs" in (out / "asce7_scaling.txt").read_text()
    assert (out / "asce7_scaling.png").stat().st_size > 0
    table = pd.read_parquet(out / "responses.parquet").drop(columns="bound")
    api = propagate_pairs(posterior, "three_story", suite.pairs, n_samples=2, progress=False)
    pd.testing.assert_frame_equal(table, api.table)
    proc = _run(["--posterior", str(posterior), "--building", "three_story", "--records", "elcentro",
                 "--asce7", "1.0,0.6,8,1.2,1.8", "--out", str(tmp_path / "o")])
    assert proc.returncode == 2 and "need --bidirectional" in proc.stderr, proc.stderr
