"""Long calibrations stay usable: a time budget stops them with what was sampled (and a rerun
continues the chain), the step cap is a visible option whose advice matches what happened, and a
dense record (tens of thousands of samples) is calibrated on a stated likelihood subsample with a
small stored posterior.

Short chains (``steps=``) keep this module fast; the data are made with the law itself on
protocol 1 (``rrfrei.protocols``) plus noise, on fixed seeds.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import stats

from rrfrei.app import cli
from rrfrei.calibration import (
    PATH_TOLERANCE,
    ConvergenceWarning,
    advice,
    calibrate,
    elpd_loco,
    path_error,
    setup_problem,
)
from rrfrei.calibration.likelihood import (
    DENSE_POINTS,
    HALF_CYCLE_POINTS,
    LIKELIHOOD_POINTS,
    half_cycles,
    likelihood_points,
    path_points,
)
from rrfrei.calibration.results import MAX_DRAWS_DENSE
from rrfrei.io import ShearTest
from rrfrei.protocols import protocol1
from rrfrei.simulate import simulate_force

TRUTH = dict(k_init=3000.0, qd=1.5, alpha1=0.15, alpha2=0.0, mu=2.0)


def small_test(n: int = 600) -> ShearTest:
    """The first cycles of protocol 1, plasticity with noise sd 0.1 kN: cheap steps."""
    t, u = protocol1()
    t, u = t[:n], u[:n]
    f = simulate_force("plasticity", TRUTH, u) + 0.1 * np.random.default_rng(0).standard_normal(n)
    return ShearTest("small", t, u, f)


# ---------------------------------------------------------------------------------------------
# time budget and checkpoint
# ---------------------------------------------------------------------------------------------
def test_a_time_budget_stops_the_chain_keeps_it_and_a_rerun_continues_it(tmp_path):
    """A budget far too short for the steps asked: the result is marked as stopped by the
    budget and keeps the steps sampled; rerunning with the same checkpoint continues from them
    (the stored steps are kept as they were, the optimum is not searched again).  A first run
    of 4 steps stores the optimum, so that the budget is spent on sampling on any machine."""
    import emcee

    test = small_test()
    ck = tmp_path / "chain.h5"
    kw = dict(walkers=16, seed=0, checkpoint=ck, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        calibrate(test, "plasticity", steps=4, **kw)
    with pytest.warns(ConvergenceWarning, match="stopped by the time budget of 2 s"):
        first = calibrate(test, "plasticity", steps=100_000, time_budget=2.0, **kw)
    d = first.diagnostics
    assert first.stopped_by == "time_budget" and not first.converged
    kept = d["steps"]
    assert 4 < kept < 100_000 and d["resumed_steps"] == 4
    assert d["time_budget"] == 2.0
    assert first.theta().shape[0] > 0  # the kept steps are a (rough) posterior
    stored = emcee.backends.HDFBackend(str(ck), read_only=True).get_chain()
    assert stored.shape[0] == kept  # written to the checkpoint when the budget ran out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        second = calibrate(test, "plasticity", steps=kept + 30, **kw)
    d2 = second.diagnostics
    assert d2["resumed_steps"] == kept and d2["steps"] == kept + 30
    assert second.stopped_by == "steps"
    chain = emcee.backends.HDFBackend(str(ck), read_only=True).get_chain()
    assert chain.shape[0] == kept + 30
    np.testing.assert_array_equal(chain[:kept], stored)


def test_a_budget_that_runs_out_before_any_step_says_so():
    from rrfrei.budget import BudgetExceeded

    with pytest.raises(BudgetExceeded, match="time budget of 0 s.*nothing was sampled"):
        calibrate(small_test(), "plasticity", walkers=16, steps=50, progress=False, time_budget=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    ({"time_budget": 0}, "time_budget"),
    ({"time_budget": -5.0}, "time_budget"),
    ({"time_budget": "soon"}, "time_budget"),
    ({"max_steps": 0}, "max_steps"),
    ({"max_steps": 1.5}, "max_steps"),
    ({"likelihood_points": 1}, "likelihood_points"),
    ({"likelihood_points": "some"}, "likelihood_points"),
])
def test_bad_budget_cap_and_point_values_raise_value_errors_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        calibrate(small_test(), "plasticity", progress=False, **kwargs)


# ---------------------------------------------------------------------------------------------
# step cap and advice
# ---------------------------------------------------------------------------------------------
def test_a_chain_stopped_at_the_step_cap_says_so_and_advises_raising_it():
    with pytest.warns(ConvergenceWarning) as rec:
        cal = calibrate(small_test(), "plasticity", walkers=16, max_steps=60, seed=0, progress=False)
    msg = " ".join(str(w.message) for w in rec if issubclass(w.category, ConvergenceWarning))
    assert cal.stopped_by == "max_steps" and cal.diagnostics["max_steps"] == 60
    assert "step cap of 60 steps" in msg and "max_steps" in msg
    assert "steps=None" not in msg  # it already ran with steps=None


@pytest.mark.parametrize("why, expected, never", [
    ("max_steps", ["step cap of 20000 steps", "tau ≈ 1546", "R-hat 2.160", "raise --max-steps"],
     ["--steps", "time budget"]),
    ("time_budget", ["time budget of 300 s", "3100 steps", "--checkpoint", "raise --time-budget"],
     ["step cap"]),
    ("steps", ["400 fixed steps", "leave out --steps"], ["step cap", "time budget"]),
    # a 'converged' chain whose stored draws fail the check cannot happen any more (the stopping
    # rule is the final check); the advice then states the one rule and asks for more --steps
    ("converged", ["the convergence rule", "R-hat 2.160", "--steps 5000", "--checkpoint"],
     ["step cap", "time budget"]),
])
def test_the_advice_matches_why_the_chain_stopped(why, expected, never):
    d = {"stopped_by": why, "steps": {"max_steps": 20000, "time_budget": 3100, "steps": 400}.get(why, 2500),
         "max_steps": 20000, "time_budget": 300.0, "tau": {"a": 1546.0, "b": 12.0}, "rhat_max": 2.16,
         "ess_min": 40.0, "points": 2401, "likelihood_stride": 1}
    text = advice(d, cli=True)
    for e in expected:
        assert e in text, (e, text)
    for n in never:
        assert n not in text, (n, text)


def test_the_advice_suggests_the_decimated_path_only_for_a_dense_record_run_without_it():
    base = {"stopped_by": "time_budget", "steps": 900, "max_steps": 20000, "time_budget": 300.0,
            "tau": {"a": 200.0}, "rhat_max": 1.2, "ess_min": 40.0, "points": 33_028, "likelihood_stride": 17}
    off = {"decimated": False, "decimable": True, "samples": 33_028}
    on = {"decimated": True, "decimable": True, "samples": 7808}
    assert "--half-cycle-points auto" in advice({**base, "path": off}, cli=True)
    assert "half_cycle_points=" in advice({**base, "path": off})
    assert "half-cycle" not in advice({**base, "path": on}, cli=True)
    assert "half-cycle" not in advice({**base, "path": {**off, "decimable": False}}, cli=True)  # rate law
    assert "half-cycle" not in advice({**base, "points": 2401, "path": off}, cli=True)  # not dense
    capped = {**base, "stopped_by": "max_steps"}
    assert "--half-cycle-points auto" in advice({**capped, "path": off}, cli=True)


def _cli(capsys, *argv):
    try:
        rc = cli.main(list(argv))
    except SystemExit as exc:
        rc = exc.code
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_the_cli_shows_the_cap_budget_and_likelihood_options_in_help(capsys):
    rc, out, _ = _cli(capsys, "calibrate", "--help")
    assert rc == 0
    for opt in ("--max-steps", "--time-budget", "--likelihood-points", "--checkpoint", "--quiet", "--fix",
                "--half-cycle-points"):
        assert opt in out
    assert "20000" in out and "300" in out


@pytest.mark.parametrize("option, value", [
    ("--max-steps", "0"), ("--max-steps", "-3"), ("--max-steps", "many"),
    ("--time-budget", "0"), ("--time-budget", "-10"), ("--time-budget", "soon"),
    ("--likelihood-points", "1"), ("--likelihood-points", "x"), ("--fix", "alpha2"), ("--fix", "mu=big"),
    ("--half-cycle-points", "1"), ("--half-cycle-points", "some"),
])
def test_the_cli_rejects_bad_values_with_exit_2_naming_the_option(capsys, tmp_path, option, value):
    rc, _, err = _cli(capsys, "calibrate", "protocol1", "--law", "plasticity", "--out",
                      str(tmp_path / "o"), option, value)
    assert rc == 2
    assert option in err and value in err
    assert len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------------------------------------
# dense records
# ---------------------------------------------------------------------------------------------
def test_likelihood_points_is_a_regular_subsample_above_the_dense_threshold():
    assert np.array_equal(likelihood_points(DENSE_POINTS), np.arange(DENSE_POINTS))
    idx = likelihood_points(33_028)
    assert idx.size <= LIKELIHOOD_POINTS and idx[0] == 0 and np.all(np.diff(idx) == 17)
    assert likelihood_points(33_028, "all").size == 33_028
    assert np.all(np.diff(likelihood_points(33_028, 500)) == 67)


def test_the_subsampled_likelihood_is_the_normal_density_of_the_kept_residuals_only():
    """The law runs along the whole history (its state at a kept sample depends on all earlier
    ones), and only the kept samples' residuals enter the density."""
    t, u = protocol1(rate=100.0)
    f = simulate_force("plasticity", TRUTH, u) + 0.1 * np.random.default_rng(1).standard_normal(u.size)
    test = ShearTest("dense", t, u, f)
    pb = setup_problem(test, "plasticity")
    assert pb.n_like <= LIKELIHOOD_POINTS and pb.n_points == u.size
    theta = np.array([[2800.0, 1.4, 0.17, 0.0, 2.0, 0.12]])
    full = simulate_force("plasticity", dict(zip(pb.free, theta[0, :5])), u)
    idx = pb.lik_idx
    expected = stats.norm.logpdf(f[idx], full[idx], 0.12).sum()
    assert pb.log_likelihood(theta)[0] == pytest.approx(expected, rel=1e-10)
    every = setup_problem(test, "plasticity", likelihood_points="all")
    assert every.log_likelihood(theta)[0] == pytest.approx(stats.norm.logpdf(f, full, 0.12).sum(), rel=1e-10)


