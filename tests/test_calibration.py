"""Bayesian calibration: known parameters are recovered, the likelihood equals its closed form,
results survive a netCDF round trip, and a killed calibration resumes without losing samples.

Recovery data are made with the law itself on protocol 1 (``rrfrei.protocols``) plus Gaussian
noise of sd 0.1 kN, on fixed seeds.  Short chains keep this module inside its time budget; the
coverage study over many seeds is in the slow tier (test_calibration_coverage.py).

Not identifiable from such a test, hence not asserted (see ``rrfrei.calibration`` docstring):
``mu`` whenever ``alpha2`` = 0 (the hardening term vanishes).  For ``bouc_wen`` the force is
invariant under (qd, beta, gamma) -> (c qd, c^eta beta, c^eta gamma); the registry holds beta at
0.5 (its truth here), and gamma is sampled and recovered.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

import rrfrei
from rrfrei.calibration import (
    Calibration,
    ConvergenceWarning,
    calibrate,
    loglik_pointwise,
    posterior_draws,
    setup_problem,
)
from rrfrei.calibration.likelihood import pointwise_from_residuals
from rrfrei.io import ShearTest
from rrfrei.protocols import protocol1
from rrfrei.simulate import simulate_force

GEO = {"d2": 0.08, "tr": 0.002, "n": 15.0}
SIGMA = 0.1  # kN
TRUTH = {
    "plasticity": dict(k_init=3000.0, qd=1.5, alpha1=0.15, alpha2=0.0, mu=2.0),
    "bouc_wen": dict(k_init=3000.0, qd=1.5, alpha1=0.15, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5),
    "elastomeric_x": dict(fy=1.5, alpha=0.15, gr=800.0, **GEO),
    "hdr": dict(a1=550.0, a2=-1.3e5, a3=7.6e7, b1=2.5, b2=-300.0, b3=220.0, c1=700.0, c2=3000.0, c3=0.83,
                c4=3.5e4),
}
FIXED = {"plasticity": {}, "bouc_wen": {}, "elastomeric_x": {}, "hdr": {}}
NOT_IDENTIFIABLE = {"plasticity": {"mu"}, "bouc_wen": {"mu"}, "elastomeric_x": set(), "hdr": set()}
CHAIN = {"plasticity": (24, 400), "bouc_wen": (20, 500), "elastomeric_x": (16, 300), "hdr": (24, 500)}


def synthetic(law: str, seed: int, sigma: float = SIGMA) -> ShearTest:
    t, u = protocol1()
    f = simulate_force(law, TRUTH[law], u, time=t)
    rng = np.random.default_rng(seed)
    return ShearTest(f"{law}-synthetic", t, u, f + sigma * rng.standard_normal(f.size), geometry=GEO)


def quiet_calibrate(*args, **kwargs) -> Calibration:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # short test chains
        return calibrate(*args, progress=False, **kwargs)


@pytest.fixture(scope="module")
def plast():
    test = synthetic("plasticity", 1)
    w, s = CHAIN["plasticity"]
    return quiet_calibrate(test, "plasticity", walkers=w, steps=s, seed=1)


# ---------------------------------------------------------------------------------------------
# recovery
# ---------------------------------------------------------------------------------------------
# elastomeric_x and hdr in the slow tier (a chain each, ~70 s of a loaded cold default tier);
# plasticity and bouc_wen (the demo's and the examples' laws) show the recovery in the default tier
@pytest.mark.parametrize("law", ["plasticity", "bouc_wen", *(pytest.param(law, marks=pytest.mark.slow)
                                                            for law in ("elastomeric_x", "hdr"))])
def test_true_parameters_lie_in_their_99_percent_intervals(law, plast):
    """Data made by the law with known parameters: every identifiable truth (and sigma) is inside
    the posterior's central 99 % interval."""
    if law == "plasticity":
        cal = plast
    else:
        w, s = CHAIN[law]
        cal = quiet_calibrate(synthetic(law, 1), law, walkers=w, steps=s, seed=1, fixed=FIXED[law])
    th = cal.theta()
    lo, hi = np.quantile(th, [0.005, 0.995], axis=0)
    truth = {**TRUTH[law], "sigma": SIGMA}
    outside = {n: (truth[n], float(a), float(b)) for n, a, b in zip(cal.sampled, lo, hi)
               if n not in NOT_IDENTIFIABLE[law] and not a <= truth[n] <= b}
    assert not outside, f"{law}: truth outside the 99 % interval: {outside}"
    # geometry comes from the test and is reported with every draw
    full = cal.draws(5, seed=0)
    for k, v in cal.fixed.items():
        assert np.all(full[k] == v)
    assert list(full.columns) == list(cal.spec.param_names)


