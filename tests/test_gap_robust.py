"""Gap diagnosis under failure, time limits and restarts (issue 16.4).

The engine (:func:`rrfrei.gap.diagnose.diagnose`) is generic over :class:`GapModel`, so most
specifications here run it on a small linear model (force = a u + effect regressors, exact
least squares, milliseconds per fit) whose fits can be made to fail and whose "fit time" is read
from a fake clock: no timing assertions, no dependence on the machine's load.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from rrfrei.app.cli import main
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.errors import NumericalFailure
from rrfrei.gap.diagnose import diagnose
from rrfrei.gap.fitting import laplace_cov
from rrfrei.gap.isolator import IsolatorFit, IsolatorModel
from rrfrei.gap.model import FitResult, GapModel, Prediction
from rrfrei.gap.report import write_report
from rrfrei.io import ShearTest
from rrfrei.laws import get

REGRESSORS = {
    "asymmetry": lambda u: np.abs(u),
    "rollover": lambda u: u**3,
    "degradation": lambda u: u * np.linspace(0.0, 1.0, u.size),
}
EFFECTS = ["degradation", "asymmetry", "rollover"]


class Clock:
    """Fake wall clock [s]: each fit of :class:`LinearModel` advances it by its ``cost``."""

    def __init__(self) -> None:
        self.t = 0.0


class ClockBudget(TimeBudget):
    """A :class:`TimeBudget` that reads the fake clock."""

    def __init__(self, seconds: float, clock: Clock) -> None:
        super().__init__(seconds, what="gap diagnosis", option="time_budget")
        self.clock = clock

    @property
    def elapsed(self) -> float:
        return self.clock.t


class LinearFit(FitResult):
    def __init__(self, effects, beta, B, sigma, regressors=None):
        self.effects, self.beta, self.B, self.sigma = tuple(effects), beta, B, float(sigma)
        self.regressors = regressors  # None: the module's REGRESSORS, read when used
        self.noise = self.sigma
        self.name = "+".join(["linear", *self.effects])
        self.params = {f"b{i}": float(b) for i, b in enumerate(beta)}

    def predict(self, data) -> Prediction:
        F = self.B @ _design(self.effects, data.disp, self.regressors).T
        m = F.mean(axis=0)
        return Prediction(mean=m, lower=m - 2 * self.sigma, upper=m + 2 * self.sigma, draws=F,
                          sigma=np.full(F.shape[0], self.sigma))

    def loglik(self, data) -> np.ndarray:
        r = np.asarray(data.force)[None, :] - self.predict(data).draws
        return -0.5 * (r / self.sigma) ** 2 - np.log(self.sigma) - 0.5 * np.log(2 * np.pi)


def _design(effects, u, regressors=None) -> np.ndarray:
    reg = REGRESSORS if regressors is None else regressors
    return np.column_stack([u, *[reg[e](u) for e in effects]])


class LinearModel(GapModel):
    """force = b0 u + sum of effect regressors (``regressors``: effect -> function of u; None, the
    default: :data:`REGRESSORS` as it is when a fit runs); ``fail``: effects whose fit raises
    LinAlgError (``"*"``: every fit, the baseline too)."""

    regressors = None

    def __init__(self, effects=(), *, clock=None, cost=0.0, fail=(), calls=None):
        self.effects, self.clock, self.cost, self.fail = tuple(effects), clock, cost, set(fail)
        self.calls = [] if calls is None else calls
        self.name = "+".join(["linear", *self.effects])

    def augment(self, effects):
        return LinearModel(self.effects + tuple(effects), clock=self.clock, cost=self.cost, fail=self.fail,
                           calls=self.calls)

    def observed(self, data):
        return np.asarray(data.force)

    def groups(self, data):
        return np.arange(len(data)) * 10 // len(data)  # ten cycles

    def fit(self, data, *, seed=0, start=None, budget=None):
        self.calls.append(self.name)
        if self.clock is not None:
            self.clock.t += self.cost
        if budget is not None:
            budget.check()
        if "*" in self.fail or set(self.effects) & self.fail:
            raise np.linalg.LinAlgError("Singular matrix")
        X = _design(self.effects, np.asarray(data.disp), self.regressors)
        y = np.asarray(data.force)
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ beta
        s2 = float(r @ r) / (y.size - X.shape[1])
        L = np.linalg.cholesky(s2 * np.linalg.inv(X.T @ X))
        B = beta + np.random.default_rng(seed).normal(size=(100, beta.size)) @ L.T
        B[0] = beta
        return LinearFit(self.effects, beta, B, np.sqrt(s2), self.regressors)

    def checkpoint_key(self, data):
        return hashlib.sha256(np.asarray(data.force).tobytes() + self.name.encode()).hexdigest()

    def fit_state(self, fit):
        return {"effects": np.array(fit.effects, dtype=str), "beta": fit.beta, "B": fit.B,
                "sigma": np.array(fit.sigma)}

    def restore(self, state):
        return LinearFit([str(e) for e in state["effects"]], state["beta"], state["B"], float(state["sigma"]),
                         self.regressors)


def _tests(asym: float = 0.3) -> list[ShearTest]:
    """Calibration and held-out tests: force = 2 u + asym |u| + noise (sd 0.05), ten cycles each."""
    out = []
    for k, amp in enumerate((1.0, 1.5)):
        t = np.linspace(0.0, 10.0, 500, endpoint=False)
        u = amp * np.sin(2 * np.pi * t)
        f = 2 * u + asym * np.abs(u) + np.random.default_rng(k).normal(0, 0.05, u.size)
        out.append(ShearTest(f"test{k}", t, u, f))
    return out


# --- a numerical failure in one step -----------------------------------------------------------
def test_an_effect_whose_refit_raises_linalgerror_is_skipped_with_the_reason_and_the_others_ranked(tmp_path):
    cal, ho = _tests()
    rep = diagnose(LinearModel(fail={"rollover"}), cal, [ho], effects=EFFECTS)
    assert rep.diagnosis == "asymmetry"
    assert sorted(s.effect for s in rep.ranking) == ["asymmetry", "degradation"]
    assert set(rep.skipped) == {"rollover"}
    assert "refit of linear+rollover" in rep.skipped["rollover"]
    assert "LinAlgError: Singular matrix" in rep.skipped["rollover"]
    assert not rep.complete
    out = rep.as_dict()
    assert out["complete"] is False and out["skipped"] == rep.skipped
    md = write_report(rep, tmp_path).read_text()
    assert "`rollover` skipped: refit of linear+rollover: LinAlgError: Singular matrix" in md


def test_without_a_significant_effect_a_skipped_effect_makes_the_verdict_incomplete_not_none():
    cal, ho = _tests(asym=0.0)
    rep = diagnose(LinearModel(fail={"asymmetry"}), cal, [ho], effects=EFFECTS)
    assert rep.diagnosis == "incomplete"
    assert any(n.startswith("incomplete diagnosis") and "asymmetry" in n for n in rep.notes)
    assert diagnose(LinearModel(), cal, [ho], effects=EFFECTS).diagnosis == "none"


def test_a_baseline_that_cannot_be_fitted_is_a_numerical_failure_naming_the_step():
    cal, ho = _tests()
    with pytest.raises(NumericalFailure, match="baseline fit of 'linear' on 'test0' failed: LinAlgError"):
        diagnose(LinearModel(fail={"*"}), cal, [ho], effects=["rollover"])


# --- time budget -------------------------------------------------------------------------------
def test_a_time_budget_ends_the_diagnosis_with_what_was_evaluated_and_lists_the_rest(tmp_path):
    """Every fit takes 100 s of the fake clock; budget 250 s: baseline (100), degradation (200),
    asymmetry interrupted inside its refit (300), rollover never started."""
    cal, ho = _tests()
    clock = Clock()
    rep = diagnose(LinearModel(clock=clock, cost=100.0), cal, [ho], effects=EFFECTS,
                   time_budget=ClockBudget(250.0, clock))
    assert [s.effect for s in rep.ranking] == ["degradation"]
    assert rep.not_evaluated == {"asymmetry": "time budget", "rollover": "time budget"}
    assert rep.diagnosis == "incomplete"  # never "none" with effects left untried
    assert "time budget of 250 s reached" in rep.budget_message
    assert "evaluated: degradation; not evaluated: asymmetry, rollover" in rep.budget_message
    out = rep.as_dict()
    assert out["diagnosis"] == "incomplete" and out["complete"] is False
    assert out["not_evaluated"] == {"asymmetry": "time budget", "rollover": "time budget"}
    assert out["time_budget"]["reached"] is True
    md = write_report(rep, tmp_path).read_text()
    assert "**Incomplete diagnosis.**" in md and "`rollover` not evaluated: time budget" in md


def test_a_time_budget_spent_during_the_baseline_raises_budget_exceeded_naming_the_baseline():
    cal, ho = _tests()
    clock = Clock()
    with pytest.raises(BudgetExceeded, match="baseline fit of 'linear' on 'test0' did not finish"):
        diagnose(LinearModel(clock=clock, cost=100.0), cal, [ho], effects=EFFECTS,
                 time_budget=ClockBudget(50.0, clock))


# --- checkpoint --------------------------------------------------------------------------------
def test_a_rerun_with_the_same_checkpoint_folder_refits_nothing_and_gives_the_same_result(tmp_path):
    cal, ho = _tests()
    first = LinearModel()
    rep1 = diagnose(first, cal, [ho], effects=EFFECTS, checkpoint=tmp_path)
    assert first.calls[:4] == ["linear", "linear+degradation", "linear+asymmetry", "linear+rollover"]
    again = LinearModel()
    rep2 = diagnose(again, cal, [ho], effects=EFFECTS, checkpoint=tmp_path)
    assert again.calls == []
    assert rep2.diagnosis == rep1.diagnosis == "asymmetry"
    assert [s.delta_holdout for s in rep2.ranking] == [s.delta_holdout for s in rep1.ranking]
    assert set(rep2.reused) >= {"baseline", "effect-degradation", "effect-asymmetry", "effect-rollover"}
    other_seed = LinearModel()
    diagnose(other_seed, cal, [ho], effects=EFFECTS, checkpoint=tmp_path, seed=1)
    assert other_seed.calls[:4] == first.calls[:4]  # another seed is another key


def test_a_rerun_after_the_budget_stopped_fits_only_the_effects_not_yet_evaluated(tmp_path):
    cal, ho = _tests()
    clock = Clock()
    diagnose(LinearModel(clock=clock, cost=100.0), cal, [ho], effects=EFFECTS,
             time_budget=ClockBudget(250.0, clock), checkpoint=tmp_path)
    resumed = LinearModel()
    rep = diagnose(resumed, cal, [ho], effects=EFFECTS, checkpoint=tmp_path)
    assert "linear" not in resumed.calls and "linear+degradation" not in resumed.calls
    assert resumed.calls[:2] == ["linear+asymmetry", "linear+rollover"]
    assert rep.complete and rep.diagnosis == "asymmetry"


# --- progress ----------------------------------------------------------------------------------
def test_progress_bar_goes_to_stderr_and_is_off_with_progress_false(capsys):
    cal, ho = _tests()
    diagnose(LinearModel(), cal, [ho], effects=["asymmetry"], progress=True)
    assert "gap linear" in capsys.readouterr().err
    diagnose(LinearModel(), cal, [ho], effects=["asymmetry"], progress=False)
    assert capsys.readouterr().err == ""


# --- the isolator model ------------------------------------------------------------------------
def _p1(n: int = 300) -> tuple[ShearTest, IsolatorFit]:
    """A plasticity loop and a fit object at its true parameters (no search)."""
    from rrfrei import simulate_force

    spec = get("plasticity")
    true = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}
    t = np.linspace(0, 30, n)
    u = 0.02 * np.sin(2 * np.pi * t / 10)
    f = simulate_force("plasticity", true, u, time=t) + np.random.default_rng(0).normal(0, 0.01, n)
    p = np.array([true[k] for k in spec.param_names])
    fit = IsolatorFit(spec=spec, p_opt=p, P=np.repeat(p[None], 10, axis=0), sig=np.full(10, 0.01),
                      sigma=0.01, noise=0.01, free=("k_init", "qd", "alpha1", "mu"), seed=0)
    return ShearTest("p", t, u, f), fit


def test_a_simulation_that_raises_inside_the_least_squares_search_is_a_bad_point(monkeypatch):
    import rrfrei.gap.isolator as gm

    test, start = _p1()
    real, calls = gm._simulate, [0]

    def flaky(spec, p, data, out=None):
        calls[0] += 1
        if calls[0] % 5 == 0:
            raise FloatingPointError("overflow in the local Newton")
        return real(spec, p, data, out)

    monkeypatch.setattr(gm, "_simulate", flaky)
    fit = IsolatorModel("plasticity", fixed={"alpha2": 0.0}, draws=10).fit(test, start=start)
    assert fit.params["qd"] == pytest.approx(0.6, rel=0.1)


def test_alaplace_covariance_from_a_non_finite_jacobian_is_a_numerical_failure_naming_where():
    J = np.array([[1.0, np.nan], [0.0, 1.0]])
    with pytest.raises(NumericalFailure, match="Laplace covariance of law 'x' on test 'y'"):
        laplace_cov(J, 1.0, 2, "law 'x' on test 'y'")


def test_a_laplace_precision_singular_in_floating_point_is_inverted_with_the_ridge_and_says_so():
    """Two collinear Jacobian columns of size 1e10 (a parameter pair stuck on the failure plateau):
    J^T J + I loses its unit ridge to rounding and np.linalg.inv raises "Singular matrix"."""
    J = np.full((4, 2), 1e10)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.inv(J.T @ J + np.eye(2))
    cov, note = laplace_cov(J, 1.0, 2, "law 'x' on test 'y'")
    assert np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) <= 1.0 + 1e-12)
    assert "singular in floating point" in note and "law 'x' on test 'y'" in note
    assert laplace_cov(np.eye(2), 1.0, 2, "w") == (pytest.approx(np.eye(2) / 2), "")


def test_an_isolator_fit_saved_for_a_checkpoint_restores_to_the_same_predictions():
    test, fit = _p1()
    model = IsolatorModel("plasticity")
    back = model.restore({k: np.asarray(v) for k, v in model.fit_state(fit).items()})
    assert back.name == fit.name and back.free == fit.free
    np.testing.assert_array_equal(back.predict(test).mean, fit.predict(test).mean)
    assert model.checkpoint_key(test) != IsolatorModel("plasticity", draws=50).checkpoint_key(test)


# --- CLI ---------------------------------------------------------------------------------------
def test_cli_baseline_failure_exits_1_naming_the_step(monkeypatch, capsys):
    def fail(self, data, **kw):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(IsolatorModel, "fit", fail)
    code = main(["gap", "protocol1", "--law", "plasticity", "--no-progress", "--effects", "asymmetry"])
    err = capsys.readouterr().err.strip()
    assert code == 1
    assert "baseline fit of 'plasticity' on 'protocol1' failed: LinAlgError: Singular matrix" in err
    assert "\n" not in err


def test_cli_time_budget_spent_in_the_baseline_exits_1_and_says_how_to_raise_it(capsys, tmp_path):
    code = main(["gap", "protocol1", "--law", "plasticity", "--no-progress", "--time-budget", "0.001",
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 1
    assert "time budget of 0 s reached" in err and "--time-budget" in err and "baseline" in err


@pytest.mark.parametrize("argv,msg", [
    (["--time-budget", "0"], "--time-budget"),
    (["--time-budget", "soon"], "--time-budget"),
])
def test_cli_bad_time_budget_is_a_user_error_exit_2(argv, msg, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["gap", "protocol1", *argv])
    assert exc.value.code == 2 and msg in capsys.readouterr().err


def test_cli_unreadable_test_file_is_a_user_error_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("this is not, a test\n1,2\n")
    code = main(["gap", str(bad), "--no-progress", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "bad.csv" in err and "\n" not in err


def test_cli_time_budget_none_means_no_limit():
    from rrfrei.budget import seconds_arg as time_budget_arg

    assert time_budget_arg("none") is None and time_budget_arg("90") == 90.0


@pytest.mark.parametrize("n_ok", [0, 1, 3])
def test_a_band_from_few_surviving_draws_is_as_wide_as_the_noise_and_says_why(n_ok):
    """Draws that fail on a held-out test (a law's local iteration, non-finite forces) are dropped;
    the band of the few that ran, or of the optimum alone, still spans the noise (95 %: about
    +- 1.96 sigma), never zero width, and the fit's note says how many draws failed."""
    spec = get("plasticity")
    u = 0.05 * np.sin(np.linspace(0.0, 4.0 * np.pi, 400))
    test = ShearTest("held", np.arange(u.size) * 0.05, u, np.zeros(u.size))
    p_opt = np.array([1000.0, 10.0, 0.1, 0.0, 2.0])  # k_init, qd, alpha1, alpha2, mu
    P = np.repeat(p_opt[None, :], 20, axis=0)
    P[n_ok:, 0] = np.nan  # these draws give non-finite forces
    sigma = 2.0
    fit = IsolatorFit(spec=spec, p_opt=p_opt, P=P, sig=np.full(20, sigma), sigma=sigma, noise=sigma,
                      free=tuple(q.name for q in spec.params))
    pr = fit.predict(test)
    width = pr.upper - pr.lower
    assert np.all(np.isfinite(width))
    assert 0.8 * 2 * 1.96 * sigma < np.median(width) < 1.2 * 2 * 1.96 * sigma
    assert f"{20 - n_ok} of 20 posterior draws failed" in fit.note


def _steep_bouc_wen_fit(n_draws=6):
    """A bouc_wen fit whose local Newton fails on the sample steps of a 0.17 m jump (eta 9.18)
    and succeeds with 4 sub-increments per sample."""
    spec = get("bouc_wen")
    p = spec.pack(dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=9.181247277429936,
                       beta=0.1979643833210143, gamma=0.28589263260021625))
    u = np.r_[np.linspace(0.0, 0.002, 8), -0.169674, -0.16, -0.15, -0.1]
    test = ShearTest("jump", np.arange(u.size, dtype=float), u, np.zeros(u.size), has_time=False)
    fit = IsolatorFit(spec=spec, p_opt=p, P=np.repeat(p[None], n_draws, axis=0),
                      sig=np.full(n_draws, 0.01), sigma=0.01, noise=0.01,
                      free=("k_init", "qd", "alpha1", "mu", "eta", "gamma"), seed=0)
    return spec, p, test, fit


