"""Robust rubber fits (issues 16.3 and 16.4): a failing evaluation is a bad point, never the end of a
fit; the flow constants are searched by flow threshold so the box cannot reach run-away C1; the
locking stretch is kept away from N = 1; the post-fit uncertainty step stays inside the bounds and
never loses a finished fit."""

from __future__ import annotations

import importlib
import json
import math

import numpy as np
import pytest

import rubber.integrate as _k
from rubber import PRESETS, PRFParams, fit, objective, simulate
from rubber.__main__ import main
from rubber.fit import (
    DTH_RANGE,
    FAIL_F,
    N_LOCK_MIN,
    _resolve_bounds,
    _Space,
    auto_bounds,
    c1_from_threshold,
    fisher_report,
)
from rubber.io import load_vhb4910, write_test
from rubber.study import BOX, multirate_tests, synthetic_test

# the parameter set of issue 16.3 at which the 12-test acrylic fit died (ZeroDivisionError in the
# kernel inside the objective; "too many steps" from simulate)
FAILING = PRFParams(C10=0.0322, C20=-0.00409, C30=0.00245, nkt_B=8.44e-05, N_B=1.0447, C1_B=1.31e+19,
                    C2_B=-1.0, C3_B=3.997, nkt_C=8.25e-04, N_C=11.48, C1_C=3.95e+20, C2_C=-1.0, C3_C=1.153)
FREE = ("C10", "C20", "C30", "nkt_B", "N_B", "C1_B", "C3_B", "nkt_C", "N_C", "C1_C", "C3_C")


@pytest.fixture(scope="module")
def acrylic():
    """The synthetic 12-test set: 3 stretch rates x 4 maximum stretches, load-unload, 1 % noise."""
    return multirate_tests(seed=0)


def _raise_in_kernel(monkeypatch, when):
    """Make the kernel raise ZeroDivisionError (as on the issue's data) for chain arrays where ``when``."""
    real_nominal, real_sim = _k.nominal_stress, _k.simulate_kernel

    def nominal(time, lam, eq, ch, rtol, out):
        if when(ch):
            raise ZeroDivisionError("division by zero")
        return real_nominal(time, lam, eq, ch, rtol, out)

    def sim(time, lam, eq, ch, rtol, u, dch, diss):
        if when(ch):
            raise ZeroDivisionError("division by zero")
        return real_sim(time, lam, eq, ch, rtol, u, dch, diss)

    monkeypatch.setattr(_k, "nominal_stress", nominal)
    monkeypatch.setattr(_k, "simulate_kernel", sim)


# --- (a) a failing evaluation is a bad point ----------------------------------------------------
def test_objective_scores_a_kernel_exception_as_a_bad_point(acrylic, monkeypatch):
    _raise_in_kernel(monkeypatch, lambda ch: True)
    f = objective(FAILING, acrylic)
    assert f.shape == (12,) and np.all(f == FAIL_F)


def test_the_issue_point_integrates_in_a_bounded_number_of_steps(acrylic):
    """At C1 ~ 1e19-1e20 a chain relaxes in microseconds; the integrator used to need > 5e7 steps
    ("too many steps" after minutes).  Now each stage rate follows from the stage equation."""
    for t in acrylic[::3]:
        r = simulate(FAILING, t.time, t.stretch)
        assert np.all(np.isfinite(r.nominal))
        assert r.steps < 20 * t.time.size
    f = objective(FAILING, acrylic)
    assert np.all(np.isfinite(f)) and np.all(f < FAIL_F)


def test_a_fit_whose_search_crosses_a_failing_region_finishes(monkeypatch):
    """Every evaluation with C3 > 7 in either chain (chain column 4) raises inside the kernel, a third
    of each C3 range; CMA-ES and the least-squares polish step over the region and the fit returns a
    finite optimum outside it."""
    truth = PRESETS["A"]
    full = synthetic_test(truth, "p1")
    data = type(full)("p1_short", full.time[:120], full.stretch[:120], full.stress[:120])
    _raise_in_kernel(monkeypatch, lambda ch: ch[0, 4] > 7.0 or ch[1, 4] > 7.0)
    r = fit(data, seed=0, restarts=1, max_evals=300)
    assert math.isfinite(r.f_total) and r.f_total < 0.1
    assert r.params.C3_B <= 7.0 and r.params.C3_C <= 7.0