@pytest.fixture(scope="module")
def dense(tmp_path_factory):
    """30,001 samples (protocol 1 at 250 Hz), plasticity + AR(1) noise with rho 0.95 per
    sample (marginal sd 0.1 kN), calibrated with AR(1) noise on the automatic subsample."""
    t, u = protocol1(rate=250.0)
    rng = np.random.default_rng(5)
    rho, sd = 0.95, 0.1
    w = rng.standard_normal(u.size) * sd * np.sqrt(1 - rho**2)
    e = np.empty_like(w)
    e[0] = rng.standard_normal() * sd
    for i in range(1, e.size):
        e[i] = rho * e[i - 1] + w[i]
    test = ShearTest("dense", t, u, simulate_force("plasticity", TRUTH, u) + e)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        cal = calibrate(test, "plasticity", noise="ar1", walkers=16, steps=400, seed=2, progress=False)
    path = cal.to_netcdf(tmp_path_factory.mktemp("dense") / "posterior.nc")
    return test, cal, path, rho


def test_a_dense_record_recovers_the_known_parameters_on_its_subsample(dense):
    test, cal, _, rho = dense
    d = cal.diagnostics
    assert d["points"] == test.disp.size and d["likelihood_points"] <= LIKELIHOOD_POINTS
    stride = d["likelihood_stride"]
    assert stride == int(np.ceil(test.disp.size / LIKELIHOOD_POINTS))
    lo, hi = np.quantile(cal.theta(), [0.005, 0.995], axis=0)
    truth = {**TRUTH, "rho": rho**stride}  # a subsampled AR(1) is AR(1) with rho^stride
    outside = {n: (truth[n], float(a), float(b)) for n, a, b in zip(cal.sampled, lo, hi)
               if n in ("k_init", "qd", "alpha1", "rho") and not a <= truth[n] <= b}
    assert not outside, f"truth outside the 99 % interval: {outside}"


