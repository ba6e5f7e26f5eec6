"""``rrfrei shake-table`` and its pipeline (structures.shake_table.gap): the JSON it prints, its exit
codes, and the two mechanisms it adds (a law's state carried from run to run, a building driven by
the runs one after the other).

The CLI runs on a reduced split of the bundled BNCS runs: 60 s windows of ICA50 (calibration) and
ICA100 (held out), written as CSV runs, the law fitted at 10 Hz, one effect, 8 draws.

The issue's test "the force derived from a simulated run equals the isolator force the
simulation used" is ``test_force_from_a_simulated_run_is_the_isolator_force_the_simulation_used``
in ``tests/test_shake_table.py``.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import numpy as np
import pytest

import ground_motions
import structures
from rrfrei.app import cli
from rrfrei.io import ShearTest, concat_tests
from rrfrei.laws import get
from structures.building.shear_building import Isolator, ShearBuilding
from structures.shake_table import BNCS_WEIGHTS_KN, ShakeTableRun, write_run
from structures.shake_table import gap as stg
from structures.shake_table.gap import simulate_law
from structures.shake_table.sequence import CHANNELS, predict_sequence

KEYS = {"law", "diagnosis", "verdict", "evidence", "combination", "where", "ranking", "extrapolation",
        "gap_before", "gap_after", "coverage", "band_width", "runs", "loop_fit", "calibration", "shrink"}


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    """Two reduced runs as CSV files (60 s of ICA50 and of ICA100) and a folder for reports."""
    root = tmp_path_factory.mktemp("shake")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = replace(structures.load_run("ICA50").window(40.0, 100.0), name="ICA50w")
        b = replace(structures.load_run("ICA100").window(45.0, 105.0), name="ICA100w")
    write_run(a, root / "ICA50w.csv.gz")
    write_run(b, root / "ICA100w.csv.gz")
    return root, a, b


def _argv(root, *extra):
    return ["shake-table", str(root / "ICA50w.csv.gz"), str(root / "ICA100w.csv.gz"), "--calibrate", "ICA50w",
            "--holdout", "ICA100w", "--law", "plasticity", "--effects", "rollover", "isolation_damping",
            "--rate", "10", "--draws", "8", "--no-progress", "--time-budget", "none", *extra]


@pytest.fixture(scope="module")
def cli_json(split):
    root, a, b = split
    out = root / "report"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = cli.main(_argv(root, "--out", str(out), "--json"))
    return code, buf.getvalue(), out


def test_json_is_one_object_with_the_issue_keys_and_per_channel_gaps(cli_json):
    code, stdout, out = cli_json
    assert code == 0
    data = json.loads(stdout)  # one object: json.loads rejects trailing text
    assert KEYS <= set(data)
    assert data["law"] == "plasticity"
    for key in ("gap_before", "gap_after"):
        assert set(data[key]) == {"calibration", "holdout"}
        for part in ("calibration", "holdout"):
            assert set(data[key][part]) == set(CHANNELS)
            assert all(v is not None and v >= 0 for v in data[key][part].values())
    assert set(data["coverage"]) == set(CHANNELS)
    assert all(0.0 <= v <= 1.0 for v in data["coverage"].values())
    assert all(v > 0 for v in data["band_width"].values())
    assert [r["effect"] for r in data["ranking"]] == ["rollover", "isolation_damping"] or \
        [r["effect"] for r in data["ranking"]] == ["isolation_damping", "rollover"]
    assert data["where"] and {"axis", "segment", "run", "channel", "error_share"} <= set(data["where"][0])
    assert {r["axis"] for r in data["where"]} == {"channel", "amplitude", "frequency", "time window"}
    # the baseline and every ranked candidate run through the building
    assert [r["effect"] for r in data["building_check"]][0] == "baseline"
    assert len(data["building_check"]) == 3
    assert set(CHANNELS) <= set(data["building_check"][0])
    best = min(data["building_check"], key=lambda r: r["isolator_disp"])
    assert data["building_best"]["effect"] == best["effect"]
    assert data["building_best"]["shrink"] == pytest.approx(
        1 - best["isolator_disp"] / data["building_check"][0]["isolator_disp"])


def test_verdict_is_the_one_answer_and_every_run_has_its_channel_metrics(cli_json):
    """``diagnosis`` and ``verdict`` say the same thing (one name, one meaning); ``runs`` holds, for
    every calibration and held-out run, each channel's NRMSE, peak error, band coverage and width."""
    _, stdout, _ = cli_json
    data = json.loads(stdout)
    assert data["diagnosis"] == data["verdict"]
    assert data["verdict"] in ("none", "unexplained", "incomplete", "rollover", "isolation_damping")
    assert set(data["runs"]) == {"ICA50w", "ICA100w"}
    for chans in data["runs"].values():
        assert set(chans) == set(CHANNELS)
        for m in chans.values():
            assert set(m) == {"nrmse", "peak_error", "coverage", "coverage_low", "coverage_high",
                              "band_width"}
            assert m["nrmse"] >= 0 and 0 <= m["coverage"] <= 1 and m["band_width"] > 0
            assert 0 <= m["coverage_low"] <= m["coverage_high"] <= 1
    # the pooled held-out numbers are those of the one held-out run
    for c in CHANNELS:
        assert data["coverage"][c] == pytest.approx(data["runs"]["ICA100w"][c]["coverage"])
        assert data["coverage_interval"][c] == pytest.approx([data["runs"]["ICA100w"][c]["coverage_low"],
                                                              data["runs"]["ICA100w"][c]["coverage_high"]])
        assert data["gap_after"]["holdout"][c] == pytest.approx(data["runs"]["ICA100w"][c]["nrmse"])
    # the building is calibrated by output error; the loop fit is the comparison row
    assert data["calibration"]["method"].startswith("output error")
    assert {"k_scale", "zeta", "k_init", "qd"} <= set(data["calibration"]["params"])
    assert data["calibration"]["importance_ess"] >= 1
    assert set(data["loop_fit"]["holdout"]) == set(CHANNELS)


