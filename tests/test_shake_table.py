"""Shake-table runs: reading, consistency, the isolation system, superstructure identification and
prediction of a run (structures.shake_table, its modules identify and predict)."""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions
import rrfrei
import structures
from structures.building.shear_building import Isolator, ShearBuilding
from structures.shake_table import (
    BNCS_WEIGHTS_KN,
    ConsistencyWarning,
    ShakeTableRun,
    available_runs,
    check_consistency,
    isolation_metrics,
    isolation_test,
    load_run,
    read_run,
    write_run,
)
from structures.shake_table.identify import identify_superstructure
from structures.shake_table.predict import predict_run

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "shake_table_bncs"

# a BNCS-like building: the run's masses (t, base slab first), stories of 60-130 MN/m
MASSES = np.array(BNCS_WEIGHTS_KN) / 9.81
K_TRUE = np.array([125e3, 95e3, 98e3, 108e3, 60e3])
BW = dict(k_init=40000.0, qd=90.0, alpha1=0.08, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5)


def _building(isolator: Isolator, zeta: float = 0.04) -> ShearBuilding:
    return ShearBuilding(MASSES[1:], K_TRUE, [4.27] * 5, zeta, MASSES[0], isolator, name="bncs-like")


def _record(scale: float = 1.0, seconds: float = 30.0):
    r = ground_motions.load("elcentro")
    n = int(seconds / r.dt)
    return ground_motions.Record("elcentro", r.dt, scale * np.asarray(r.accel[:n]))


def _as_run(resp, record, masses, *, rng=None, accel_noise=0.0, disp_noise=0.0, name="sim") -> ShakeTableRun:
    """The channels of a simulated building exported as a shake-table run (optionally noisy)."""
    acc = np.column_stack([resp.base_accel_abs, resp.floor_accel_abs])
    disp = np.column_stack([resp.isolator_disp, resp.floor_disp])
    if rng is not None:
        acc = acc + accel_noise * acc.std(axis=0) * rng.standard_normal(acc.shape)
        disp = disp + disp_noise * rng.standard_normal(disp.shape)
    return ShakeTableRun(name=name, time=resp.time, table_accel=np.asarray(record.accel), accel=acc,
                         disp=disp, masses=masses, level_names=("base", "f2", "f3", "f4", "f5", "roof"))


@pytest.fixture(scope="module")
def simulated():
    """A Bouc-Wen-isolated BNCS-like building under 30 s of El Centro (100 Hz)."""
    b = _building(Isolator("bouc_wen", BW))
    rec = _record()
    return b, rec, structures.time_history(b, rec)


# ------------------------------------------------------------------------------------ reading
def test_bundled_runs_are_the_four_bncs_runs_at_50_hz_and_pass_the_consistency_check():
    assert available_runs() == ("CNP100", "ICA100", "ICA50", "LAC100")
    run = load_run("ICA50")
    assert run.rate_hz == pytest.approx(50.0)
    assert run.n_levels == 6 and run.level_names[0] == "base" and run.level_names[-1] == "roof"
    np.testing.assert_allclose(run.masses * 9.81, BNCS_WEIGHTS_KN, rtol=1e-9)
    assert run.consistency is not None and run.consistency.ok
    # a_i = d_i'' + a_g holds to within 1.1 % (RMS) on every level after the 5 Hz low-pass
    assert run.consistency.table["rel_error"].max() < 0.02


def test_bundled_run_is_the_shared_source_decimated_with_an_anti_alias_filter():
    if not SHARED.is_dir():
        raise FileNotFoundError(f"shared BNCS data missing: expected {SHARED} (../shared from the repo)")
    # CNP100's raw files number the levels from the base slab (a1 = base; the level-order check)
    src = read_run(SHARED / "CNP100", rate_hz=200, weights=BNCS_WEIGHTS_KN, a1="base")
    assert src.consistency.ok
    assert src.time.size == 8001
    bundled = load_run("CNP100")
    dec = src.decimate(50)
    # the bundle is written with 6 significant digits: half a unit in the 6th digit is 5e-6
    np.testing.assert_allclose(dec.accel, bundled.accel, rtol=5e-6, atol=1e-12)
    np.testing.assert_allclose(dec.disp, bundled.disp, rtol=5e-6, atol=1e-12)
    # base slab = source channel a1 of this run, roof = a6 (bottom-up order)
    a1 = np.loadtxt(SHARED / "CNP100" / "a1.txt.gz")
    np.testing.assert_array_equal(src.accel[:, 0], a1)


@pytest.mark.parametrize("name", ["CNP100", "LAC100", "ICA50", "ICA100"])
def test_every_bundled_run_is_bottom_up_by_its_physics(name):
    """The relative displacement and the absolute acceleration grow from the base slab to the roof
    (structures.check_level_order), and the story shears of the bundled masses follow the drifts
    of a shear building (R^2 >= 0.9 on every story, 1-15 Hz)."""
    from structures.shake_table import check_level_order, story_fit_r2

    run = load_run(name)
    assert check_level_order(run) == []
    assert story_fit_r2(run).min() >= 0.9