def test_a_dense_records_stored_posterior_is_small(dense):
    _, cal, path, _ = dense
    assert path.stat().st_size < 10e6
    assert cal.theta().shape[0] <= MAX_DRAWS_DENSE
    assert cal.idata.log_likelihood["force"].sizes["sample"] == cal.diagnostics["likelihood_points"]
    elpd, se, per = elpd_loco(cal)  # cycle labels follow the stored subsample
    assert np.isfinite(elpd) and len(per) == 12


def test_the_cli_checkpoints_to_its_output_folder_and_says_why_it_stopped(capsys, tmp_path):
    """Default checkpoint DIR/chain.h5; the summary names the stop reason, the cap and the budget;
    the warning's advice matches fixed --steps (never the step cap)."""
    csv = tmp_path / "small.csv"
    test = small_test(300)
    csv.write_text("time_s,disp_mm,force_kN\n" + "\n".join(
        f"{t:.17g},{1e3 * u:.17g},{f:.17g}" for t, u, f in zip(test.time, test.disp, test.force)) + "\n")
    out = tmp_path / "out"
    rc, so, err = _cli(capsys, "calibrate", str(csv), "--law", "plasticity", "--out", str(out),
                       "--steps", "10", "--walkers", "16", "--quiet", "--max-steps", "5000")
    assert rc == 0, err
    assert (out / "chain.h5").exists()
    run = json.loads((out / "run.json").read_text())
    assert isinstance(run["sampling_coordinates"], str)  # which coordinates the ensemble moved in
    assert ("stopped: fixed --steps done after 10 steps x 16 walkers (--max-steps 5000, "
            "--time-budget 300 s") in so
    assert "NOT converged: the 10 fixed steps were too few" in err and "step cap" not in err


