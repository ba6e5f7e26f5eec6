"""Honest signals on a user's first day (issue 29 items 2, 4, 5, 7; issue 28 item 7).

* a comparison runs the laws the test can run and says which it skipped and why, before any work;
* a fit's adequacy is NRMSE, its systematic part and coverage read together, in one sentence;
* parameters at a bound are named; the convergence rule is one function and one text;
* notes carry a severity, and the critical ones come first;
* help texts list what exists, messages write numbers as numbers and name the file they read.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from rrfrei.app.cli import main
from rrfrei.calibration.compare import runnable_laws
from rrfrei.calibration.priors import Prior
from rrfrei.calibration.quality import ADEQUATE, INADEQUATE, adequacy, at_bounds, bounds_text
from rrfrei.io import ShearTest, load_test
from rrfrei.laws import get
from rrfrei.notes import Note, as_dicts, label, ordered


def _loop(n=2000, seed=0):
    t = np.linspace(0.0, 20.0, n)
    u = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    return t, u, np.random.default_rng(seed)


# --- 29.2: compare --laws all on a test without geometry --------------------------------------
def test_a_test_without_geometry_runs_every_law_but_elastomeric_x_which_is_skipped_with_why():
    test = load_test("protocol1")
    test = ShearTest(test.name, test.time, test.disp, test.force)  # no geometry sidecar
    ok, skipped = runnable_laws(test, "all")
    assert "elastomeric_x" not in ok and len(ok) >= 3
    assert list(skipped) == ["elastomeric_x"]
    assert "needs the bearing geometry" in skipped["elastomeric_x"]
    # with the bundled geometry every law runs
    assert runnable_laws(load_test("protocol1"), "all")[1] == {}


def test_cli_compare_all_skips_the_law_up_front_and_compares_the_others(tmp_path, monkeypatch, capsys):
    """Before: about a minute of calibrations, then "law 'elastomeric_x' needs the bearing
    geometry ..." and exit 2.  After: a warning naming the skipped law, first, and the other laws
    calibrated (the calibrations are stubbed here: the test is about which laws run)."""
    import rrfrei.app.commands.compare as cmd

    src = load_test("protocol4")
    csv = tmp_path / "nogeo.csv"
    np.savetxt(csv, np.c_[src.time, 1e3 * src.disp, src.force], delimiter=",",
               header="time_s,disp_mm,force_kN", comments="")
    calibrated = []

    class Stop(Exception):
        pass

    def fake_calibrate(test, law, **kw):
        assert "skipped elastomeric_x" in capsys.readouterr().err  # said before any work
        calibrated.append(law)
        raise Stop

    monkeypatch.setattr(cmd, "calibrate", fake_calibrate)
    with pytest.raises(Stop):
        main(["compare", str(csv), "--out", str(tmp_path / "cmp"), "--no-progress"])
    assert calibrated and "elastomeric_x" not in calibrated


def test_cli_compare_with_fewer_than_two_runnable_laws_is_one_line_naming_the_skipped_one(tmp_path, capsys):
    src = load_test("protocol4")
    csv = tmp_path / "nogeo.csv"
    np.savetxt(csv, np.c_[src.time, 1e3 * src.disp, src.force], delimiter=",",
               header="time_s,disp_mm,force_kN", comments="")
    code = main(["compare", str(csv), "--laws", "plasticity,elastomeric_x", "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err
    assert code == 2 and "elastomeric_x" in err and "needs the bearing geometry" in err
    assert not (tmp_path / "c" / "posterior_plasticity.nc").exists()  # nothing was calibrated


# --- 29.4: adequacy -----------------------------------------------------------------------------
def test_a_pinched_test_fitted_by_a_smooth_loop_is_inadequate_whatever_the_coverage():
    """A band widened by a noise sd that absorbed the misfit covers ~96 % of the samples; the
    systematic part of the gap says the law misses the shape."""
    t, u, rng = _loop()
    pinched = 40.0 * np.sign(u) * np.abs(u / 0.05) ** 3 + rng.normal(0, 0.5, u.size)
    smooth = 400.0 * u
    a = adequacy(pinched, smooth, coverage=0.959)
    assert a.systematic > INADEQUATE and a.level == "inadequate"
    assert a.sentence.startswith("inadequate: NRMSE") and "coverage 95.9 %" in a.sentence
    assert "cannot reproduce this test's shape" in a.sentence


def test_a_fit_that_misses_only_noise_is_adequate_with_a_small_systematic_part():
    t, u, rng = _loop()
    model = 400.0 * u
    a = adequacy(model + rng.normal(0.0, 1.0, u.size), model, coverage=0.95)
    assert a.nrmse > 0.05 and a.systematic < ADEQUATE and a.level == "adequate"


def test_the_loop_plot_title_shows_nrmse_systematic_part_coverage_and_the_reading():
    from types import SimpleNamespace

    from rrfrei.calibration.plots import loop_title

    t, u, rng = _loop()
    pinched = 40.0 * np.sign(u) * np.abs(u / 0.05) ** 3
    pred = SimpleNamespace(law="bouc_wen", test=ShearTest("pinched", t, u, pinched), nrmse=0.45,
                           coverage=0.959, adequacy=adequacy(pinched, 400.0 * u, 0.959))
    title = loop_title(pred)
    assert "systematic" in title and "coverage 95.9 %" in title and "INADEQUATE" in title


# --- 29.4: parameters at a bound ----------------------------------------------------------------
def test_parameters_at_or_near_a_bound_are_named_with_value_and_side():
    spec = get("bouc_wen")
    names = ("k_init", "alpha2", "gamma", "eta")
    priors = {"k_init": Prior("loguniform", 10.0, 1e5), "alpha2": Prior("uniform", -1.0, 1.0),
              "gamma": Prior("uniform", -1.0, 1.0), "eta": Prior("uniform", 0.1, 10.0)}
    lower = [spec.param(n).lower for n in names]
    upper = [spec.param(n).upper for n in names]
    hits = at_bounds(spec, priors, names, [99_000.0, -1.0, 0.999, 2.0], lower, upper)
    assert [(h["name"], h["side"]) for h in hits] == [("k_init", "upper"), ("alpha2", "lower"),
                                                      ("gamma", "upper")]
    text = bounds_text(hits)
    assert "alpha2 = -1 at its lower bound -1" in text and "np.float64" not in text
    assert at_bounds(spec, priors, names, [3000.0, 0.0, 0.3, 2.0], lower, upper) == []


# --- 28.7 / 29.4: one convergence rule ----------------------------------------------------------
def test_the_stopping_check_is_the_final_check_on_the_stored_draws():
    """check() thins the chain as the stored draws are thinned, and its R-hat and ESS are arviz'
    on those draws: the run cannot stop as converged and then fail a second, different check."""
    import warnings

    import arviz as az

    from rrfrei.calibration.convergence import check, thinning

    rng = np.random.default_rng(3)
    n, m, k = 1200, 32, 3
    x = np.empty((n, m, k))
    x[0] = rng.standard_normal((m, k))
    for i in range(1, n):
        x[i] = 0.9 * x[i - 1] + rng.standard_normal((m, k))
    chk = check(x, max_draws=600)
    assert chk.thin == thinning(n, chk.burn, chk.tmax, m, 600)
    stored = x[chk.burn::chk.thin]
    assert stored.shape[0] * m == chk.draws <= 600
    ds = {f"p{j}": stored[:, :, j].T for j in range(k)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rhat = max(float(az.rhat(ds)[v]) for v in ds)
        ess = min(float(az.ess(ds, method="bulk")[v]) for v in ds)
    assert chk.rhat == pytest.approx(rhat, rel=1e-10) and chk.ess_bulk == pytest.approx(ess, rel=1e-10)


def test_the_convergence_rule_is_stated_once_and_quoted_by_the_help_and_the_advice(capsys):
    from rrfrei.calibration import CONVERGENCE_RULE, advice

    with pytest.raises(SystemExit):
        main(["calibrate", "--help"])
    helptext = " ".join(capsys.readouterr().out.split())
    assert " ".join(CONVERGENCE_RULE.split()) in helptext
    assert "R-hat < 1.04" not in helptext
    d = {"stopped_by": "converged", "steps": 800, "tau": {"a": 20.0}, "rhat_max": 1.06, "ess_min": 300}
    assert CONVERGENCE_RULE in advice(d)


@pytest.mark.parametrize("kw", [{"steps": 300}, {"max_steps": 300}])
def test_run_json_and_the_summary_tell_one_story_of_convergence(kw):
    """Before: run.json could say "stopped_by": "converged" with "converged": false (the run
    stopped on a rule over the whole chain, the final check on the thinned draws failed).  Now the
    flag is the rule on the stored draws, whose R-hat and ESS are the summary's."""
    import warnings

    from rrfrei.calibration import calibrate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(load_test("protocol4"), "plasticity", walkers=16, seed=1, progress=False, **kw)
    d = cal.diagnostics
    assert d["stopped_by"] != "converged" or d["converged"]
    assert d["rhat"] == pytest.approx(d["rhat_max"], rel=1e-9)  # the rule's number is the summary's
    assert d["ess_bulk"] == pytest.approx(d["ess_min"], rel=1e-9)
    draws_ok = d["rhat"] < 1.05 and min(d["ess_bulk"], d["ess_tail"]) >= 400
    assert d["converged"] <= draws_ok  # converged implies the stored draws pass
    assert isinstance(d["at_bounds"], list) and d["rule"]


