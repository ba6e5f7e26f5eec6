"""Posterior propagation on the plan building under record pairs (the code's answers over draws).

* a pair whose y component is zero gives the 1-D propagation's answers, draw by draw (the coupled
  plasticity law reduces to the 1-D law along an axis, bit for bit);
* the plan displacement is never below either direction's, and the batch kernel and one plan time
  history per draw give the same table;
* over a suite of 2 pairs the design value of each draw is the larger pair's (fewer than 7);
* a run resumed from its store gives the same table; a store made for other bounds is refused;
* the lower-bound draws are the nominal ones with their force-like parameters x lambda.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import ground_motions
import structures
from structures.propagation.plan_design import TorsionAmplification
from structures.propagation.plan_propagate import design_distribution, propagate_pairs, suite_design
from structures.propagation.propagate import propagate
from tests._plan_fake import pair_from
from tests.test_propagate import draws_around

SECONDS = 6.0


@pytest.fixture(scope="module")
def three():
    return structures.load_building("three_story")


@pytest.fixture(scope="module")
def post(three):
    return draws_around(three, 6, seed=2)


@pytest.fixture(scope="module")
def pairs():
    return [pair_from(ground_motions.load("elcentro"), SECONDS, name="elcentro2"),
            pair_from(ground_motions.load("kocaeli"), SECONDS, y_factor=1.2, delay=1.0, name="kocaeli2")]


@pytest.fixture(scope="module")
def plan_rs(three, post, pairs):
    return propagate_pairs(post, three, pairs, n_samples=4, seed=5, chunk_size=3, progress=False)


def test_a_pair_along_x_gives_the_one_directional_answers(three, post):
    rec = ground_motions.load("elcentro")
    along_x = pair_from(rec, SECONDS, y_factor=0.0, name="elcentro")
    n = int(SECONDS / rec.dt) + 1
    one = ground_motions.Record("elcentro", rec.dt, rec.accel[:n])
    rs2 = propagate_pairs(post, three, [along_x], n_samples=4, seed=5, progress=False)
    rs1 = propagate(post, three, [one], n_samples=4, seed=5, progress=False)
    pd.testing.assert_frame_equal(rs2.draws, rs1.draws)
    for col in ("iso_disp_peak_m", "iso_disp_residual_m", "drift_ratio_max", "floor_acc_max_ms2",
                "base_shear_peak_kN", "iso_energy_kNm"):
        np.testing.assert_allclose(rs2.table[col], rs1.table[col], rtol=1e-12, atol=1e-15, err_msg=col)
    np.testing.assert_allclose(rs2.table["iso_disp_x_peak_m"], rs1.table["iso_disp_peak_m"], rtol=1e-12)
    assert (rs2.table["iso_disp_y_peak_m"] == 0.0).all()
    assert (rs2.table["base_shear_y_peak_kN"] == 0.0).all()
    pd.testing.assert_series_equal(rs2.table["extrapolated"], rs1.table["extrapolated"])


def test_the_plan_displacement_bounds_both_directions_and_the_kernels_agree(three, post, pairs, plan_rs):
    t = plan_rs.table
    assert t["converged"].all() and len(t) == 2 * 4
    assert (t["iso_disp_peak_m"] >= t[["iso_disp_x_peak_m", "iso_disp_y_peak_m"]].max(axis=1)).all()
    hyp = np.hypot(t["iso_disp_x_peak_m"], t["iso_disp_y_peak_m"])
    assert (t["iso_disp_peak_m"] <= hyp * (1 + 1e-12)).all()
    assert (t["iso_disp_y_peak_m"] > 0.0).all()
    np.testing.assert_array_equal(t["total_max_disp_m"], t["iso_disp_peak_m"])  # no torsion
    per_run = propagate_pairs(post, three, pairs, n_samples=4, seed=5, chunk_size=3, progress=False,
                              simulate=structures.plan_time_history)
    for col in ("iso_disp_peak_m", "iso_disp_x_peak_m", "iso_disp_y_peak_m", "base_shear_x_peak_kN",
                "base_shear_y_peak_kN", "drift_ratio_max", "floor_acc_max_ms2", "iso_energy_kNm"):
        np.testing.assert_allclose(per_run.table[col], t[col], rtol=1e-12, err_msg=col)
    assert set(plan_rs.summary()["demand"]) >= {"iso_disp_peak_m", "drift_ratio_max"}


def test_two_pairs_take_the_larger_pair_per_draw(plan_rs):
    d = suite_design(plan_rs)
    assert len(d) == 4 and (d["rule"] == "maximum").all() and (d["n_pairs"] == 2).all()
    wide = plan_rs.table.pivot_table(index="sample", columns="record", values="iso_disp_peak_m")
    np.testing.assert_allclose(d.set_index("sample")["plan_disp_max_m"], wide.max(axis=1))
    dist = design_distribution(plan_rs)
    row = dist[dist["answer"] == "plan_disp_max_m"].iloc[0]
    assert row["n"] == 4 and row["p2.5"] <= row["median"] <= row["p97.5"]
    assert row["median"] == pytest.approx(np.median(wide.max(axis=1)))


def test_a_resumed_store_gives_the_same_table_and_other_bounds_are_refused(three, post, pairs, tmp_path):
    store = tmp_path / "store"
    kw = dict(n_samples=4, seed=5, chunk_size=2, store=store, progress=False)
    a = propagate_pairs(post, three, pairs[:1], **kw)
    parts = sorted(store.glob("part-*.parquet"))
    assert len(parts) == 2
    parts[-1].unlink()  # as if killed after the first chunk
    b = propagate_pairs(post, three, pairs[:1], **kw)
    pd.testing.assert_frame_equal(a.table, b.table)
    with pytest.raises(ValueError, match="different inputs.*lambda"):
        propagate_pairs(post, three, pairs[:1], **kw, lam=0.85)


def test_the_lower_bound_scales_the_force_like_parameters(three, post, pairs):
    tor = TorsionAmplification(y=3.5, b=6.0, d=7.0, e=0.35)
    lo = propagate_pairs(post, three, pairs[:1], n_samples=3, seed=5, lam=0.85, torsion=tor, progress=False)
    nom = propagate_pairs(post, three, pairs[:1], n_samples=3, seed=5, progress=False)
    for name in ("k_init", "qd"):
        np.testing.assert_allclose(lo.draws[name], 0.85 * nom.draws[name], rtol=1e-14)
    np.testing.assert_array_equal(lo.draws["alpha1"], nom.draws["alpha1"])
    np.testing.assert_allclose(lo.table["total_max_disp_m"], tor.factor * lo.table["iso_disp_peak_m"],
                               rtol=1e-14)
    assert any("x 0.85" in n for n in lo.notes)


def test_a_thread_pool_gives_the_same_table_as_the_local_run(three, post, pairs, plan_rs):
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as ex:
        pooled = propagate_pairs(post, three, pairs, n_samples=4, seed=5, chunk_size=3, progress=False,
                                 executor=ex)
    pd.testing.assert_frame_equal(pooled.table, plan_rs.table)
