"""``rrfrei gap`` answers in the engineer's quantities (issue 12 point 5): the JSON and the report
carry k_eff, beta_eff, Qd, F(DD), F(DM) per test before/after, the ASCE 7-22 17.2.8.4 lambdas and
the five-story building at its bounds; ``--every`` and ``--carry`` do what they say."""

import json
import subprocess
import sys

import pytest


@pytest.fixture(scope="module")
def gap_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("gap")
    cmd = [sys.executable, "-m", "rrfrei.app", "gap", "protocol1", "--law", "plasticity",
           "--holdout", "protocol2", "protocol3", "--effects", "degradation", "--every", "2",
           "--carry", "--building-records", "2", "--out", str(out), "--json", "--no-progress"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout), out


def test_the_json_gives_each_test_its_design_quantities_measured_before_and_after(gap_run):
    data, _ = gap_run
    tests = data["design"]["tests"]
    assert set(tests) == {"protocol1[::2]", "protocol2[::2]", "protocol3[::2]"}  # --every 2, named
    for q in ("k_eff", "beta_eff", "edc", "qd", "f_dd", "f_dm"):
        row = tests["protocol1[::2]"][q]
        assert {"measured", "before", "after", "rel_err_before", "rel_err_after", "unit"} <= set(row)
    k = tests["protocol1[::2]"]["k_eff"]
    assert k["unit"] == "kN/m" and k["measured"] > 0 and k["before"] > 0
    # the relative error is what it says: (predicted - measured) / measured
    assert k["rel_err_before"] == pytest.approx((k["before"] - k["measured"]) / k["measured"])


def test_the_lambdas_bracket_one_and_the_building_runs_at_both_bounds(gap_run):
    data, out = gap_run
    pm = data["design"]["lambdas_measured"]
    for p in ("k_eff", "qd", "edc"):
        assert 0 < pm["lambda_min"][p] <= 1 <= pm["lambda_max"][p]
        assert pm["lower"][p] <= pm["nominal"][p] <= pm["upper"][p]
    rows = data["building"]
    assert {r["bound"] for r in rows} == {"lower", "nominal", "upper"}
    nominal = next(r for r in rows if r["bound"] == "nominal" and r["effect"] == "none")
    assert nominal["lambda"] == 1.0 and nominal["iso_disp_peak_m"] > 0 and nominal["base_shear_peak_kN"] > 0
    md = (out / "report.md").read_text()
    assert "## In design quantities" in md and "17.2.8.4" in md
    assert (out / "design_gap.png").stat().st_size > 0 and (out / "consequences.png").stat().st_size > 0


def test_bad_every_and_building_records_are_user_errors(tmp_path):
    for extra in (["--every", "0"], ["--building-records", "12"]):
        proc = subprocess.run([sys.executable, "-m", "rrfrei.app", "gap", "protocol1", "--out",
                               str(tmp_path), *extra], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2, proc.stderr
        assert extra[0] in proc.stderr