# --- (b) flow-threshold parameterisation ------------------------------------------------------
@pytest.mark.parametrize("tau", ["frobenius", "mises"])
def test_c1_from_threshold_inverts_the_chain_flow_threshold(tau):
    for d, c3, rate in [(1e-4, 10.0, 0.01), (0.36, 7.4, 0.093), (5.0, 1.0, 1.0)]:
        c1 = c1_from_threshold(d, c3, rate=rate, tau=tau)
        ch = PRESETS["A"].to_model().chains[0]
        ch = type(ch)(ch.nkt, ch.N, c1, -1.0, c3, 5e-3)
        assert ch.flow_threshold(rate, tau) == pytest.approx(d, rel=1e-12)


def test_auto_box_searches_flow_thresholds_scaled_to_the_data(acrylic):
    b = auto_bounds(acrylic)
    smax = max(float(np.max(np.abs(t.stress))) for t in acrylic)
    assert "C1_B" not in b and "C1_C" not in b
    assert b["Dth_B"] == pytest.approx((DTH_RANGE[0] * smax, DTH_RANGE[1] * smax))
    assert b["ref_rate"] == pytest.approx(0.0311)  # geometric mean of 0.01, 0.03, 0.1 1/s
    space = _Space(FREE, b, {"C2_B": -1.0, "C2_C": -1.0, "xi": 5e-3})
    # the issue's point lies outside the box: its thresholds are microscopic
    for c in space.threshold:
        assert FAILING.to_model().chains["BC".index(c)].flow_threshold(b["ref_rate"]) < b["Dth_" + c][0]
    # and every point of the box maps to native parameters whose thresholds are inside it
    rng = np.random.default_rng(3)
    for x in rng.uniform(0, 1, (20, len(FREE))):
        p = space.params(x)
        lo, hi = b["Dth_B"]
        for ch in p.to_model().chains:
            assert lo * (1 - 1e-9) <= ch.flow_threshold(b["ref_rate"]) <= hi * (1 + 1e-9)
        back = space.params(space.x_of(p)).as_dict()  # the round trip returns the same (ordered) chains
        for n, v in p.as_dict().items():
            assert back[n] == pytest.approx(v, rel=1e-9, abs=1e-15), n


def test_no_corner_of_the_auto_box_fails_to_evaluate(acrylic):
    """The stiffest and softest chains the box allows all integrate (none scores FAIL_F)."""
    b = auto_bounds(acrylic)
    space = _Space(FREE, b, {"C2_B": -1.0, "C2_C": -1.0, "xi": 5e-3})
    rng = np.random.default_rng(7)
    sub = acrylic[3::4]  # the three lambda_max = 3 tests
    for x in rng.integers(0, 2, (24, len(FREE))).astype(float):
        f = objective(space.params(x), sub)
        assert np.all(np.isfinite(f)) and np.all(f < FAIL_F), x


def test_a_user_box_may_name_flow_thresholds():
    b = _resolve_bounds({"Dth_B": [0.1, 2.0], "ref_rate": 0.093}, [])
    space = _Space(FREE, b, {"C2_B": -1.0, "C2_C": -1.0, "xi": 5e-3})
    assert space.threshold == ("B",) and "Dth_B" in space.coords and "C1_C" in space.coords
    for bad, match in [({"Dth_B": [0.0, 1.0]}, "lo > 0"), ({"ref_rate": -1}, "ref_rate"),
                       ({"C9": [0, 1]}, "unknown parameter")]:
        with pytest.raises(ValueError, match=match):
            _resolve_bounds(bad, [])