def test_extrapolation_is_the_held_out_peak_over_the_calibrated_peak(cli_json, split):
    _, stdout, _ = cli_json
    _, a, b = split
    ratio = json.loads(stdout)["extrapolation"]["ICA100w"]
    # the law is fitted on the 10 Hz isolation test; its peak is within the anti-alias filter's reach
    expected = np.max(np.abs(b.isolator_disp)) / np.max(np.abs(a.isolator_disp))
    assert ratio == pytest.approx(expected, rel=0.03)
    assert ratio > 1.5  # ICA100 goes well beyond ICA50


def test_the_report_has_its_figures_and_gap_table(cli_json):
    _, _, out = cli_json
    md = (out / "shake_table.md").read_text()
    for name in ("loops_ICA100w.png", "isolator_disp_ICA100w.png", "roof_accel_ICA100w.png"):
        assert (out / name).stat().st_size > 0
        assert f"]({name})" in md
    assert "| isolator_disp |" in md and "Diagnosis" in md


@pytest.mark.parametrize("extra, words", [
    (["--law", "no_such_law"], "no_such_law"),
    (["--calibrate", "ICA50w,ICA100w"], "both calibrated on and held out"),
    (["--holdout", "NOPE"], "NOPE"),
    (["--rate", "7"], "rate_hz = 7"),
])
def test_user_errors_exit_2_with_one_line(split, capsys, extra, words):
    root, _, _ = split
    code = cli.main([*_argv(root, "--out", str(root / "err")), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "\n" not in err and words in err, err


def test_an_unknown_run_exits_2_naming_it(capsys, tmp_path):
    code = cli.main(["shake-table", "ICA50", "NO_SUCH_RUN", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "NO_SUCH_RUN" in err and "\n" not in err


def test_a_calibration_run_without_a_superstructure_exits_2_before_any_isolator_fit(split, capsys,
                                                                                    monkeypatch):
    """The superstructure is identified first: a run where it cannot be (here a 25 Hz copy, too
    slow for its 1-15 Hz band) is reported in seconds, not after minutes of isolator fits."""
    root, a, _ = split
    slow = replace(a.decimate(25.0), name="ICA50slow")
    write_run(slow, root / "ICA50slow.csv.gz")

    def no_fit(*args, **kw):
        raise AssertionError("an isolator was fitted before the superstructure was checked")

    monkeypatch.setattr(stg, "_pick_law", no_fit)
    monkeypatch.setattr(stg, "_loop_fit", no_fit)
    monkeypatch.setattr(stg, "diagnose", no_fit)
    code = cli.main(["shake-table", str(root / "ICA50slow.csv.gz"), "--calibrate", "ICA50slow",
                     "--holdout", "", "--rate", "25", "--no-progress", "--out", str(root / "slow")])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert "superstructure not identified on ICA50slow" in err and "--building" in err


def test_every_building_analysis_failing_exits_1_and_says_what_and_where(split, capsys, monkeypatch):
    from structures.shake_table import building_model

    root, _, _ = split

    def diverges(*args, **kw):
        return -4, {}

    monkeypatch.setattr(building_model, "simulate", diverges)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = cli.main(_argv(root, "--out", str(root / "fail")))
    err = capsys.readouterr().err.strip()
    assert code == 1, err
    assert "numerical failure" in err and "plasticity" in err and "ICA50w" in err


# ---------------------------------------------------------------------------------------------
# state carried from run to run
# ---------------------------------------------------------------------------------------------
def _cycles(amp: float, n: int = 400, name: str = "t") -> ShearTest:
    t = np.linspace(0.0, 20.0, n)
    return ShearTest(name, t, amp * np.sin(2 * np.pi * 0.25 * t) * np.minimum(1.0, t / 4.0), np.zeros(n))


def test_a_held_out_test_is_predicted_from_the_state_the_preceding_runs_left():
    spec = get("plasticity+degradation")
    p = spec.pack({"k_init": 5000.0, "qd": 100.0, "alpha1": 0.1, "alpha2": 0.0, "mu": 2.0,
                   "deg_rate": 0.05, "deg_travel": 0.0})
    first, second = _cycles(0.2, name="first"), _cycles(0.1, name="second")
    carried = second.after(first)
    st, f_joined = simulate_law(spec, p, concat_tests([first, second]))
    st2, f_virgin = simulate_law(spec, p, second)
    st3, f_carried = simulate_law(spec, p, carried)
    assert st == st2 == st3 == 0
    tail = f_joined[len(first):]
    np.testing.assert_array_equal(f_carried, tail)
    # the degraded bearing carries less force than a virgin one on the same displacements
    assert np.max(np.abs(tail)) < 0.9 * np.max(np.abs(f_virgin))
    fit = _fake_fit(spec, p)
    np.testing.assert_allclose(fit.predict(carried).mean, tail, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.predict(second).mean, f_virgin, rtol=0, atol=1e-9)


def _fake_fit(spec, p):
    from rrfrei.gap.model import IsolatorFit

    P = np.repeat(p[None, :], 10, axis=0)
    return IsolatorFit(spec=spec, p_opt=p, P=P, sig=np.full(10, 1.0), sigma=1.0, noise=1.0,
                       free=spec.param_names)


# ---------------------------------------------------------------------------------------------
# the building driven by the runs in order
# ---------------------------------------------------------------------------------------------
MASSES = np.array(BNCS_WEIGHTS_KN) / 9.81
K = np.array([125e3, 95e3, 98e3, 108e3, 60e3])
PL = dict(k_init=20000.0, qd=80.0, alpha1=0.15, alpha2=0.0, mu=2.0)


def test_the_building_driven_by_the_runs_in_order_reproduces_one_simulation_of_them():
    """Two runs cut from ONE simulation of (record 1, 10 s rest, record 2): predicting them in order
    with the true isolator must give back every channel, displacements from each run's start."""
    b = ShearBuilding(MASSES[1:], K, [4.27] * 5, 0.04, MASSES[0], Isolator("plasticity", PL))
    r = ground_motions.load("elcentro")
    n, dt = int(15.0 / r.dt), r.dt
    a1 = np.asarray(r.accel[:n])
    a2 = 1.5 * np.asarray(r.accel[n:2 * n])
    pad = int(round(10.0 / dt))
    rec = ground_motions.Record("both", dt, np.concatenate([[0.0], a1, np.zeros(pad), a2]))
    resp = structures.time_history(b, rec)
    runs = []
    for name, start, acc in (("one", 1, a1), ("two", 1 + n + pad, a2)):
        s = slice(start, start + n)
        u0 = resp.isolator_disp[start - 1]
        f0 = resp.floor_disp[start - 1]
        runs.append(ShakeTableRun(
            name=name, time=np.arange(n) * dt, table_accel=acc,
            accel=np.column_stack([resp.base_accel_abs[s], resp.floor_accel_abs[s]]),
            disp=np.column_stack([resp.isolator_disp[s] - u0, resp.floor_disp[s] - f0]),
            masses=MASSES, level_names=("base", "f2", "f3", "f4", "f5", "roof")))
    pred = predict_sequence(b, b.isolator.packed()[None, :].repeat(2, axis=0), runs)
    assert pred.n_failed == 0
    for run in ("one", "two"):
        for c in CHANNELS:
            scale = np.max(np.abs(pred.measured[run][c]))
            np.testing.assert_allclose(pred.median[run][c], pred.measured[run][c], rtol=0, atol=1e-6 * scale,
                                       err_msg=f"{run} {c}")
    assert pred.nrmse(["one", "two"])["isolator_disp"] < 1e-6
    assert pred.coverage(["two"], {c: 1e-9 for c in CHANNELS})["roof_accel"] > 0.99


def test_a_rerun_with_the_same_out_reuses_the_fits_and_gives_the_same_numbers(cli_json, split):
    import contextlib
    import io

    root, _, _ = split
    code, first, out = cli_json
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(_argv(root, "--out", str(out), "--json")) == 0
    a, b = json.loads(first), json.loads(buf.getvalue())
    assert any("reused" in n for n in b["notes"]) and not any("reused" in n for n in a["notes"])
    assert b["gap_before"] == a["gap_before"] and b["gap_after"] == a["gap_after"]


def test_the_default_law_is_the_best_leave_one_cycle_out_elpd_of_the_opensees_laws(split, capsys):
    root, _, _ = split
    argv = [a if a != "plasticity" else "auto" for a in _argv(root, "--out", str(root / "auto"), "--json")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    scores = {r["law"]: r["loco_elpd"] for r in data["law_scores"]}
    assert set(scores) == set(stg.AUTO_LAWS)
    assert data["law"] == max(scores, key=scores.get)
    # the chosen law's loop fit is the start of the output-error calibration and the comparison row
    assert data["loop_fit"]["law"] == data["law"]