# ---------------------------------------------------------------------------------------------
# likelihood against closed forms
# ---------------------------------------------------------------------------------------------
def test_iid_log_likelihood_equals_the_scipy_normal_density():
    test = synthetic("plasticity", 3)
    pb = setup_problem(test, "plasticity")
    theta = np.array([[3000.0, 1.5, 0.15, 0.0, 2.0, 0.12], [2500.0, 1.2, 0.2, 0.01, 1.5, 0.3]])
    ll = pb.log_likelihood(theta)
    for row, value in zip(theta, ll):
        f = simulate_force("plasticity", dict(zip(pb.free, row[:5])), test.disp)
        assert value == pytest.approx(stats.norm.logpdf(test.force, f, row[5]).sum(), rel=1e-10)


def test_ar1_pointwise_terms_sum_to_the_joint_gaussian_with_ar1_covariance():
    """Conditional densities of a stationary AR(1) sum to the multivariate normal log density
    with covariance sigma^2 rho^|i-j| / (1 - rho^2) (Box & Jenkins)."""
    rng = np.random.default_rng(0)
    n, sigma, rho = 60, 0.3, 0.7
    e = rng.standard_normal((1, n))
    cov = sigma**2 / (1 - rho**2) * rho ** np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    joint = stats.multivariate_normal(np.zeros(n), cov).logpdf(e[0])
    pw = pointwise_from_residuals(e, np.array([sigma]), np.array([rho]))
    assert pw.sum() == pytest.approx(joint, rel=1e-10)


def test_batched_ar1_likelihood_matches_the_pointwise_sum():
    test = synthetic("plasticity", 4)
    pb = setup_problem(test, "plasticity", noise="ar1")
    theta = np.array([[3000.0, 1.5, 0.15, 0.0, 2.0, 0.12, 0.4]])
    f = simulate_force("plasticity", dict(zip(pb.free, theta[0, :5])), test.disp)
    expected = pointwise_from_residuals((test.force - f)[None, :], theta[:, 5], theta[:, 6]).sum()
    assert pb.log_likelihood(theta)[0] == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("noise", ["iid", "ar1"])
def test_the_profiled_optimiser_objective_is_the_sampled_posterior_at_the_noise_mle(noise):
    """One likelihood, two paths: the optimiser's profile (pointwise densities of the forces)
    equals the sampler's Numba batch at the same theta, and its noise is the maximum."""
    test = synthetic("plasticity", 5)
    pb = setup_problem(test, "plasticity", noise=noise)
    X = np.array([[3000.0, 1.5, 0.15, 0.0, 2.0], [2800.0, 1.4, 0.17, 0.001, 1.8]])
    theta, lp = pb.profile_log_prob(X)
    assert np.all(theta[:, :5] == X)
    assert lp == pytest.approx(pb.log_prob(theta), rel=1e-10)
    for w in range(2):  # the profiled noise maximises the likelihood over each noise parameter
        for j in range(5, pb.ndim):  # sigma by 2 %, rho by 0.02
            for step in (-0.02, 0.02):
                moved = theta[w:w + 1].copy()
                moved[0, j] += step * (moved[0, j] if j == 5 else 1.0)
                assert pb.log_likelihood(moved)[0] < pb.log_likelihood(theta[w:w + 1])[0]


def test_the_problem_counts_its_own_law_runs_and_only_those():
    test = synthetic("plasticity", 6)
    pb = setup_problem(test, "plasticity")
    theta = np.array([[3000.0, 1.5, 0.15, 0.0, 2.0, 0.1]] * 3)
    assert pb.n_evals == 0
    pb.log_likelihood(theta)
    pb.forces(pb.full_params(theta[:2]))
    pb.profile_log_prob(theta[:1, :5])
    assert pb.n_evals == 3 + 2 + 1
    pb.forces(pb.full_params(theta), test=synthetic("plasticity", 7))  # another test: not counted
    assert pb.n_evals == 6
    with pytest.raises(AttributeError):
        pb.n_evals = 0  # the counter is the problem's own