def test_csv_round_trip_with_weights_in_a_sidecar(tmp_path, simulated):
    b, rec, resp = simulated
    run = _as_run(resp, rec, MASSES)
    path = write_run(run, tmp_path / "sim.csv")
    # replace the masses by weights with a unit: the reader converts them back with g = 9.81
    (tmp_path / "sim.toml").write_text(
        'name = "sim"\n[levels]\nnames = ["base", "f2", "f3", "f4", "f5", "roof"]\n'
        f"weights = {list(BNCS_WEIGHTS_KN)}\nweight_unit = \"kN\"\n")
    back = read_run(path)
    np.testing.assert_allclose(back.accel, run.accel, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(back.disp, run.disp, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(back.masses, MASSES, rtol=1e-12)
    assert back.level_names == run.level_names


def test_csv_units_from_suffixes_are_converted_to_si(tmp_path):
    t = np.arange(200) * 0.01
    ag = np.sin(2 * np.pi * t)
    df = pd.DataFrame({"time_s": t, "table_accel_g": ag / 9.81,
                       "B_accel_abs_cmps2": 100 * ag, "B_disp_rel_mm": np.zeros_like(t)})
    df.to_csv(tmp_path / "r.csv", index=False)
    run = read_run(tmp_path / "r.csv", masses=[10.0], check=False)
    np.testing.assert_allclose(run.table_accel, ag, rtol=1e-12)
    np.testing.assert_allclose(run.accel[:, 0], ag, rtol=1e-12)


def test_folder_layout_reads_roof_first_files_into_bottom_up_order(tmp_path):
    n = 300
    t = np.arange(n) / 100.0
    u = np.sin(2 * np.pi * 0.5 * t)
    for i in (1, 2):
        with gzip.open(tmp_path / f"a{i}.txt.gz", "wt") as fh:
            np.savetxt(fh, u * i)
        np.savetxt(tmp_path / f"d{i}.txt", np.zeros(n))
    np.savetxt(tmp_path / "u.txt", u)
    run = read_run(tmp_path, rate_hz=100, masses=[5.0, 1.0], check=False)
    np.testing.assert_allclose(run.accel[:, 0], 2 * u)  # a2 is the base slab (bottom)
    np.testing.assert_allclose(run.accel[:, 1], u)  # a1 is the roof
    np.testing.assert_allclose(run.masses, [5.0, 1.0])


@pytest.mark.parametrize("mutate, match", [
    (lambda df: df.drop(columns=["roof_disp_rel_m"]), "roof_disp_rel"),
    (lambda df: df.assign(f2_accel_abs_mps2=df["f2_accel_abs_mps2"].astype(object).where(
        df.index != 7, "x")), r"f2_accel_abs_mps2.*row 9.*'x'"),
    (lambda df: df.rename(columns={"table_accel_mps2": "table_accel_furlong"}), "no accel unit suffix"),
])
def test_malformed_csv_names_the_column_and_value(tmp_path, simulated, mutate, match):
    b, rec, resp = simulated
    run = _as_run(resp, rec, MASSES)
    write_run(run, tmp_path / "sim.csv")
    mutate(pd.read_csv(tmp_path / "sim.csv")).to_csv(tmp_path / "sim.csv", index=False)
    with pytest.raises(ValueError, match=match):
        read_run(tmp_path / "sim.csv")


def test_missing_masses_and_missing_files_are_clear_errors(tmp_path):
    np.savetxt(tmp_path / "a1.txt", np.zeros(20))
    np.savetxt(tmp_path / "u.txt", np.zeros(20))
    with pytest.raises(ValueError, match="d1.txt"):
        read_run(tmp_path, rate_hz=100, masses=[1.0])
    np.savetxt(tmp_path / "d1.txt", np.zeros(20))
    with pytest.raises(ValueError, match="no level masses.*BNCS_WEIGHTS_KN"):
        read_run(tmp_path, rate_hz=100)
    with pytest.raises(ValueError, match="sampling rate"):
        read_run(tmp_path, masses=[1.0])
    with pytest.raises(ValueError, match="does not exist"):
        read_run(tmp_path / "nope.csv")


def test_a_displacement_channel_inconsistent_with_its_acceleration_is_reported(simulated):
    """Physical fact: a_i = d_i'' + a_g.  A roof displacement recorded at the wrong scale breaks it
    for that level only; the report names it and reading warns."""
    b, rec, resp = simulated
    good = _as_run(resp, rec, MASSES)
    assert check_consistency(good).ok
    disp = np.array(good.disp)
    disp[:, -1] *= 1.5
    bad = ShakeTableRun("bad", good.time, good.table_accel, good.accel, disp, good.masses, good.level_names)
    rep = check_consistency(bad)
    assert not rep.ok
    assert list(rep.table.loc[~rep.table["passed"], "channel"]) == ["roof"]
    assert "roof" in rep.failures[0]


def test_read_run_warns_on_inconsistent_channels(tmp_path, simulated):
    b, rec, resp = simulated
    good = _as_run(resp, rec, MASSES)
    disp = np.array(good.disp)
    disp[:, 2] = np.roll(disp[:, 2], 25)  # 0.25 s timing error in one displacement channel
    write_run(ShakeTableRun("bad", good.time, good.table_accel, good.accel, disp, good.masses,
                            good.level_names), tmp_path / "bad.csv")
    with pytest.warns(ConsistencyWarning, match="f3"):
        run = read_run(tmp_path / "bad.csv")
    assert not run.consistency.ok


@settings(max_examples=20, deadline=None)
@given(q=st.sampled_from([2, 4, 5]), f=st.floats(0.2, 3.0))
def test_decimation_keeps_a_band_limited_signal(q, f):
    """A sine well below the new Nyquist frequency passes the anti-alias filter unchanged."""
    fs = 200.0
    t = np.arange(4000) / fs
    x = np.sin(2 * np.pi * f * t)
    run = ShakeTableRun("s", t, x, x[:, None], np.zeros((t.size, 1)), [1.0], ("b",))
    d = run.decimate(fs / q)
    core = slice(40, -40)  # away from the filter's end transients
    np.testing.assert_allclose(d.accel[core, 0], x[::q][core], atol=2e-3)


def test_decimate_rejects_a_rate_that_is_not_an_integer_divisor():
    t = np.arange(100) / 200.0
    run = ShakeTableRun("s", t, t, t[:, None], t[:, None], [1.0], ("b",))
    with pytest.raises(ValueError, match="rate_hz = 70"):
        run.decimate(70)


# ------------------------------------------------------------------------------------ isolation system
def test_force_from_a_simulated_run_is_the_isolator_force_the_simulation_used(simulated):
    """Equilibrium of everything above the isolators: F_iso = -sum m_i a_i (the story forces are
    internal; no damping to the ground with stiffness-proportional damping)."""
    b, rec, resp = simulated
    test = isolation_test(_as_run(resp, rec, MASSES))
    assert isinstance(test, rrfrei.ShearTest) and test.has_time
    scale = np.max(np.abs(resp.isolator_force))
    np.testing.assert_allclose(test.force, resp.isolator_force, rtol=0, atol=1e-8 * scale)
    np.testing.assert_array_equal(test.disp, resp.isolator_disp)


def test_isolation_metrics_recover_the_bilinear_characteristic_strength(simulated):
    """For Bouc-Wen with eta = 1 and beta = gamma = 0.5 the loop is nearly bilinear: at zero
    displacement the force is +-(1 - alpha1) qd once yielded; large cycles must show it."""
    b, rec, resp = simulated
    m = isolation_metrics(_as_run(resp, rec, MASSES))
    big = m[(m["d_pos"] - m["d_neg"]) > 0.5 * (m["d_pos"] - m["d_neg"]).max()]
    assert len(big) >= 2
    qd_model = (1 - BW["alpha1"]) * BW["qd"]
    np.testing.assert_allclose(big["qd"], qd_model, rtol=0.1)
    assert (big["k_eff"] > BW["alpha1"] * BW["k_init"]).all()
    assert ((big["beta_eff"] > 0) & (big["beta_eff"] < 0.64)).all()  # 2/pi bounds a rigid-plastic loop


def test_isolation_test_of_a_real_run_is_accepted_by_calibration_tools():
    run = load_run("CNP100")
    test = isolation_test(run)
    assert test.name == "CNP100" and len(test) == run.time.size
    assert np.max(np.abs(test.disp)) == pytest.approx(0.0873, abs=1e-3)
    # the force follows the displacement: secant stiffness 3,000-6,000 kN/m on the large cycles
    m = isolation_metrics(run)
    big = m[(m["d_pos"] - m["d_neg"]) > 0.05]
    assert ((big["k_eff"] > 3000) & (big["k_eff"] < 6000)).all()


# ------------------------------------------------------------------------------------ identification
def test_identification_recovers_story_stiffness_of_a_simulated_building_with_noise(simulated):
    """Noise, white: 2 % of each acceleration channel's RMS and 20 micrometres on each displacement.
    Tolerance 2 % on k: in the 1-15 Hz band the drift noise is ~15 micrometres against a drift RMS
    of 200-460 micrometres, so errors in the regressor attenuate k by (noise/drift)^2 <= 0.6 %,
    and the bootstrap SE is 0.15-0.3 %; 2 % is that bias plus more than 4 SE.  c gets 15 %: the
    derivative amplifies the displacement noise, so the drift-rate regressor is noisier (bias up to
    8 % on the stiffest-to-drift story over seeds 0-2)."""
    b, rec, resp = simulated
    run = _as_run(resp, rec, MASSES, rng=np.random.default_rng(1), accel_noise=0.02, disp_noise=2e-5)
    ident = identify_superstructure(run, seed=0, n_boot=100)
    np.testing.assert_allclose(ident.stiffness, K_TRUE, rtol=0.02)
    c_true, _ = b.damping_coefficients()
    np.testing.assert_allclose(ident.damping, c_true, rtol=0.15)
    assert ident.damping_ratio() == pytest.approx(b.damping_ratio, rel=0.15)
    assert (ident.r2 > 0.95).all()
    # the bootstrap interval is honest about its scatter: the truth lies within 4 SE
    assert (np.abs(ident.stiffness - K_TRUE) < 4 * ident.stiffness_se + 0.01 * K_TRUE).all()
    # and the identified building reproduces the fixed-base periods
    nb = ident.building(Isolator("bouc_wen", BW))
    np.testing.assert_allclose(nb.fixed_base_modes()[0], b.fixed_base_modes()[0], rtol=0.02)


def test_identification_is_reproducible_from_its_seed(simulated):
    b, rec, resp = simulated
    run = _as_run(resp, rec, MASSES)
    a = identify_superstructure(run, seed=3, n_boot=20)
    c = identify_superstructure(run, seed=3, n_boot=20)
    np.testing.assert_array_equal(a.boot, c.boot)


def test_identification_of_a_real_run_gives_positive_stiffness_with_good_fit():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ident = identify_superstructure(load_run("ICA50"), n_boot=50)
    assert (ident.stiffness > 0).all() and (ident.r2 > 0.9).all()
    assert (ident.stiffness_se < 0.05 * ident.stiffness).all()


def test_identification_rejects_a_band_above_nyquist():
    with pytest.raises(ValueError, match="band_hz"):
        identify_superstructure(load_run("CNP100"), band_hz=(1.0, 30.0))


# ------------------------------------------------------------------------------------ prediction
@pytest.fixture(scope="module")
def linear_case():
    """A linear-isolator building, its run, and a posterior of the layer law from that run."""
    iso = Isolator("linear", {"k": 4000.0, "c": 150.0})
    b = _building(iso)
    rec = _record(seconds=20.0)
    run = _as_run(structures.time_history(b, rec), rec, MASSES, name="lin")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = rrfrei.calibrate(isolation_test(run), "linear", seed=0, steps=300, progress=False,
                               priors={"c": {"kind": "loguniform", "a": 1.0, "b": 1e4}})
    return b, rec, run, cal


def test_prediction_of_a_run_by_its_own_model_is_near_exact(linear_case):
    b, rec, run, cal = linear_case
    ident = identify_superstructure(run, n_boot=20)
    pred = predict_run(cal, ident.building(cal), run, n_draws=20, progress=False)
    assert pred.n_failed == 0 and not pred.extrapolates
    assert pred.peak_ratio == pytest.approx(1.0)
    for ch in ("isolator_disp", "base_shear", "accel_roof"):
        assert pred.nrmse[ch] < 0.02, (ch, pred.nrmse[ch])
        assert abs(pred.peak_error[ch]) < 0.02
    assert set(pred.coverage) >= {"drift_1", "drift_5", "accel_base"}


def test_prediction_beyond_the_calibrated_displacement_warns_and_states_the_ratio(linear_case, tmp_path):
    b, rec, run, cal = linear_case
    rec2 = ground_motions.Record("x2", rec.dt, 2.0 * np.asarray(rec.accel))
    run2 = _as_run(structures.time_history(b, rec2), rec2, MASSES, name="lin x2")
    with pytest.warns(UserWarning, match="2.00 x the largest isolator displacement"):
        pred = predict_run(cal, b.with_isolator_params(cal.map_params()), run2, n_draws=5, progress=False)
    assert pred.extrapolates and pred.peak_ratio == pytest.approx(2.0, rel=1e-3)
    fig = pred.plot(path=tmp_path / "p.png", time_window=(0, 10))
    assert (tmp_path / "p.png").stat().st_size > 0
    assert fig.axes[0].get_xlabel() == "time [s]" and "[m]" in fig.axes[0].get_ylabel()


def test_prediction_rejects_a_building_with_the_wrong_number_of_stories(linear_case):
    b, rec, run, cal = linear_case
    short = ShearBuilding(MASSES[1:3], K_TRUE[:2], [4.0, 4.0], 0.05, MASSES[0], b.isolator)
    with pytest.raises(ValueError, match="2 stories"):
        predict_run(cal, short, run, progress=False)
