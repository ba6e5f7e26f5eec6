"""The building as the model (structures.shake_table.building_model): a building simulated from the table
accelerations and calibrated by output error recovers the parameters it was simulated with, carries
the isolators' state from run to run, never lets a failed simulation end its optimiser, and its bands
are judged by coverage and width.

The runs here are cut from one simulation of a known building (plasticity isolators, five stories)
under two records with rest between them, so the truth is known.
"""

from __future__ import annotations

import numpy as np
import pytest

from structures.shake_table.building_model import BuildingModel
from structures.shake_table.sequence import CHANNELS, building_prediction, run_metrics
from structures.shake_table.simulation import (
    FIT_CHANNELS,
    BuildingData,
    Superstructure,
    measured_channels,
)
from tests._shake_table_truth import MASSES, PL, ZETA, K, model_of


def test_the_true_building_reproduces_every_run_it_was_simulated_with(truth):
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    x = np.array([{**PL, "k_scale": 1.0, "zeta": ZETA}[n] for n in m.layout.names])
    held = BuildingData(tuple(runs), observed=("run2",))
    st, out = m.simulate(x, held)
    assert st == 0
    for c in CHANNELS:
        meas = held.measured("run2")[c]
        np.testing.assert_allclose(out["run2"][c], meas, rtol=0, atol=1e-6 * np.max(np.abs(meas)), err_msg=c)


def test_a_held_out_run_starts_from_the_state_the_runs_before_it_left(truth):
    """The isolators yield in run 1 and keep a residual displacement: run 2 simulated alone (from a
    virgin, centred isolator) differs from run 2 driven after run 1, which is the measurement."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    x = np.array([{**PL, "k_scale": 1.0, "zeta": ZETA}[n] for n in m.layout.names])
    _, carried = m.simulate(x, BuildingData(tuple(runs), observed=("run2",)))
    _, alone = m.simulate(x, BuildingData((runs[1],)))
    meas = runs[1].isolator_force
    err_alone = np.sqrt(np.mean((alone["run2"]["isolator_force"] - meas) ** 2))
    err_carried = np.sqrt(np.mean((carried["run2"]["isolator_force"] - meas) ** 2))
    assert err_carried < 1e-6 * np.max(np.abs(meas)) < err_alone


def test_output_error_recovers_the_superstructure_scale_and_the_isolator_law(truth):
    """Identified stiffness 20 % too low and a loop start 25 % off: the output-error fit on run 1
    finds the stiffness scale (1 / 0.8) and the law, and predicts the held-out, larger run 2."""
    b, runs = truth
    sup = Superstructure(MASSES, K * 0.8, ZETA, np.full(5, 4.27), "biased identification")
    start = {**PL, "k_init": 1.25 * PL["k_init"], "qd": 0.75 * PL["qd"], "alpha1": 0.2}
    m = model_of(runs, sup, start)
    cal = BuildingData(tuple(runs), observed=("run1",))
    held = BuildingData(tuple(runs), observed=("run2",))
    fit = m.fit(cal, seed=0)
    p = fit.params
    assert p["k_scale"] == pytest.approx(1.25, rel=0.02)
    assert p["qd"] == pytest.approx(PL["qd"], rel=0.05)
    assert p["alpha1"] == pytest.approx(PL["alpha1"], rel=0.05)
    assert p["zeta"] == pytest.approx(ZETA, rel=0.15)
    pred = building_prediction(fit, {"run1": cal, "run2": held}, ["run1", "run2"])
    met = run_metrics(pred, "run2")
    assert met["isolator_disp"]["nrmse"] < 0.02
    assert abs(met["isolator_disp"]["peak_error"]) < 0.02
    assert fit.ess >= 1.0 and fit.X.shape == (8, len(fit.names))


def test_a_failing_simulation_is_a_bad_point_never_an_exception(truth, monkeypatch):
    """Every third of the search's first 30 simulations fails (as a law's local Newton may, here and
    there): the fit still ends at the truth, started 25 % off, and says how many failed."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), {**PL, "qd": 0.75 * PL["qd"]})
    m.global_evals = 0  # the local search alone: its count of failures is the injected one
    real = BuildingModel.simulate
    calls = {"n": 0}

    def flaky(self, x, data, tally=None):
        calls["n"] += 1
        if calls["n"] <= 30 and calls["n"] % 3 == 0:
            return -4, {}
        return real(self, x, data, tally)

    monkeypatch.setattr(BuildingModel, "simulate", flaky)
    fit = m.fit(BuildingData(tuple(runs), observed=("run1",)), seed=0)
    assert fit.failed == 10 and "10 of" in fit.note
    assert fit.params["qd"] == pytest.approx(PL["qd"], rel=0.05)
    assert fit.params["alpha1"] == pytest.approx(PL["alpha1"], rel=0.05)


