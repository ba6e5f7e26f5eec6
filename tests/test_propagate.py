"""Posterior propagation on real buildings: executors, Dask, the resumable store, convergence.

* the same inputs and seed give the same table whether the chunks run here, on a thread pool or on
  a Dask ``LocalCluster`` (two workers on loopback);
* a run killed mid-way and resumed from its store gives the same table as an uninterrupted run,
  with no lost and no duplicated rows;
* on a nearly rigid superstructure over a linear isolator (an SDOF), each run's peak isolator
  displacement is the record's spectral displacement at T(k) (``ground_motions.response_spectrum``,
  an independent exact recurrence), and the empirical percentiles converge to the exact ones as the
  number of samples grows.
"""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ground_motions
import structures
from rrfrei.laws import get as get_law
from structures.propagation.propagate import ResponseSet, propagate

ROOT = Path(__file__).resolve().parents[1]


def draws_around(building, n: int, seed: int, spread: float = 0.1) -> pd.DataFrame:
    """A stand-in posterior: the building's own isolator parameters, lognormally perturbed.

    Geometry parameters stay fixed; ``attrs`` carry the law and a calibrated range of +-0.1 m.
    """
    iso = building.isolator
    spec = get_law(iso.law)
    base = spec.as_dict(np.asarray(iso.params, dtype=float)) if not isinstance(iso.params, dict) \
        else dict(iso.params)
    rng = np.random.default_rng(seed)
    cols = {}
    for p in spec.params:
        x = float(base.get(p.name, p.default if p.default is not None else 0.0))
        if p.geometry or p.optional or x == 0.0:
            cols[p.name] = np.full(n, x)
        else:
            cols[p.name] = np.clip(x * np.exp(rng.normal(0.0, spread, n)), p.lower, p.upper)
    df = pd.DataFrame(cols)
    df.attrs.update(law=spec.name, disp_min_m=-0.1, disp_max_m=0.1)
    return df


def short(name: str, seconds: float) -> ground_motions.Record:
    """The first ``seconds`` of a bundled record (keeps the tests fast)."""
    r = ground_motions.load(name)
    n = int(seconds / r.dt) + 1
    return ground_motions.Record(r.name, r.dt, r.accel[:n], r.meta)


@pytest.fixture(scope="module")
def five():
    return structures.load_building("five_story")


@pytest.fixture(scope="module")
def small_case(five):
    post = draws_around(five, 400, seed=1)
    recs = [short("elcentro", 6.0), short("kocaeli", 6.0)]
    return post, five, recs


# ------------------------------------------------------------------------------------ interface
def test_a_posterior_of_another_law_is_refused(five):
    law = "linear" if get_law(five.isolator.law).name != "linear" else "plasticity"
    df = pd.DataFrame({"k": [1.0e3]})
    df.attrs["law"] = law
    with pytest.raises(ValueError, match="isolator uses"):
        propagate(df, five, ["elcentro"], n_samples=2, progress=False)


@pytest.mark.parametrize(
    ("kw", "match"),
    [({"n_samples": 0}, "n_samples"), ({"scales": (1.0, -2.0)}, "scales"),
     ({"chunk_size": 0}, "chunk_size"), ({"seed": -1}, "seed")],
)
def test_bad_arguments_are_named_in_the_error(small_case, kw, match):
    post, bld, recs = small_case
    with pytest.raises(ValueError, match=match):
        propagate(post, bld, recs, progress=False, **kw)