def test_the_noise_model_is_resolved_once_and_bad_names_say_what_is_allowed():
    from rrfrei.calibration.noise import NoiseModel, noise_model

    ar1 = noise_model("ar1")
    assert noise_model(ar1) is ar1 and ar1.params == ("sigma", "rho")
    pb = setup_problem(synthetic("plasticity", 0), "plasticity", noise=ar1)
    assert pb.noise is ar1 and pb.names[-2:] == ("sigma", "rho")
    assert list(pb.lower[-2:]) == [0.0, -1.0] and list(pb.upper[-2:]) == [np.inf, 1.0]
    for bad in ("gauss", "AR1", None):
        with pytest.raises(ValueError, match=r"noise = .*expected one of iid, ar1"):
            noise_model(bad)
    with pytest.raises(ValueError, match="noise = 'white'"):
        NoiseModel("white")


def test_the_convergence_checks_statistics_are_emcees_tau_and_arviz_ess_and_rhat():
    """The stopping rule's fast all-parameter estimators (one FFT) give exactly the reference
    numbers: emcee's integrated time, arviz' bulk and tail ESS and rank-normalised R-hat."""
    import arviz as az
    import emcee

    from rrfrei.calibration.convergence import _diagnose, _tau

    rng = np.random.default_rng(1)
    n, m, phi = 600, 16, np.array([0.5, 0.8, 0.95])  # AR(1) chains: tau = (1 + phi) / (1 - phi)
    x = np.empty((n, m, phi.size))
    x[0] = rng.standard_normal((m, phi.size))
    for t in range(1, n):
        x[t] = phi * x[t - 1] + rng.standard_normal((m, phi.size))
    np.testing.assert_allclose(_tau(x), emcee.autocorr.integrated_time(x, tol=0), rtol=1e-12)
    ds = {f"p{j}": x[:, :, j].T for j in range(phi.size)}  # walkers as chains
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = [min(float(az.ess(ds, method=k)[v]) for v in ds) for k in ("bulk", "tail")]
        ref.append(max(float(az.rhat(ds)[v]) for v in ds))
    assert _diagnose(x) == pytest.approx(tuple(ref), rel=1e-12)


def test_a_failing_or_out_of_support_parameter_set_has_zero_posterior_density():
    pb = setup_problem(synthetic("plasticity", 0), "plasticity")
    bad = np.array([[3000.0, 1.5, 1.5, 0.0, 2.0, 0.1],  # alpha1 > 1 (outside bounds)
                    [3000.0, 1.5, 0.15, 0.0, 2.0, -0.1]])  # negative sigma
    assert np.all(pb.log_prob(bad) == -np.inf)


# ---------------------------------------------------------------------------------------------
# result object
# ---------------------------------------------------------------------------------------------
def test_summary_has_the_studys_columns_and_map_is_the_best_point_seen(plast):
    s = plast.summary
    assert list(s.index) == ["k_init", "qd", "alpha1", "alpha2", "mu", "sigma"]
    for c in ("mean", "MAP", "sd", "2.5%", "97.5%", "ESS", "R-hat", "unit"):
        assert c in s.columns
    pb = setup_problem(plast.test, "plasticity")
    lp_map = pb.log_prob(np.array([[plast.map[n] for n in plast.sampled]]))[0]
    assert lp_map >= plast.idata.sample_stats["lp"].values.max() - 1e-9
    d = plast.diagnostics
    assert 0 < d["acceptance"] < 1 and d["steps"] == 400 and d["walkers"] == 24


def test_netcdf_round_trip_keeps_everything_needed(plast, tmp_path):
    path = plast.to_netcdf(tmp_path / "post.nc")
    back = Calibration.from_netcdf(path)
    assert back.law == "plasticity" and back.noise == "iid"
    assert back.map == pytest.approx(plast.map)
    np.testing.assert_array_equal(back.test.disp, plast.test.disp)
    np.testing.assert_array_equal(back.theta(), plast.theta())
    pd.testing.assert_frame_equal(back.summary, plast.summary)
    a = back.idata.posterior.attrs
    assert a["disp_min_m"] == pytest.approx(-0.03) and a["disp_max_m"] == pytest.approx(0.03)
    for g in ("posterior", "log_likelihood", "posterior_predictive", "observed_data", "sample_stats"):
        assert g in back.idata.groups()


def test_posterior_draws_accepts_every_source_form(plast, tmp_path):
    path = plast.to_netcdf(tmp_path / "p.nc")
    for src in (plast, plast.idata, path, str(path)):
        law, df = posterior_draws(src, 7, seed=3)
        assert law == "plasticity" and len(df) == 7
        assert {"k_init", "qd", "alpha1", "alpha2", "mu", "sigma"} <= set(df.columns)
    df = plast.draws(4, seed=0)
    law, again = posterior_draws(df, 10, seed=0)
    assert law == "plasticity" and len(again) == 10
    with pytest.raises(ValueError, match="attrs"):
        posterior_draws(pd.DataFrame({"k_init": [1.0]}), 1)