def test_band_width_and_coverage_follow_their_definitions(truth):
    """A band of +-1 about a perfect median covers every sample and is 2 / RMS wide."""
    from structures.shake_table.sequence import SequencePrediction

    _, runs = truth
    meas = {"run1": measured_channels(runs[0])}
    med = {"run1": {c: v.copy() for c, v in meas["run1"].items()}}
    lo = {"run1": {c: v - 1.0 for c, v in meas["run1"].items()}}
    hi = {"run1": {c: v + 1.0 for c, v in meas["run1"].items()}}
    pred = SequencePrediction(law="x", runs=("run1",), time={"run1": runs[0].time}, measured=meas, median=med,
                              lower=lo, upper=hi, draws={})
    met = run_metrics(pred, "run1")
    for c in CHANNELS:
        rms = np.sqrt(np.mean(meas["run1"][c] ** 2))
        assert met[c]["coverage"] == 1.0
        assert met[c]["nrmse"] == 0.0 and met[c]["peak_error"] == 0.0
        assert met[c]["band_width"] == pytest.approx(2.0 / rms)


def test_blocks_are_time_windows_holding_every_fitted_channel(truth):
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    d = BuildingData(tuple(runs), observed=("run1", "run2"))
    g = m.groups(d)
    n = runs[0].time.size
    assert g.size == m.observed(d).size == 2 * n * len(FIT_CHANNELS)
    # the same window of one run has one label on every channel
    first = g[:n]
    for j in range(1, len(FIT_CHANNELS)):
        np.testing.assert_array_equal(g[j * n:(j + 1) * n], first)
    assert set(np.unique(g[: n * len(FIT_CHANNELS)])).isdisjoint(np.unique(g[n * len(FIT_CHANNELS):]))


def test_a_stronger_run_gets_a_proportionally_wider_band(truth):
    """The residual model is relative: with no parameter uncertainty, the band's width on each run
    is 2 x 1.96 sigma_c x the RMS of the run's predicted channel, so run 2 (1.8 x the input) gets a
    band wider in proportion to its response, not the calibration run's width."""
    from structures.shake_table.building_fit import BuildingFit

    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    x = np.array([{**PL, "k_scale": 1.0, "zeta": ZETA}[n] for n in m.layout.names])
    sig = {c: 0.1 for c in CHANNELS}
    fit = BuildingFit(model=m, x_opt=x, X=np.repeat(x[None, :], 4, axis=0), sigma_c=sig,
                      rho_c={c: 0.5 for c in FIT_CHANNELS}, ess=4.0)
    widths = {}
    for run in ("run1", "run2"):
        d = BuildingData(tuple(runs), observed=(run,))
        med, lo, hi = fit.band(d, run, "isolator_disp")
        rms = np.sqrt(np.mean(med**2))
        widths[run] = np.mean(hi - lo) / rms
        assert widths[run] == pytest.approx(2 * 1.96 * 0.1, rel=0.1)
    rms1 = np.sqrt(np.mean(runs[0].isolator_disp ** 2))
    rms2 = np.sqrt(np.mean(runs[1].isolator_disp ** 2))
    assert rms2 > 1.5 * rms1


def test_a_building_that_misses_its_own_calibration_runs_is_said_to_be_beyond_its_law():
    from structures.shake_table.gap import MISFIT_NRMSE, calibration_misfit

    # BNCS with `--law hdr`: the output-error building missed its calibration runs by 0.78-1.20
    note = calibration_misfit("hdr", {"isolator_disp": 1.20, "isolator_force": 0.78, "roof_accel": 0.30})
    assert note is not None and note.severity == "critical"
    assert "'hdr'" in note and "isolator_disp 1.20" in note and "roof_accel" not in note
    assert calibration_misfit("bouc_wen", {"isolator_disp": 0.11, "roof_accel": MISFIT_NRMSE}) is None
    assert calibration_misfit("hdr", {"isolator_disp": float("nan")}) is not None  # no number is no fit