def test_table_has_one_row_per_sample_record_and_scale_with_units_in_names(small_case):
    post, bld, recs = small_case
    rs = propagate(post, bld, recs, n_samples=6, scales=(0.5, 1.0), chunk_size=4, progress=False)
    assert isinstance(rs, ResponseSet)
    t = rs.table
    assert len(t) == 6 * 2 * 2
    assert not t.duplicated(["sample", "record", "scale"]).any()
    n_st = len([c for c in t.columns if c.startswith("drift_ratio_s")])
    assert n_st == 5
    for c in ("iso_disp_peak_m", "iso_disp_residual_m", "drift_ratio_max", "floor_acc_max_ms2",
              "base_shear_peak_kN", "iso_energy_kNm", "energy_error", "converged", "extrapolated"):
        assert c in t.columns
    assert t["converged"].all()
    # the isolator dissipates energy, the drift envelope is the largest story drift
    assert (t["iso_energy_kNm"] >= 0).all()
    stories = [f"drift_ratio_s{j}" for j in range(1, 6)]
    np.testing.assert_array_equal(t["drift_ratio_max"], t[stories].max(axis=1))
    # default limits: tested isolator displacement (prototype) and 0.5 % drift
    assert rs.limits["drift_ratio_max"] == 0.005
    assert rs.limits["iso_disp_peak_m"] == pytest.approx(0.1 * bld.isolator.length_scale)


def test_extrapolation_flag_marks_runs_beyond_the_calibrated_range_times_the_length_scale(small_case):
    post, bld, recs = small_case
    rs = propagate(post, bld, recs[:1], n_samples=8, progress=False)
    peak = rs.table["iso_disp_peak_m"].to_numpy()
    s = bld.isolator.length_scale
    tight = post.copy()
    tight.attrs.update(law=post.attrs["law"], disp_min_m=-np.median(peak) / s, disp_max_m=np.median(peak) / s)
    flag = propagate(tight, bld, recs[:1], n_samples=8, progress=False).table["extrapolated"].to_numpy(bool)
    assert flag.any() and not flag.all()
    np.testing.assert_array_equal(flag, peak > np.median(peak) * (1 + 1e-9))


# ------------------------------------------------------------------------------------ executors
def test_thread_pool_and_local_runs_give_identical_tables(small_case):
    post, bld, recs = small_case
    kw = dict(n_samples=10, scales=(1.0,), chunk_size=3, progress=False, seed=4)
    local = propagate(post, bld, recs, **kw)
    with ThreadPoolExecutor(max_workers=2) as ex:
        pooled = propagate(post, bld, recs, executor=ex, **kw)
    pd.testing.assert_frame_equal(local.table, pooled.table)


def test_dask_local_cluster_gives_the_same_table_as_the_local_run(small_case):
    distributed = pytest.importorskip("distributed")
    post, bld, recs = small_case
    kw = dict(n_samples=8, scales=(1.0, 1.5), chunk_size=4, progress=False, seed=2)
    local = propagate(post, bld, recs, **kw)
    # two workers talking TCP on loopback (every task and result is serialised over the socket);
    # processes=False keeps the start-up under a second and reuses this process's compiled kernels
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://",
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        remote = propagate(post, bld, recs, executor=client, **kw)
    pd.testing.assert_frame_equal(local.table, remote.table)


# ------------------------------------------------------------------------------------ store
def test_rerun_with_the_same_store_skips_every_finished_chunk(small_case, tmp_path, monkeypatch):
    post, bld, recs = small_case
    kw = dict(n_samples=6, chunk_size=3, progress=False, store=tmp_path / "s")
    first = propagate(post, bld, recs, **kw)
    P = importlib.import_module("structures.propagation.propagate")

    def boom(*a, **k):
        raise AssertionError("a finished chunk was run again")

    monkeypatch.setattr(P, "run_chunk", boom)  # the module (structures.propagate is the function)
    again = propagate(post, bld, recs, **kw)
    pd.testing.assert_frame_equal(first.table, again.table)
    with pytest.raises(ValueError, match="different inputs"):
        propagate(post, bld, recs, **{**kw, "seed": 9})


