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
from structures.propagate import ResponseSet, propagate

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
    import structures.propagate as P

    def boom(*a, **k):
        raise AssertionError("a finished chunk was run again")

    monkeypatch.setattr(P, "run_chunk", boom)
    again = propagate(post, bld, recs, **kw)
    pd.testing.assert_frame_equal(first.table, again.table)
    with pytest.raises(ValueError, match="different inputs"):
        propagate(post, bld, recs, **{**kw, "seed": 9})


KILL_SCRIPT = textwrap.dedent("""
    import sys, time
    import numpy as np
    sys.path.insert(0, {tests!r})
    import structures.propagate as P
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