# --- (c) the locking stretch ---------------------------------------------------------------------
def test_auto_box_keeps_the_locking_stretch_away_from_n_equal_1(acrylic):
    """N = 1.0447 of the issue puts the chain at rest at x = 1/sqrt(N) = 0.98 of its lock; the auto box
    starts at N = 4 (x <= 1/2 at rest) and reaches 2 I1(lambda_max)."""
    b = auto_bounds(acrylic)
    for c in "BC":
        assert b["N_" + c] == pytest.approx((N_LOCK_MIN, 2 * (3.0**2 + 2 / 3.0)))
        assert 1 / math.sqrt(b["N_" + c][0]) <= 0.5
    assert not b["N_B"][0] <= FAILING.N_B


# --- 16.4: the uncertainty step at a bound ----------------------------------------------------
def test_fisher_at_a_parameter_on_its_bound_stays_inside_and_is_finite():
    """C3_B on its lower bound 1 (and C1_C on its upper bound 5): the old central difference stepped
    C3_B to 0.9999 and raised 'C3_B = 0.9999: expected >= 1.0' after the fit had finished."""
    p = PRESETS["A"].replace(C3_B=1.0, C1_B=0.05)
    data = [synthetic_test(p, "p1", dt=0.5)]
    fim, corr, rel, notes = fisher_report(p, data, FREE, bounds=BOX)
    assert np.all(np.isfinite(fim))
    assert math.isfinite(rel["C3_B"]) and rel["C3_B"] > 0
    assert any(n.startswith("C3_B: one-sided") for n in notes)
    assert any(n.startswith("C1_C: one-sided") for n in notes)


def test_fisher_on_the_vhb_data_at_a_default_box_point_on_five_bounds():
    """The bundled VHB 4910 test with the study's default box: the default-bounds fit ends with C10,
    nkt_B, nkt_C on their lower bounds; C3_B = 1 and C1_B = 1e-6 (lower bounds) added as in the issue
    ('C3 = 0.9999000050206774: expected >= 1.0')."""
    p = PRFParams(C10=1.0, C20=-0.0695, C30=0.00133, nkt_B=0.01, N_B=3.26, C1_B=1e-6, C2_B=-1.0, C3_B=1.0,
                  nkt_C=0.01, N_C=3.28, C1_C=1.05e-6, C2_C=-1.0, C3_C=8.52)
    fim, corr, rel, notes = fisher_report(p, [load_vhb4910()], FREE, bounds=BOX)
    assert all(math.isfinite(rel[n]) for n in FREE)
    for n in ("C10", "nkt_B", "C1_B", "C3_B", "nkt_C"):
        assert any(x.startswith(f"{n}: one-sided") for x in notes), n


def test_fisher_gives_nan_with_a_reason_where_no_step_fits():
    p = PRESETS["A"]
    data = [synthetic_test(p, "p1", dt=0.5)]
    b = dict(BOX, N_B=(5.0, 5.0001))  # narrower than the difference step on both sides
    fim, corr, rel, notes = fisher_report(p, data, FREE, bounds=b)
    assert math.isnan(rel["N_B"]) and all(math.isfinite(rel[n]) for n in FREE if n != "N_B")
    assert any(n.startswith("N_B: no uncertainty") and "outside its bounds" in n for n in notes)


def test_cli_fit_writes_its_outputs_when_the_uncertainty_step_fails(tmp_path, monkeypatch, capsys):
    rf = importlib.import_module("rubber.fit")  # the attribute rubber.fit is the function

    def broken(*a, **k):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(rf, "fisher_report", broken)
    t = synthetic_test(PRESETS["A"], "p1", dt=0.5)
    write_test(tmp_path / "p1.csv", t, unit="kPa")
    code = main(["fit", str(tmp_path / "p1.csv"), "--out", str(tmp_path / "out"), "--restarts", "1",
                 "--max-evals", "64"])
    assert code == 0
    doc = json.loads((tmp_path / "out" / "params.json").read_text())
    assert set(doc["params"]) >= set(FREE) and math.isfinite(doc["f_total"])
    assert doc["rel_sigma"]["C10"] is None
    assert doc["uncertainty_notes"] == ["uncertainty step failed: division by zero"]
    assert (tmp_path / "out" / "fit.png").is_file()
    assert "uncertainty step failed" in capsys.readouterr().err