KILL_SCRIPT = textwrap.dedent("""
    import sys, time
    import numpy as np
    sys.path.insert(0, {tests!r})
    import importlib
    P = importlib.import_module("structures.propagation.propagate")
    from test_propagate import draws_around, short
    import structures
    bld = structures.load_building("five_story")
    real = P.run_chunk
    def slow(*a, **k):  # make the run long enough to be killed in the middle
        out = real(*a, **k)
        time.sleep(0.4)
        return out
    P.run_chunk = slow
    P.propagate(draws_around(bld, 400, seed=1), bld, [short("elcentro", 4.0), short("kocaeli", 4.0)],
                n_samples=12, scales=(1.0, 2.0), chunk_size=2, progress=False, store={store!r})
""")


def test_a_killed_run_resumes_with_no_lost_and_no_duplicated_rows(small_case, tmp_path):
    post, bld, _ = small_case
    store = tmp_path / "store"
    script = KILL_SCRIPT.format(tests=str(ROOT / "tests"), store=str(store))
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, env={**os.environ},
                            stderr=subprocess.PIPE, start_new_session=True)
    total = 2 * 2 * 6  # records x scales x chunks
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        done = len(list(store.glob("part-*.parquet"))) if store.exists() else 0
        if 3 <= done:
            break
        time.sleep(0.05)
    if proc.poll() is not None:
        pytest.fail(f"the run ended before it could be killed: {proc.stderr.read().decode()[-2000:]}")
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(list(store.glob("part-*.parquet")))
    assert 3 <= done < total
    recs = [short("elcentro", 4.0), short("kocaeli", 4.0)]
    kw = dict(n_samples=12, scales=(1.0, 2.0), chunk_size=2, progress=False)
    resumed = propagate(post, bld, recs, store=store, **kw)
    fresh = propagate(post, bld, recs, **kw)
    assert len(resumed.table) == 12 * 2 * 2
    assert not resumed.table.duplicated(["sample", "record", "scale"]).any()
    pd.testing.assert_frame_equal(resumed.table, fresh.table)


# ------------------------------------------------------------------------------------ convergence
ZETA = 0.05
K0, SIG = 1750.0, 0.3  # median [kN/m] and log-sd of the isolator stiffness


def _sdof_building() -> structures.ShearBuilding:
    """A 50 t slab on a 50 t base, story 1e7 kN/m (0.014 s: rigid next to T ~ 1.5 s), no damping.

    On a linear isolator (k, c) it is an SDOF of mass M = 100 t: T = 2 pi sqrt(M / k) and
    zeta = c / (2 sqrt(k M)).
    """
    return structures.ShearBuilding(
        story_masses=[50.0], story_stiffness=[1.0e7], story_heights=[3.0], damping_ratio=0.0,
        base_mass=50.0, isolator=structures.Isolator("linear", {"k": K0, "c": 0.0}, 1, 1.0),
    )


def _lognormal_stiffness_posterior(n: int, seed: int) -> pd.DataFrame:
    k = K0 * np.exp(SIG * np.random.default_rng(seed).standard_normal(n))
    df = pd.DataFrame({"k": k, "c": 2.0 * ZETA * np.sqrt(k * 100.0)})
    df.attrs["law"] = "linear"
    return df


def _exact_quantiles(record, q) -> np.ndarray:
    """Quantiles of Sd(T(k)) for k ~ LogNormal(ln K0, SIG): Sd on 4000 stratified quantiles of k."""
    from scipy import stats

    kq = K0 * np.exp(SIG * stats.norm.ppf((np.arange(4000) + 0.5) / 4000))
    sd = ground_motions.response_spectrum(record, 2 * np.pi * np.sqrt(100.0 / kq), ZETA).sd
    return np.quantile(sd, q)


@pytest.fixture(scope="module")
def sdof_case():
    return _sdof_building(), ground_motions.load("rinaldi"), _lognormal_stiffness_posterior(20_000, 7)