def test_pointwise_log_likelihood_of_the_own_test_equals_the_stored_one(plast):
    ll = loglik_pointwise(plast, plast.test)
    stored = plast.idata.log_likelihood["force"].values.reshape(ll.shape)
    np.testing.assert_allclose(ll, stored, rtol=1e-12)
    law, df = posterior_draws(plast, None)
    np.testing.assert_allclose(loglik_pointwise((law, df), plast.test), ll, rtol=1e-12)


def test_opensees_command_builds_the_map_element(plast, ops):
    """The printed openseespy call runs and its element reproduces the MAP force (peer)."""
    from opensees_harness import command_force

    cmd = plast.opensees_command()
    assert cmd.startswith("ops.element('elastomericBearingPlasticity'")
    u = plast.test.disp[:200]
    forces = command_force(ops, "plasticity", cmd, u)
    ours = simulate_force("plasticity", plast.map_params(), u)
    np.testing.assert_allclose(forces, ours, rtol=1e-9, atol=1e-9 * np.max(np.abs(ours)))


# ---------------------------------------------------------------------------------------------
# boundary
# ---------------------------------------------------------------------------------------------
def test_geometry_laws_need_the_bearing_geometry():
    t, u = protocol1()
    test = ShearTest("nogeo", t, u, simulate_force("elastomeric_x", TRUTH["elastomeric_x"], u))
    with pytest.raises(ValueError, match="d2, tr, n"):
        calibrate(test, "elastomeric_x", steps=10, progress=False)


@pytest.mark.parametrize("kwargs, match", [
    ({"noise": "pink"}, "pink"),
    ({"priors": {"zeta": ("uniform", 0, 1)}}, "zeta"),
    ({"fixed": {"nope": 1.0}}, "nope"),
    ({"fixed": {"alpha1": 3.0}}, "alpha1"),
    ({"walkers": 4, "steps": 10}, "walkers"),
])
def test_bad_arguments_raise_value_errors_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        calibrate(synthetic("plasticity", 0), "plasticity", progress=False, **kwargs)


def test_an_augmented_law_calibrates_through_the_same_code():
    """'plasticity+rate' comes from the registry; its extra parameters are sampled like any other."""
    cal = quiet_calibrate(synthetic("plasticity", 2), "plasticity+rate", walkers=16, steps=40, seed=0)
    spec = rrfrei.laws.get("plasticity+rate")
    assert set(cal.free) == set(spec.free_names)
    assert len(cal.free) > len(rrfrei.laws.get("plasticity").free_names)


def test_a_short_chain_warns_plainly_that_it_has_not_converged():
    with pytest.warns(ConvergenceWarning, match="NOT converged"):
        cal = calibrate(synthetic("plasticity", 0), "plasticity", walkers=16, steps=30, progress=False)
    assert not cal.converged


# ---------------------------------------------------------------------------------------------
# initial ensemble: the Laplace approximation at the optimum
# ---------------------------------------------------------------------------------------------
def _linear_problem(noise: str):
    """A linear spring F = k u on protocol 1 with known noise; its posterior of k is Gaussian."""
    t, u = protocol1()
    f = 2500.0 * u + 0.1 * np.random.default_rng(3).standard_normal(u.size)
    return setup_problem(ShearTest("linear", t, u, f), "linear", noise=noise), u


@pytest.mark.parametrize("noise, rho", [("iid", None), ("ar1", 0.6)])
def test_the_initial_ensemble_covariance_is_the_closed_form_posterior_of_a_linear_spring(noise, rho):
    """For F = k u with Gaussian noise, Var(k | data) = sigma^2 / sum(w_t^2), w the whitened
    displacement (w_0 = sqrt(1 - rho^2) u_0, w_t = u_t - rho u_{t-1}); in the sampler's unit-cube
    coordinate z (k = k(z)) the precision is that times (dk/dz)^2, plus the stated ridge."""
    from rrfrei.calibration.laplace import LAPLACE_RIDGE, laplace_cov
    from rrfrei.calibration.optimum import _Cube

    pb, u = _linear_problem(noise)
    k_hat, sigma = 2500.0, 0.1
    theta0 = np.array([k_hat, sigma] + ([rho] if rho is not None else []))
    cube = _Cube(pb)
    z0 = cube.to_z(np.array([k_hat]))[0, 0]
    dkdz = (cube.to_x(np.array([[z0 + 1e-7]]))[0, 0] - cube.to_x(np.array([[z0 - 1e-7]]))[0, 0]) / 2e-7
    r = 0.0 if rho is None else rho
    w = np.concatenate([[np.sqrt(1 - r * r) * u[0]], u[1:] - r * u[:-1]])
    precision = dkdz**2 * np.sum(w * w) / sigma**2 + 1.0 / LAPLACE_RIDGE**2
    cov = laplace_cov(pb, theta0)
    assert cov.shape == (1, 1)
    assert cov[0, 0] == pytest.approx(1.0 / precision, rel=1e-4)