def test_the_cli_exits_2_when_the_budget_ends_before_any_sample(capsys, tmp_path):
    rc, _, err = _cli(capsys, "calibrate", "protocol1", "--law", "plasticity", "--out",
                      str(tmp_path / "o"), "--time-budget", "0.001", "--quiet")
    assert rc == 2
    assert "time budget of 0 s" in err and "nothing was sampled" in err and "--time-budget" in err


# ---------------------------------------------------------------------------------------------
# decimation of the law's input path (dense quasi-static records)
# ---------------------------------------------------------------------------------------------
BW_TRUTH = dict(k_init=1130.0, qd=3.1, alpha1=0.45, alpha2=-0.7, mu=1.55, eta=1.0, beta=0.5, gamma=0.35)


def dense_bouc_wen(rate: float = 250.0, sd: float = 0.1, seed: int = 3) -> ShearTest:
    """Protocol 1 at ``rate`` Hz (30,001 samples at 250 Hz), bouc_wen with strong softening plus
    Gaussian noise of sd ``sd`` kN."""
    t, u = protocol1(rate=rate)
    f = simulate_force("bouc_wen", BW_TRUTH, u, time=t)
    return ShearTest("dense-bw", t, u, f + sd * np.random.default_rng(seed).standard_normal(u.size))