# --- a time budget ends the search with the best fit so far ------------------------------------
def test_a_time_budget_ends_the_search_early_and_keeps_the_best_fit_so_far(acrylic):
    r = fit(acrylic[:2], bounds="auto", restarts=2, max_evals=5000, time_budget=1.0)
    assert r.stopped_by == "time_budget"
    assert r.evaluations < 2 * 5000 and math.isfinite(r.f_total) and r.f_total < 2.0
    done = fit(acrylic[:1], bounds="auto", restarts=1, max_evals=32, polish=False)
    assert done.stopped_by is None


def test_cli_fit_time_budget_writes_the_best_fit_and_warns(tmp_path, acrylic, capsys):
    write_test(tmp_path / "a.csv", acrylic[0], unit="kPa")
    code = main(["fit", str(tmp_path / "a.csv"), "--out", str(tmp_path / "out"), "--bounds", "auto",
                 "--max-evals", "20000", "--time-budget", "1", "--no-progress"])
    assert code == 0
    doc = json.loads((tmp_path / "out" / "params.json").read_text())
    assert doc["stopped_by"] == "time_budget" and math.isfinite(doc["f_total"])
    assert "time budget of 1 s reached" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["0", "-5", "soon"])
def test_cli_fit_rejects_a_bad_time_budget_naming_the_option(tmp_path, value, capsys):
    with pytest.raises(SystemExit) as e:
        main(["fit", str(tmp_path / "a.csv"), "--out", str(tmp_path / "o"), "--time-budget", value])
    assert e.value.code == 2 and "--time-budget" in capsys.readouterr().err


# --- the 12-test multi-rate fit (slow tier) -----------------------------------------------------
@pytest.mark.slow
def test_twelve_test_multirate_fit_recovers_the_identifiable_combinations(tmp_path, acrylic):
    from rubber.fit import combinations
    from rubber.study import ACRYLIC

    paths = []
    for t in acrylic:
        write_test(tmp_path / f"{t.name}.csv", t, unit="kPa")
        paths.append(str(tmp_path / f"{t.name}.csv"))
    code = main(["fit", *paths, "--bounds", "auto", "--out", str(tmp_path / "out"), "--max-evals", "3000"])
    assert code == 0
    doc = json.loads((tmp_path / "out" / "params.json").read_text())
    assert doc["flow_parameterisation"] == ["Dth_B", "Dth_C"]
    # at the noise floor: no worse than the true parameters on the noisy data
    assert doc["f_total"] <= 1.02 * float(np.sum(objective(ACRYLIC, acrylic, rtol=1e-8)))
    truth = combinations(ACRYLIC, rate=doc["ref_rate"])
    for n, v in truth.items():  # moduli, flow thresholds at r_ref, equilibrium stresses
        assert doc["combinations"][n] == pytest.approx(v, rel=0.05), n


# --- the polish has an evaluation cap (Jacobians included) --------------------------------------
def test_the_polish_stops_at_its_evaluation_cap_jacobians_included(acrylic):
    bare = fit(acrylic[:1], bounds="auto", restarts=1, max_evals=32, polish=False)
    capped = fit(acrylic[:1], bounds="auto", restarts=1, max_evals=32, polish_evals=25)
    # the same CMA-ES run (same seed), then at most 25 polish evaluations; the polish keeps the best
    assert 0 < capped.evaluations - bare.evaluations <= 25
    assert capped.f_total <= bare.f_total


def test_a_polish_cap_below_one_is_refused_naming_the_option(acrylic):
    with pytest.raises(ValueError, match="polish_evals = 0"):
        fit(acrylic[:1], bounds="auto", restarts=1, max_evals=32, polish_evals=0)
