"""Summaries of a propagation table, the lognormal fragility fit and the Parquet store.

These parts do not need a structural analysis: they are checked on synthetic tables whose answer
is known in closed form.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from structures.propagation import summaries
from structures.propagation.fragility import fit_fragility
from structures.propagation.store import MANIFEST, ParquetStore


def _crossed(y: np.ndarray, scale: float = 1.0, demand: str = "d") -> pd.DataFrame:
    """Tidy table from a (samples, records) array."""
    ns, nr = y.shape
    return pd.DataFrame({
        "sample": np.repeat(np.arange(ns), nr),
        "record": np.tile([f"r{j}" for j in range(nr)], ns),
        "scale": scale,
        demand: y.ravel(),
        "converged": True,
    })


# ----------------------------------------------------------------------------------- variance
def test_additive_log_demand_splits_exactly_into_parameter_and_record_variance():
    """ln D = a(theta) + b(r): the law of total variance gives Var(a) and Var(b) with no interaction."""
    rng = np.random.default_rng(1)
    a = rng.normal(0, 0.3, 400)
    b = rng.normal(0, 0.6, 7)
    t = _crossed(np.exp(a[:, None] + b[None, :]))
    row = summaries.variance_split(t, ["d"]).iloc[0]
    va, vb = a.var(), b.var()
    assert row["share_params"] == pytest.approx(va / (va + vb), rel=1e-10)
    assert row["share_records"] == pytest.approx(vb / (va + vb), rel=1e-10)
    assert abs(row["share_interaction"]) < 1e-10
    assert row["var_log"] == pytest.approx(va + vb, rel=1e-10)


def test_a_parameter_effect_that_changes_sign_between_records_is_interaction():
    """ln D = a(theta) * s(r) with s = +-1: no main effect of either factor, all interaction."""
    a = np.linspace(-1, 1, 101)
    s = np.array([1.0, -1.0])
    row = summaries.variance_split(_crossed(np.exp(a[:, None] * s[None, :])), ["d"]).iloc[0]
    assert row["share_params"] == pytest.approx(0.0, abs=1e-12)
    assert row["share_records"] == pytest.approx(0.0, abs=1e-12)
    assert row["share_interaction"] == pytest.approx(1.0)


def test_variance_split_uses_only_samples_converged_on_every_record():
    y = np.exp(np.random.default_rng(2).normal(size=(50, 3)))
    t = _crossed(y)
    t.loc[(t["sample"] == 4) & (t["record"] == "r1"), "converged"] = False
    row = summaries.variance_split(t, ["d"]).iloc[0]
    assert row["n_samples"] == 49 and row["n_records"] == 3
    ref = summaries.variance_split(_crossed(np.delete(y, 4, axis=0)), ["d"]).iloc[0]
    assert row["share_params"] == pytest.approx(ref["share_params"], rel=1e-12)


def test_a_demand_that_is_zero_somewhere_has_no_log_variance_split():
    y = np.ones((5, 2))
    y[0, 0] = 0.0
    row = summaries.variance_split(_crossed(y), ["d"]).iloc[0]
    assert math.isnan(row["share_params"])


# ----------------------------------------------------------------------------------- percentiles
def test_percentiles_per_record_and_pooled_equal_numpy_quantiles():
    rng = np.random.default_rng(3)
    y = rng.lognormal(size=(200, 3))
    t = _crossed(y, scale=1.5)
    p = summaries.percentiles(t, ["d"], ["r0", "r1", "r2"])
    assert list(p["record"]) == ["r0", "r1", "r2", summaries.ALL]
    q = [0.025, 0.16, 0.5, 0.84, 0.975]
    for j in range(3):
        np.testing.assert_allclose(p.iloc[j][list(summaries.QUANTILES)].to_numpy(float),
                                   np.quantile(y[:, j], q), rtol=1e-12)
    np.testing.assert_allclose(p.iloc[3][list(summaries.QUANTILES)].to_numpy(float),
                               np.quantile(y.ravel(), q), rtol=1e-12)
    assert p.iloc[3]["n"] == 600


def test_exceedance_counts_strictly_greater_values():
    t = _crossed(np.array([[1.0, 2.0], [3.0, 4.0]]))
    e = summaries.exceedance(t, {"d": 2.0}, ["r0", "r1"])
    got = dict(zip(e["record"], e["p_exceed"]))
    assert got == {"r0": 0.5, "r1": 0.5, summaries.ALL: 0.5}


# ----------------------------------------------------------------------------------- fragility
def _binomial_loglik(theta, beta, x, n, z):
    """Binomial log-likelihood, broadcasting over arrays of theta and beta."""
    theta, beta = np.asarray(theta)[..., None], np.asarray(beta)[..., None]
    p = stats.norm.cdf(np.log(x / theta) / beta)
    return stats.binom.logpmf(z, n, p).sum(axis=-1)


def test_fragility_mle_is_the_maximum_of_the_binomial_likelihood_on_a_fine_grid():
    """Baker (2015): the fit maximises sum_j ln Binom(z_j | n_j, Phi(ln(x_j/theta)/beta))."""
    x = np.array([0.25, 0.5, 0.75, 1.0, 1.5, 2.0])
    n = np.array([40, 40, 40, 40, 40, 40])
    z = np.array([0, 3, 11, 19, 31, 37])
    fr = fit_fragility(x, n, z)
    thetas = np.exp(np.linspace(np.log(0.5), np.log(2.0), 301))
    betas = np.exp(np.linspace(np.log(0.1), np.log(1.5), 301))
    T, B = np.meshgrid(thetas, betas, indexing="ij")
    ll = _binomial_loglik(T, B, x, n, z)
    i, j = np.unravel_index(np.argmax(ll), ll.shape)
    assert fr.loglik >= ll[i, j] - 1e-9  # at least as good as the best grid point
    assert fr.theta == pytest.approx(thetas[i], rel=0.01)
    assert fr.beta == pytest.approx(betas[j], rel=0.02)
    assert fr.loglik == pytest.approx(float(_binomial_loglik(fr.theta, fr.beta, x, n, z)), rel=1e-9)


def test_fragility_recovers_the_curve_that_generated_the_counts():
    theta, beta = 1.3, 0.45
    x = np.array([0.4, 0.7, 1.0, 1.3, 1.8, 2.5])
    n = np.full(6, 200_000)
    z = stats.binom(n, stats.norm.cdf(np.log(x / theta) / beta)).rvs(random_state=5)
    fr = fit_fragility(x, n, z)
    assert fr.theta == pytest.approx(theta, rel=5e-3)
    assert fr.beta == pytest.approx(beta, rel=1e-2)


@settings(deadline=None, max_examples=15)
@given(c=st.floats(0.05, 20.0))
def test_rescaling_the_intensity_rescales_theta_and_leaves_beta(c):
    x = np.array([0.5, 1.0, 1.5, 2.0])
    n = np.array([30, 30, 30, 30])
    z = np.array([2, 9, 18, 25])
    a, b = fit_fragility(x, n, z), fit_fragility(c * x, n, z)
    assert b.theta == pytest.approx(c * a.theta, rel=1e-4)
    assert b.beta == pytest.approx(a.beta, rel=1e-4)


def test_fragility_without_a_finite_maximum_says_why():
    assert "no analysis" in fit_fragility([1, 2], [5, 5], [0, 0]).note
    assert "every analysis" in fit_fragility([1, 2], [5, 5], [5, 5]).note
    assert "two scales" in fit_fragility([1], [5], [2]).note
    assert "separated" in fit_fragility([0.5, 1, 2], [5, 5, 5], [0, 5, 5]).note
    assert fit_fragility([0.5, 1, 2], [5, 5, 5], [1, 4, 5]).note == ""  # two stripes in between
    with pytest.raises(ValueError, match="0 <= z <= n"):
        fit_fragility([1, 2], [5, 5], [6, 1])


# ----------------------------------------------------------------------------------- store
def test_store_resumes_finished_chunks_and_ignores_half_written_files(tmp_path):
    desc = {"law": "linear", "n_samples": 4}
    s = ParquetStore(tmp_path, "abc", desc)
    s.write("c1", pd.DataFrame({"sample": [0, 1], "x": [1.0, 2.0]}))
    (tmp_path / ".part-c2.parquet.123.tmp").write_bytes(b"PAR1 truncated")  # a killed write
    s2 = ParquetStore(tmp_path, "abc", desc)
    assert s2.done() == {"c1"}
    assert not list(tmp_path.glob(".*.tmp"))
    pd.testing.assert_frame_equal(s2.read(), pd.DataFrame({"sample": [0, 1], "x": [1.0, 2.0]}))


def test_store_refuses_results_made_for_other_inputs(tmp_path):
    ParquetStore(tmp_path, "abc", {"law": "linear", "seed": 0})
    with pytest.raises(ValueError, match="different inputs.*seed"):
        ParquetStore(tmp_path, "xyz", {"law": "linear", "seed": 1})
    assert json.loads((tmp_path / MANIFEST).read_text())["inputs"]["seed"] == 0


def test_store_refuses_result_files_without_a_manifest(tmp_path):
    (tmp_path / "part-c1.parquet").write_bytes(b"")
    with pytest.raises(ValueError, match="no manifest"):
        ParquetStore(tmp_path, "abc", {})