def test_the_decimated_path_keeps_every_reversal_the_likelihood_samples_and_n_per_half_cycle():
    t, u = protocol1(rate=250.0)
    bounds = half_cycles(u)
    assert bounds.size == 26 and bounds[0] == 0 and bounds[-1] == u.size - 1
    du = np.diff(u)
    assert np.all(du[bounds[1:-1] - 1] * du[bounds[1:-1]] < 0)  # each inner bound is a turning point
    lik = likelihood_points(u.size)
    for n in (10, HALF_CYCLE_POINTS):
        path = path_points(u, n, keep=lik)
        assert path[0] == 0 and np.all(np.diff(path) > 0)
        assert np.isin(bounds, path).all() and np.isin(lik, path).all()
        for a, b in zip(bounds[:-1], bounds[1:]):
            inside = np.count_nonzero((path >= a) & (path < b))
            assert inside >= min(n, b - a), (a, b, inside)
        # regular within a half-cycle: every k-th sample, k = floor(samples / n)
        a, b = bounds[1], bounds[2]
        own = path_points(u, n)
        seg = own[(own >= a) & (own < b)]
        assert np.all(np.diff(seg) == max(1, (b - a) // n))
    assert np.array_equal(path_points(u, "all"), np.arange(u.size))
    assert path_points(u).size < u.size / 5  # auto: decimated above DENSE_POINTS samples
    assert np.array_equal(path_points(u[:DENSE_POINTS]), np.arange(DENSE_POINTS))  # not dense
    for bad in (1, 0, "some", 2.5, True):
        with pytest.raises(ValueError, match="half_cycle_points"):
            path_points(u, bad)


def test_the_force_along_the_decimated_path_converges_to_the_whole_records_as_n_grows():
    """The law's step-size error at the likelihood's samples, at the truth (12,001 samples): it
    falls as the half-cycles are resolved more finely and vanishes without decimation.  (200
    likelihood samples, every 61st: the path holds them, so they must not set its resolution.)"""
    test = dense_bouc_wen(rate=100.0)
    theta = np.array([BW_TRUTH[n] for n in ("k_init", "qd", "alpha1", "alpha2", "mu", "eta", "gamma")]
                     + [0.1])
    errors = []
    for n in (3, 20, 120):  # every 160th, 24th, 4th sample of a 480-sample half-cycle
        pb = setup_problem(test, "bouc_wen", half_cycle_points=n, likelihood_points=200)
        assert pb.decimated and pb.n_path < test.disp.size
        errors.append(path_error(pb, theta)["rms_kN"])
    assert all(b < 0.7 * a for a, b in zip(errors, errors[1:])), errors
    assert errors[0] > PATH_TOLERANCE * 0.1  # the coarsest path is visibly off: the check can fail
    full = setup_problem(test, "bouc_wen", half_cycle_points="all")
    assert not full.decimated and path_error(full, theta)["rms_kN"] == 0.0
    # the likelihood along the path is the same density of the kept residuals
    pb = setup_problem(test, "bouc_wen", half_cycle_points=HALF_CYCLE_POINTS)
    F, _ = pb.forces(pb.full_params(theta[None, :]))
    expected = stats.norm.logpdf(test.force[pb.lik_idx], pb.at_points(F)[0], 0.1).sum()
    assert pb.log_likelihood(theta[None, :])[0] == pytest.approx(expected, rel=1e-10)


def test_calibrate_states_the_decimation_and_refines_a_too_coarse_path(tmp_path):
    """Asked for 3 samples per half-cycle (6,001 samples, noise sd 0.2 kN, 200 likelihood
    samples), the force along the path is off by more than the tolerance at the optimum:
    ``calibrate`` doubles N until it is within it, and says so in the diagnostics."""
    truth = {**BW_TRUTH, "alpha2": 0.0, "mu": 2.0}
    t, u = protocol1(rate=50.0)
    f = simulate_force("bouc_wen", truth, u) + 0.2 * np.random.default_rng(0).standard_normal(u.size)
    test = ShearTest("dense-bw", t, u, f)
    fixed = {k: truth[k] for k in ("k_init", "alpha1", "alpha2", "mu", "eta", "gamma")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        kw = dict(half_cycle_points=3, likelihood_points=200, fixed=fixed, walkers=16, seed=0,
                  progress=False, checkpoint=tmp_path / "chain.h5")
        cal = calibrate(test, "bouc_wen", steps=4, **kw)
        again = calibrate(test, "bouc_wen", steps=6, **kw)  # resumed: the refined path, not N = 3
    assert again.diagnostics["resumed_steps"] == 4 and again.diagnostics["path"] == cal.diagnostics["path"]
    p = cal.diagnostics["path"]
    assert p["decimated"] and p["refinements"] >= 1 and p["half_cycle_points"] == 3 * 2 ** p["refinements"]
    assert p["samples"] < test.disp.size
    assert p["error_rms_sigma"] <= PATH_TOLERANCE and p["tolerance_sigma"] == PATH_TOLERANCE
    assert 0 < p["error_rms_kN"] <= p["error_max_kN"]
    # the refined path's error really is within the tolerance (recomputed independently)
    pb = setup_problem(test, "bouc_wen", half_cycle_points=p["half_cycle_points"],
                       likelihood_points=200, fixed=fixed)
    theta = np.array([cal.map["qd"], cal.map["sigma"]])
    F, _ = pb.forces(pb.full_params(theta[None, :]))
    full = simulate_force("bouc_wen", {**fixed, "qd": theta[0], "beta": 0.5}, u)
    rms = float(np.sqrt(np.mean((pb.at_points(F)[0] - full[pb.lik_idx]) ** 2)))
    assert rms == pytest.approx(p["error_rms_kN"], rel=1e-6)
    coarse = setup_problem(test, "bouc_wen", half_cycle_points=p["half_cycle_points"] // 2,
                           likelihood_points=200, fixed=fixed)
    assert path_error(coarse, theta)["rms_sigma"] > PATH_TOLERANCE  # the step before was not


@pytest.mark.slow
def test_a_dense_bouc_wen_record_is_calibrated_on_a_decimated_path_and_recovers_the_truth():
    """~20,000 samples (protocol 1 at 166 Hz) of bouc_wen with strong softening plus noise of sd
    0.1 kN, calibrated with the defaults (decimated path, likelihood subsample) to the unchanged
    convergence rule: it converges, states its path (error within the tolerance at the optimum),
    and every sampled parameter's 99 % interval holds the truth."""
    test = dense_bouc_wen(rate=166.0, sd=0.1, seed=11)
    assert 19_900 < test.disp.size < 20_100
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        # alpha2's registry prior N(0, 0.1) puts the truth (-0.7) 7 sd out and pulls the posterior
        # toward 0 (its mode is near -0.6 on the 2,401-sample record too, test_calibration_mixing):
        # a wide prior makes this a test of the recovery, not of the prior's pull
        cal = calibrate(test, "bouc_wen", seed=0, progress=False, max_steps=20_000,
                        priors={"alpha2": {"kind": "normal", "a": 0.0, "b": 1.0}})
    d = cal.diagnostics
    # the convergence rule, one check on the stored draws, stopped the run before the cap
    assert d["steps"] < 20_000 and cal.converged and d["stopped_by"] == "converged", advice(d)
    assert d["rhat"] < 1.05 and min(d["ess_bulk"], d["ess_tail"]) >= 400, advice(d)
    p = d["path"]
    assert p["decimated"] and p["samples"] < test.disp.size / 2
    assert p["error_rms_sigma"] <= PATH_TOLERANCE
    truth = {**BW_TRUTH, "sigma": 0.1}
    lo, hi = np.quantile(cal.theta(), [0.005, 0.995], axis=0)
    outside = {n: (truth[n], float(a), float(b)) for n, a, b in zip(cal.sampled, lo, hi)
               if n in truth and not a <= truth[n] <= b}
    assert not outside, f"truth outside the 99 % interval: {outside}"
