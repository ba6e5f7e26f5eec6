"""RotD50 / RotD100 spectra of a pair (Boore 2010, BSSA 100(4) 1830-1835).

The facts: the oscillator is linear, so the response to the ground motion along ``theta`` is
``u1 cos(theta) + u2 sin(theta)``; RotD100 (the maximum over directions) does not depend on how
the recording instrument was oriented, is at least each component's own spectrum and at most
their square root of the sum of squares; a pair with one silent component has RotD100 equal to
the other component's spectrum; two identical components in phase are one motion along 45 deg,
sqrt(2) times as strong.  A brute-force reference (rotate the record, integrate each direction
with SciPy's ``lsim``, take the percentile with NumPy) agrees.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

import ground_motions as gm
from ground_motions.rotd import RotDSpectrum, component_spectra, rotate, rotd_spectrum

PERIODS = np.array([0.0, 0.1, 0.3, 0.7, 1.5, 3.0])


def _pair(seed: int, n: int = 300, dt: float = 0.01, second=None) -> gm.RecordPair:
    rng = np.random.default_rng(seed)
    envelope = np.sin(np.pi * np.arange(n) / (n - 1)) ** 2
    a1 = rng.normal(size=n) * envelope
    a2 = rng.normal(size=n) * envelope if second is None else second(a1)
    return gm.RecordPair(gm.Record("x.1", dt, a1, {"component": "N"}),
                         gm.Record("x.2", dt, a2, {"component": "E"}))


def test_a_silent_second_component_leaves_rotd100_equal_to_the_first_components_spectrum():
    p = _pair(1, second=np.zeros_like)
    r = rotd_spectrum(p, PERIODS)
    one = gm.response_spectrum(p.first, PERIODS)
    np.testing.assert_allclose(r.rotd100.sd, one.sd, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.rotd100.psa, one.psa, rtol=1e-12, atol=0)
    # every direction sees |cos(theta)| of it; RotD50 is the median of |cos| over the angles
    median_cos = np.percentile(np.abs(np.cos(np.radians(np.arange(180.0)))), 50)
    np.testing.assert_allclose(r.rotd50.psa, median_cos * one.psa, rtol=1e-12)


def test_identical_in_phase_components_give_sqrt2_times_the_single_spectrum():
    p = _pair(2, second=np.copy)
    r = rotd_spectrum(p, PERIODS)
    one = gm.response_spectrum(p.first, PERIODS)
    np.testing.assert_allclose(r.rotd100.psa, math.sqrt(2.0) * one.psa, rtol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**20), k=st.integers(-360, 360))
def test_rotating_the_instrument_by_a_whole_angle_step_leaves_rotd50_and_rotd100_unchanged(seed, k):
    p = _pair(seed)
    r0 = rotd_spectrum(p, PERIODS)
    r1 = rotd_spectrum(rotate(p, float(k)), PERIODS)  # 1 deg = the step of 180 angles
    np.testing.assert_allclose(r1.sd, r0.sd, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(r1.psa, r0.psa, rtol=1e-9, atol=1e-15)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**20), theta=st.floats(-360.0, 360.0, allow_nan=False))
def test_rotd100_of_a_pair_rotated_by_any_angle_agrees_within_the_angle_step_bound(seed, theta):
    """Both are within cos(step / 2) of the continuous maximum max_t |u(t)|."""
    p = _pair(seed)
    bound = 1.0 - math.cos(math.radians(0.5))
    r0 = rotd_spectrum(p, PERIODS).rotd100.psa
    r1 = rotd_spectrum(p.rotated(theta), PERIODS).rotd100.psa
    np.testing.assert_allclose(r1, r0, rtol=bound * 1.0001)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**20), scale2=st.floats(0.0, 3.0))
def test_rotd100_lies_between_the_larger_component_and_the_srss_and_above_rotd50(seed, scale2):
    p = _pair(seed, second=lambda a: scale2 * np.random.default_rng(seed + 1).normal(size=a.size))
    r = rotd_spectrum(p, PERIODS, percentile=(0, 50, 100))
    s1, s2 = component_spectra(p, PERIODS)
    rot00, rot50, rot100 = r.psa
    assert np.all(rot00 >= 0.0) and np.all(rot50 >= rot00) and np.all(rot100 >= rot50)
    assert np.all(rot100 >= np.maximum(s1.psa, s2.psa) * (1 - 1e-12))  # 0 and 90 deg are angles
    assert np.all(rot100 <= np.hypot(s1.psa, s2.psa) * (1 + 1e-12))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**20), n_angles=st.sampled_from([4, 36, 180, 360]))
def test_rotd100_is_the_peak_plan_displacement_up_to_the_angle_step(seed, n_angles):
    """Over all directions, max_theta max_t |u . e(theta)| = max_t |u(t)| (the oscillator's peak
    plan displacement); a grid of angles with step 180/n misses at most a factor cos(90/n)."""
    p = _pair(seed)
    T = PERIODS[1:]
    r = rotd_spectrum(p, T, percentile=100, n_angles=n_angles).sd[0]
    for j, period in enumerate(T):
        u1 = gm.sdof_response(p.first, period)[0]
        u2 = gm.sdof_response(p.second, period)[0]
        plan = np.max(np.hypot(u1, u2))
        assert plan * math.cos(math.radians(90.0 / n_angles)) * (1 - 1e-12) <= r[j] <= plan * (1 + 1e-12)


def test_one_factor_on_the_pair_scales_every_rotdnn_by_it():
    p = _pair(3)
    r = rotd_spectrum(p, PERIODS)
    np.testing.assert_allclose(rotd_spectrum(p.scaled(2.5), PERIODS).psa, 2.5 * r.psa, rtol=1e-12)


def _brute_force(p: gm.RecordPair, periods, damping, percentiles, n_angles):
    """Rotate the record to each angle, integrate u'' + 2 z w u' + w^2 u = -a(t) with SciPy's lsim
    (linear interpolation between samples: exact for this input), take the percentile."""
    t = p.time
    angles = np.radians(np.arange(n_angles) * 180.0 / n_angles)
    out = np.empty((len(percentiles), len(periods)))
    for j, period in enumerate(periods):
        w = 2 * np.pi / period
        system = signal.lti([[0.0, 1.0], [-w * w, -2 * damping * w]], [[0.0], [-1.0]], [[1.0, 0.0]], [[0.0]])
        peaks = []
        for th in angles:
            a = p.accel[:, 0] * np.cos(th) + p.accel[:, 1] * np.sin(th)
            _, u, _ = signal.lsim(system, a, t, interp=True)
            peaks.append(np.max(np.abs(u)))
        out[:, j] = w * w * np.percentile(peaks, percentiles)
    return out


def test_rotd_agrees_with_a_brute_force_numpy_scipy_implementation_on_a_short_record():
    p = _pair(4, n=250)
    periods = np.array([0.15, 0.5, 1.2])
    ours = rotd_spectrum(p, periods, damping=0.05, percentile=(50, 100), n_angles=36).psa
    ref = _brute_force(p, periods, 0.05, (50, 100), 36)
    np.testing.assert_allclose(ours, ref, rtol=1e-10)


def test_the_rigid_limit_is_the_rotdnn_of_the_ground_acceleration():
    p = _pair(5)
    r = rotd_spectrum(p, [0.0], percentile=(50, 100))
    a = p.accel
    th = np.radians(np.arange(180.0))
    peaks = np.max(np.abs(a[:, :1] * np.cos(th) + a[:, 1:] * np.sin(th)), axis=0)
    np.testing.assert_allclose(r.psa[:, 0], np.percentile(peaks, (50, 100)), rtol=1e-12)
    assert np.all(r.sd[:, 0] == 0.0)


def test_the_bundled_santamonica_pair_has_a_maximum_direction_above_both_components():
    p = gm.load_pair("santamonica")
    T = np.geomspace(0.1, 4.0, 20)
    r = rotd_spectrum(p, T)
    s1, s2 = component_spectra(p, T)
    assert s1.name == "santamonica 90" and s2.name == "santamonica 360"
    assert np.all(r.rotd100.psa >= np.maximum(s1.psa, s2.psa) * (1 - 1e-12))
    ratio = r.rotd100.psa / r.rotd50.psa
    assert np.all(ratio >= 1.0) and np.all(ratio <= math.sqrt(2.0) * 1.5)
    assert r.rotd100.name == "santamonica RotD100"
    assert isinstance(r, RotDSpectrum) and r.angle_sd.shape == (20, 180) and not r.psa.flags.writeable


@pytest.mark.parametrize(("kw", "message"), [
    ({"percentile": 101}, r"percentile must be one or more values in \[0, 100\]"),
    ({"percentile": ()}, r"percentile must be one or more values"),
    ({"n_angles": 0}, r"n_angles must be a whole number >= 1, got 0"),
    ({"n_angles": 1.5}, r"n_angles must be a whole number >= 1, got 1.5"),
    ({"damping": 1.0}, r"damping must be a ratio in \[0, 1\)"),
    ({"periods": [-1.0]}, r"periods\[0\] = -1.0"),
])
def test_bad_arguments_are_value_errors_naming_them(kw, message):
    args = {"periods": PERIODS, **kw}
    with pytest.raises(ValueError, match=message):
        rotd_spectrum(_pair(6), **args)


def test_a_single_record_is_not_a_pair():
    with pytest.raises(ValueError, match="pair must be a ground_motions.RecordPair, got Record"):
        rotd_spectrum(gm.load("elcentro"), PERIODS)
    with pytest.raises(ValueError, match="RotD84 was not computed"):
        rotd_spectrum(_pair(7), PERIODS).spectrum(84)


def test_the_rotd_plot_shows_both_components_rotd50_rotd100_and_the_target_with_units():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ground_motions.asce7 import mcer_target

    p = gm.load_pair("santamonica")
    T = np.geomspace(0.1, 4.0, 25)
    ax = gm.plot_rotd(p, T, target=mcer_target(1.0, 0.6, 8.0), target_label="MCE_R", period_range=(1.5, 3.75))
    assert ax.get_xlabel() == "Period T [s]" and ax.get_ylabel() == "Pseudo-spectral acceleration [g]"
    labels = [ln.get_label() for ln in ax.lines]
    assert labels == ["component 90", "component 360", "RotD50", "RotD100 (maximum direction)", "MCE_R"]
    np.testing.assert_allclose(ax.lines[3].get_ydata(), rotd_spectrum(p, T).rotd100.psa / gm.G)
    with pytest.raises(ValueError, match="plot_rotd: units must be 'g' or 'm/s\\^2'"):
        gm.plot_rotd(p, T, units="cm")
    plt.close("all")