def test_each_run_on_a_rigid_building_over_a_linear_isolator_peaks_at_the_spectral_displacement(sdof_case):
    bld, rec, post = sdof_case
    rs = propagate(post, bld, [rec], n_samples=40, seed=3, progress=False)
    k = rs.draws["k"].to_numpy()
    sd = ground_motions.response_spectrum(rec, 2 * np.pi * np.sqrt(100.0 / k), ZETA).sd
    # Newmark (average acceleration, dt = 0.01 s) vs. the exact recurrence: period error ~ (w dt)^2/12
    np.testing.assert_allclose(rs.table["iso_disp_peak_m"].to_numpy(), sd, rtol=2e-3)


def _percentile_errors(case, sizes, seeds) -> dict[int, float]:
    """RMS relative error of the 2.5/16/50/84/97.5 % percentiles vs. the exact ones, mean over seeds."""
    bld, rec, post = case
    q = [0.025, 0.16, 0.5, 0.84, 0.975]
    exact = _exact_quantiles(rec, q)
    err = {}
    for n in sizes:
        e = []
        for seed in seeds:
            rs = propagate(post, bld, [rec], n_samples=n, seed=seed, progress=False, chunk_size=200)
            got = np.quantile(rs.table["iso_disp_peak_m"], q)
            e.append(np.sqrt(np.mean((got / exact - 1.0) ** 2)))
        err[n] = float(np.mean(e))
    return err


def test_demand_percentiles_converge_to_the_exact_ones_as_samples_grow(sdof_case):
    """Percentile error (mean over 4 seeds) falls like a Monte Carlo error, ~ 1/sqrt(n)."""
    err = _percentile_errors(sdof_case, (25, 400), range(4))
    # Monte Carlo error ~ n^-1/2: 16x the samples -> about 4x smaller; at least 2x
    assert err[400] < err[25] / 2.0, err
    assert err[400] < 0.05, err


@pytest.mark.slow
def test_percentile_error_decays_at_the_monte_carlo_rate(sdof_case):
    """Over n = 16 ... 1024 (12 seeds each) the log-log slope of the error is about -1/2."""
    sizes = (16, 64, 256, 1024)
    err = _percentile_errors(sdof_case, sizes, range(12))
    slope = np.polyfit(np.log(sizes), np.log([err[n] for n in sizes]), 1)[0]
    assert -0.8 < slope < -0.3, (slope, err)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:calibration of .* has NOT converged")  # 20 steps on purpose
def test_cli_writes_the_table_and_figures_that_the_api_computes(tmp_path):
    """`rrfrei propagate` on a real (short) calibration: same table as the API, figures, JSON summary."""
    import json

    from rrfrei.calibration import calibrate
    from rrfrei.io import load_test

    cal = calibrate(load_test("protocol1"), "bouc_wen", steps=20, walkers=32, progress=False, seed=0)
    nc = cal.to_netcdf(tmp_path / "posterior.nc")
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "rrfrei.app", "propagate", "--posterior", str(nc),
            "--building", "five_story", "--records", "rinaldi,tabas", "--samples", "6",
            "--scales", "0.5,1,2", "--seed", "3",
            "--out", str(out), "--json", "--no-progress"]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    body = json.loads(proc.stdout)
    assert body["law"] == "bouc_wen" and body["samples"] == 6
    assert body["limits"]["iso_disp_peak_m"] == pytest.approx(3.0 * cal.test.disp.max())
    for name in ("responses.parquet", "responses.csv", "summary.csv", "variance_split.csv", "exceedance.csv",
                 "fragility.csv", "fragility.png", "distribution_iso_disp_peak_m.png",
                 "exceedance_drift_ratio_max.png"):
        assert (out / name).stat().st_size > 0, name
    api = propagate(nc, "five_story", ["rinaldi", "tabas"], n_samples=6, scales=(0.5, 1.0, 2.0), seed=3,
                    progress=False)
    pd.testing.assert_frame_equal(pd.read_parquet(out / "responses.parquet"), api.table)