# --- 29.5: notes with a severity ----------------------------------------------------------------
def test_notes_are_ordered_critical_first_and_keep_their_text():
    notes = [Note("reused 3 finished fits", "info"), "a plain note",
             Note("199 of 200 posterior draws failed", "critical"), Note("effect x skipped", "warning")]
    out = ordered(notes)
    assert [n.severity for n in out] == ["critical", "warning", "info", "info"]
    assert out[0] == "199 of 200 posterior draws failed" and isinstance(out[0], str)
    assert label(out[0]).startswith("CRITICAL: ")
    assert json.loads(json.dumps(as_dicts(notes)))[0] == {"severity": "critical",
                                                          "text": "199 of 200 posterior draws failed"}
    with pytest.raises(ValueError, match="severity 'loud'"):
        Note("x", "loud")


@pytest.mark.parametrize("n_ok,severity", [(1, "critical"), (15, "warning")])
def test_a_band_from_a_minority_of_the_draws_is_a_critical_note(n_ok, severity):
    from rrfrei.gap.model import IsolatorFit

    spec = get("plasticity")
    u = 0.05 * np.sin(np.linspace(0.0, 4.0 * np.pi, 400))
    test = ShearTest("held", np.arange(u.size) * 0.05, u, np.zeros(u.size))
    p_opt = np.array([1000.0, 10.0, 0.1, 0.0, 2.0])
    P = np.repeat(p_opt[None, :], 20, axis=0)
    P[n_ok:, 0] = np.nan
    fit = IsolatorFit(spec=spec, p_opt=p_opt, P=P, sig=np.full(20, 2.0), sigma=2.0, noise=2.0,
                      free=tuple(q.name for q in spec.params))
    fit.predict(test)
    (note,) = [n for n in fit.notes if "posterior draws failed" in n]
    assert note.severity == severity