def test_a_prediction_whose_local_solve_fails_is_retried_with_sub_increments_and_says_so():
    from rrfrei import simulate_force
    from rrfrei.gap.isolator import _simulate

    spec, p, test, fit = _steep_bouc_wen_fit()
    assert _simulate(spec, p, test)[0] == -2  # the sample steps fail
    pred = fit.predict(test)
    want = simulate_force("bouc_wen", spec.as_dict(p), test.disp, substeps=4)
    np.testing.assert_allclose(pred.mean, want, rtol=1e-14)  # the mean of six equal draws
    assert "ran with 4/16 sub-increments per sample" in fit.note


def test_a_prediction_that_fails_for_every_draw_and_the_optimum_is_a_numerical_failure_not_garbage(
        monkeypatch):
    """A failed driver leaves its force array uninitialised from the failing sample on; the
    prediction must never be read from it."""
    import rrfrei.gap.isolator as model

    _, _, test, fit = _steep_bouc_wen_fit()

    def failing(spec, p, data, out=None, substeps=1):
        F = np.full(len(data), 123.0) if out is None else out  # what a failed run leaves behind
        F[:] = 123.0
        return -2, F

    monkeypatch.setattr(model, "_simulate", failing)
    with pytest.raises(NumericalFailure, match=r"every posterior draw and the optimum fail \(status -2, "
                                               r"also with 16 sub-increments"):
        fit.predict(test)
    status, F, sub = model.simulate_retry(fit.spec, fit.p_opt, test)
    assert status == -2 and sub == 16 and np.all(np.isnan(F))