def test_the_initial_walkers_spread_like_the_posterior_not_like_a_point():
    """Drawn walkers of the linear spring: sd of k within 5 % of the closed-form posterior sd
    (4000 walkers: the sd estimate itself scatters by ~1 %), sigma within its 1/sqrt(2n) spread."""
    from rrfrei.calibration.laplace import _ball

    pb, u = _linear_problem("iid")
    theta0 = np.array([2500.0, 0.1])
    walkers = _ball(pb, theta0, 4000, np.random.default_rng(0))
    sd_k = 0.1 / np.sqrt(np.sum(u * u))
    assert np.std(walkers[:, 0]) == pytest.approx(sd_k, rel=0.05)
    assert np.mean(walkers[:, 0]) == pytest.approx(2500.0, abs=4 * sd_k / np.sqrt(4000))
    assert np.std(walkers[:, 1]) == pytest.approx(0.1 / np.sqrt(2 * u.size), rel=0.05)
    assert np.all(np.isfinite(pb.log_prob(walkers)))


# ---------------------------------------------------------------------------------------------
# checkpoint: kill and resume
# ---------------------------------------------------------------------------------------------
SCRIPT = textwrap.dedent("""
    import sys, warnings
    warnings.simplefilter("ignore")
    import numpy as np
    from rrfrei.calibration import calibrate
    from rrfrei.io import ShearTest
    from rrfrei.protocols import protocol1
    from rrfrei.simulate import simulate_force
    t, u = protocol1()
    t, u = t[:600], u[:600]  # the first six cycles keep each step cheap
    f = simulate_force("plasticity", dict(k_init=3000.0, qd=1.5, alpha1=0.15, alpha2=0.0, mu=2.0), u)
    f = f + 0.1 * np.random.default_rng(0).standard_normal(f.size)
    cal = calibrate(ShearTest("k", t, u, f), "plasticity", walkers=16, steps=int(sys.argv[2]),
                    seed=0, checkpoint=sys.argv[1], progress=False)
    print("STEPS", cal.diagnostics["steps"], flush=True)
""")


def _iterations(path) -> int:
    import emcee

    try:
        return int(emcee.backends.HDFBackend(str(path), read_only=True).iteration)
    except Exception:
        return 0


def test_a_killed_and_resumed_calibration_ends_with_as_many_samples_as_an_uninterrupted_one(tmp_path):
    steps = 600
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    # the child imports the same rrfrei as this process (the checkout under test, not an install)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "HDF5_USE_FILE_LOCKING": "FALSE",
           "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    ck = tmp_path / "chain.h5"
    proc = subprocess.Popen([sys.executable, str(script), str(ck), str(steps)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 240
    killed_at = 0
    while time.time() < deadline and proc.poll() is None:
        n = _iterations(ck) if ck.exists() else 0
        if n >= 30:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            killed_at = _iterations(ck)
            break
        time.sleep(0.05)
    assert 0 < killed_at < steps, f"the run was not killed mid-chain (stored {killed_at} steps)"
    out = subprocess.run([sys.executable, str(script), str(ck), str(steps)], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert f"STEPS {steps}" in out.stdout
    import emcee

    resumed = emcee.backends.HDFBackend(str(ck), read_only=True)
    assert resumed.iteration == steps
    assert resumed.get_chain().shape == (steps, 16, 6)
    # an uninterrupted run (same script, in this process) stores exactly as many samples
    ck2 = tmp_path / "straight.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys_argv = sys.argv
        try:
            sys.argv = ["run.py", str(ck2), str(steps)]
            exec(compile(SCRIPT, "run.py", "exec"), {"__name__": "__main__"})
        finally:
            sys.argv = sys_argv
    straight = emcee.backends.HDFBackend(str(ck2), read_only=True)
    assert straight.get_chain().shape == resumed.get_chain().shape
    # the samples stored before the kill are kept, not redrawn
    np.testing.assert_array_equal(resumed.get_chain()[:killed_at], straight.get_chain()[:killed_at])