# --- 29.7: help and messages --------------------------------------------------------------------
def test_gap_help_lists_every_catalogue_effect(capsys):
    from rrfrei.gap.catalogue import catalogue

    with pytest.raises(SystemExit):
        main(["gap", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    missing = [e for e in catalogue() if e not in out]
    assert len(catalogue()) >= 9 and missing == []


def test_every_rubber_option_has_a_help_text():
    import argparse

    from rubber.__main__ import _parser

    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    silent = [f"{cmd} {a.option_strings or a.dest}" for cmd, p in sub.choices.items()
              for a in p._actions if not a.help and not isinstance(a, argparse._HelpAction)]
    assert silent == []


def test_messages_write_numpy_scalars_as_plain_numbers(monkeypatch, capsys):
    import rrfrei.app.commands.compare as cmd
    from rrfrei._text import plain_numbers

    assert plain_numbers(f"x = {np.float64(-674.0)!r}, {[np.int64(3)]}") == "x = -674.0, [3]"

    def bad(args):
        raise ValueError(f"force {np.float64(-674.0)!r} kN out of range")

    monkeypatch.setattr(cmd, "run", bad)  # register() binds the module's run when main() builds
    assert main(["compare", "x.csv", "--out", "o"]) == 2
    err = capsys.readouterr().err
    assert "force -674.0 kN" in err and "np.float64" not in err


def test_a_checkpoint_that_is_not_hdf5_is_one_line_naming_it_not_an_hdf5_traceback(tmp_path, capsys):
    ck = tmp_path / "notes.txt"
    ck.write_text("a,b\n")
    code = main(["calibrate", "protocol4", "--law", "plasticity", "--checkpoint", str(ck),
                 "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and str(ck) in err and "not an HDF5 file" in err and "\n" not in err


@pytest.mark.parametrize("option", ["--params", "--bounds"])
def test_rubber_names_the_file_it_cannot_decode(tmp_path, capsys, option):
    from rubber.__main__ import main as rubber_main

    binary = tmp_path / "p.json"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    csv = tmp_path / "t.csv"
    csv.write_text("time_s,stretch,stress_MPa\n0,1,0\n1,1.1,0.1\n2,1.2,0.2\n3,1.1,0.1\n")
    argv = (["predict", "--params", str(binary), str(csv)] if option == "--params" else
            ["fit", str(csv), "--out", str(tmp_path / "o"), "--bounds", str(binary), "--no-progress"])
    code = rubber_main(argv)
    err = capsys.readouterr().err
    assert code == 2 and str(binary) in err and "UTF-8" in err


def test_cli_calibrate_says_first_on_stderr_that_a_law_cannot_reproduce_the_test(tmp_path, capsys):
    """Before: "NRMSE 45 %, coverage 95.9 %, converged: False" and nothing on stderr about the fit.
    After: a CRITICAL note, before the routine ones, and the reading in result.json."""
    code = main(["calibrate", "protocol1", "--law", "linear", "--steps", "40", "--walkers", "8",
                 "--out", str(tmp_path / "c"), "--quiet"])
    captured = capsys.readouterr()
    assert code == 0
    lines = [ln for ln in captured.err.splitlines() if ln.startswith("rrfrei calibrate: ")]
    first = lines[0]
    assert first.startswith("rrfrei calibrate: CRITICAL: ") and "inadequate: NRMSE" in " ".join(lines)
    assert "fit: inadequate: NRMSE" in captured.out
    res = json.loads((tmp_path / "c" / "result.json").read_text())
    assert res["adequacy"]["adequacy"] == "inadequate"
    assert res["notes"][0]["severity"] == "critical"
    run = json.loads((tmp_path / "c" / "run.json").read_text())
    assert run["stopped_by"] != "converged" or run["converged"]
