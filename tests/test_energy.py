"""Cycle metrics against closed forms; noise-robust cycle detection."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rrfrei.energy import METRIC_COLUMNS, cycle_bounds, cycle_metrics, cycle_metrics_batch, dissipated_energy


def _ellipse(n_cycles, m, d0, f0, phi):
    """u = d0 sin(w t), F = F0 sin(w t + phi), m samples per cycle, starting at rest."""
    th = 2 * np.pi * np.arange(n_cycles * m + 1) / m
    return d0 * np.sin(th), f0 * np.sin(th + phi)


@given(
    d0=st.floats(1e-3, 1.0), f0=st.floats(1e-2, 1e3), phi=st.floats(0.05, 1.5),
    m=st.integers(16, 400),
)
@settings(max_examples=40, deadline=None)
def test_ellipse_loop_energy_is_pi_f0_d0_sin_phi(d0, f0, phi, m):
    """A polygon of m points inscribed in the ellipse encloses pi F0 d0 sin(phi) * sinc factor.

    The trapezoidal F du of a sampled ellipse is exactly the area of the inscribed m-gon,
    F0 d0 sin(phi) * (m/2) sin(2 pi/m), which tends to pi F0 d0 sin(phi).
    """
    u, f = _ellipse(3, m, d0, f0, phi)
    df = cycle_metrics(u, f)
    assert len(df) == 3
    exact_polygon = f0 * d0 * math.sin(phi) * (m / 2) * math.sin(2 * math.pi / m)
    np.testing.assert_allclose(df["energy"], exact_polygon, rtol=1e-9)
    assert abs(exact_polygon - math.pi * f0 * d0 * math.sin(phi)) <= 0.03 * math.pi * f0 * d0


def test_ellipse_k_eff_and_beta_eff_closed_forms():
    """Sampled at its peaks (m divisible by 4): k_eff = F0 cos(phi)/d0, beta_eff -> tan(phi)/2."""
    d0, f0, phi, m = 0.02, 5.0, 0.4, 4000
    u, f = _ellipse(2, m, d0, f0, phi)
    df = cycle_metrics(u, f)
    np.testing.assert_allclose(df["d_pos"], d0, rtol=1e-12)
    np.testing.assert_allclose(df["d_neg"], -d0, rtol=1e-12)
    np.testing.assert_allclose(df["k_eff"], f0 * math.cos(phi) / d0, rtol=1e-12)
    np.testing.assert_allclose(df["beta_eff"], math.tan(phi) / 2, rtol=1e-5)
    assert tuple(df.columns) == METRIC_COLUMNS


def test_elastic_line_dissipates_nothing_and_rigid_plastic_square_dissipates_4_qd_d():
    th = 2 * np.pi * np.arange(2 * 400 + 1) / 400
    u = 0.03 * np.sin(th)
    np.testing.assert_allclose(cycle_metrics(u, 700.0 * u)["energy"], 0.0, atol=1e-14)
    assert np.all(cycle_metrics(u, 700.0 * u)["beta_eff"].abs() < 1e-12)
    # rigid-plastic: F = qd sgn(du); the trapezoid smears only the reversal steps (du ~ 0 there)
    qd = 2.0
    f = qd * np.sign(np.gradient(u))
    e = cycle_metrics(u, f)["energy"].to_numpy()
    np.testing.assert_allclose(e, 4 * qd * 0.03, rtol=1e-3)


def test_dissipated_energy_is_cumulative_trapezoid():
    u = np.array([0.0, 1.0, 3.0, 2.0])
    f = np.array([0.0, 2.0, 2.0, -1.0])
    np.testing.assert_allclose(dissipated_energy(u, f), [0.0, 1.0, 5.0, 4.5])


@given(
    n=st.integers(1, 6), m=st.integers(20, 200), amp=st.floats(1e-3, 0.5),
    noise=st.floats(0.0, 0.008), seed=st.integers(0, 2**31 - 1),
)
@settings(max_examples=60, deadline=None)
def test_noisy_sinusoid_from_rest_keeps_its_cycle_count(n, m, amp, noise, seed):
    """Bounded noise (< eps) never adds or removes cycles; starts and ends at rest count."""
    rng = np.random.default_rng(seed)
    u = amp * np.sin(2 * np.pi * np.arange(n * m + 1) / m)
    u = u + rng.uniform(-noise, noise, u.size) * amp
    b = cycle_bounds(u)
    assert b.shape == (n, 2)
    assert b[0, 0] <= 1 and b[-1, 1] == u.size - 1
    assert np.all(np.abs(b[1:, 0] - m * np.arange(1, n)) <= 1)


@given(
    n=st.integers(2, 6), m=st.integers(20, 200), amp=st.floats(1e-3, 0.5),
    phase=st.one_of(st.floats(0.3, math.pi - 0.3), st.floats(math.pi + 0.3, 2 * math.pi - 0.3)),
    noise=st.floats(0.0, 0.008), seed=st.integers(0, 2**31 - 1),
)
@settings(max_examples=60, deadline=None)
def test_noisy_sinusoid_not_at_rest_drops_its_partial_ends(n, m, amp, phase, noise, seed):
    """Starting mid-cycle: n periods contain n up-crossings, hence n - 1 full cycles."""
    rng = np.random.default_rng(seed)
    u = amp * np.sin(2 * np.pi * np.arange(n * m + 1) / m + phase)
    u = u + rng.uniform(-noise, noise, u.size) * amp
    assert cycle_bounds(u).shape == (n - 1, 2)


def test_no_full_cycle_gives_empty_metrics():
    assert cycle_bounds(np.linspace(0, 1, 50)).shape == (0, 2)
    assert cycle_bounds(np.zeros(10)).shape == (0, 2)
    assert len(cycle_metrics(np.linspace(0, 1, 50), np.ones(50))) == 0


@pytest.mark.parametrize(
    "u, f, match",
    [
        (np.zeros((3, 2)), np.zeros((3, 2)), "1-D"),
        ([0.0, np.nan, 1.0], [0.0, 1.0, 2.0], "disp is not finite at index 1"),
        ([0.0, 1.0], [0.0, 1.0, 2.0], "force has 3"),
        ([0.0], [0.0], "at least 2"),
    ],
)
def test_bad_input_raises_clear_value_error(u, f, match):
    with pytest.raises(ValueError, match=match):
        cycle_metrics(u, f)


def test_the_batched_cycle_metrics_are_the_single_history_ones_row_by_row():
    """Many force histories along one displacement history (posterior draws): every row equals
    cycle_metrics of that row exactly, including a cycle with no stiffness (NaN beta)."""
    rng = np.random.default_rng(3)
    u, f = _ellipse(4, 60, 0.05, 10.0, 0.4)
    F = f[None, :] * rng.uniform(0.5, 1.5, (7, 1)) + 0.1 * rng.standard_normal((7, u.size))
    F[2] = 0.0  # no force: k_eff 0, beta_eff NaN
    batch = cycle_metrics_batch(u, F)
    for r in range(F.shape[0]):
        one = cycle_metrics(u, F[r])
        for k in ("energy", "k_eff", "beta_eff"):
            np.testing.assert_array_equal(batch[k][r], one[k].to_numpy(float))
    assert np.all(np.isnan(batch["beta_eff"][2])) and batch["energy"].shape == (7, len(cycle_bounds(u)))
    with pytest.raises(ValueError, match="disp has"):
        cycle_metrics_batch(u, F[:, :-1])
