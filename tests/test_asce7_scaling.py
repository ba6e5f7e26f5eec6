"""ASCE 7-22 Chapter 17 scaling of ground-motion pairs (17.3.2, 17.3.3) and design values (17.6.3.4).

The facts: each pair is scaled by one factor on both components; the suite's average
maximum-direction (RotD100) spectrum is nowhere below the target over 0.75 T_M (upper-bound) to
1.25 T_M (lower-bound) and touches it at the governing period (the smallest compliant scaling);
fewer than seven pairs is flagged; design values are the average over seven or more pairs and
the maximum over fewer.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions as gm
from ground_motions.asce7 import (
    MIN_PAIRS,
    ScaledSuite,
    SuiteSizeWarning,
    design_value,
    mcer_target,
    scale_pairs_asce7,
)
from ground_motions.rotd import rotd_spectrum

TARGET = mcer_target(1.0, 0.6, 8.0)  # SDS = 1.0 g, SD1 = 0.6 g, TL = 8 s
T_UPPER, T_LOWER = 0.4, 0.6


def _pair(seed: int, n: int = 400, dt: float = 0.01) -> gm.RecordPair:
    rng = np.random.default_rng(seed)
    env = np.sin(np.pi * np.arange(n) / (n - 1)) ** 2
    amp = rng.uniform(0.5, 3.0)
    return gm.RecordPair(gm.Record(f"p{seed}.1", dt, amp * rng.normal(size=n) * env),
                         gm.Record(f"p{seed}.2", dt, amp * rng.normal(size=n) * env), name=f"p{seed}")


SUITE = [_pair(s) for s in range(MIN_PAIRS)]


def _scale(pairs=SUITE, **kw) -> ScaledSuite:
    return scale_pairs_asce7(pairs, TARGET, T_UPPER, T_LOWER, **kw)


@pytest.mark.parametrize("method", ["log-ls", "common"])
def test_the_suite_average_rotd100_is_not_below_the_target_and_touches_it_at_the_governing_period(method):
    s = _scale(method=method)
    assert s.periods[0] == pytest.approx(0.75 * T_UPPER) and s.periods[-1] == pytest.approx(1.25 * T_LOWER)
    # recomputed from the returned (scaled) pairs, independently of the stored arrays
    avg = np.mean([rotd_spectrum(p, s.periods, 0.05, percentile=100).psa[0] for p in s.pairs], axis=0)
    ratio = avg / TARGET(s.periods)
    assert np.all(ratio >= 1.0 - 1e-12)
    assert ratio.min() == pytest.approx(1.0, rel=1e-12)
    assert s.governing_period == s.periods[int(np.argmin(ratio))]
    np.testing.assert_allclose(s.ratio, ratio, rtol=1e-12)
    assert s.meets_count and s.n_pairs == MIN_PAIRS and s.min_ratio == pytest.approx(1.0)


def test_each_pair_is_scaled_by_one_factor_on_both_components():
    s = _scale()
    for original, scaled, f in zip(SUITE, s.pairs, s.factors):
        np.testing.assert_allclose(scaled.accel, f * original.accel, rtol=1e-15)
        assert scaled.first.meta["scale_factor"] == scaled.second.meta["scale_factor"] == f
        assert scaled.scale_factor == f > 0


def test_the_common_method_gives_every_pair_the_same_factor():
    f = _scale(method="common").factors
    np.testing.assert_allclose(f, f[0], rtol=1e-15)


@settings(max_examples=15, deadline=None)
@given(c=st.floats(0.01, 100.0), k=st.integers(0, MIN_PAIRS - 1))
def test_log_ls_factors_do_not_depend_on_the_amplitude_a_pair_arrives_with(c, k):
    """Each pair is matched to the target by its shape: pre-scaling one pair by c divides its
    factor by c and leaves the scaled suite unchanged."""
    ref = _scale()
    pairs = list(SUITE)
    pairs[k] = pairs[k].scaled(c)
    s = _scale(pairs)
    np.testing.assert_allclose(s.factors[k] * c, ref.factors[k], rtol=1e-9)
    np.testing.assert_allclose(s.average, ref.average, rtol=1e-9)


def test_a_fraction_of_the_target_is_honoured():
    s = _scale(fraction=0.9)
    assert s.min_ratio == pytest.approx(0.9, rel=1e-12) and np.all(s.ratio >= 0.9 * (1 - 1e-12))
    np.testing.assert_allclose(s.factors, 0.9 * _scale().factors, rtol=1e-12)


def test_the_target_may_be_a_callable_a_spectrum_or_a_periods_psa_pair():
    periods = np.geomspace(0.1, 2.0, 400)
    psa = TARGET(periods)
    spectrum = gm.Spectrum(periods, psa / (2 * np.pi / periods) ** 2, psa / (2 * np.pi / periods), psa)
    a = _scale()
    for target in (spectrum, (periods, psa)):
        b = scale_pairs_asce7(SUITE, target, T_UPPER, T_LOWER)
        np.testing.assert_allclose(b.factors, a.factors, rtol=2e-3)  # linear interpolation of the target
    design = scale_pairs_asce7(
        SUITE, lambda T: 1.5 * gm.design_spectrum(1.0, 0.6, 8.0, T, units="m/s^2"), T_UPPER, T_LOWER
    )
    np.testing.assert_allclose(design.factors, a.factors, rtol=1e-15)


def test_the_mcer_target_is_one_and_a_half_times_the_design_spectrum_in_si_units():
    T = np.array([0.0, 0.05, 0.3, 1.0, 5.0, 10.0])
    np.testing.assert_allclose(TARGET(T), 1.5 * gm.G * gm.design_spectrum(1.0, 0.6, 8.0, T), rtol=1e-15)
    with pytest.raises(ValueError, match="sds must be finite and > 0"):
        mcer_target(0.0, 0.6, 8.0)


def test_fewer_than_seven_pairs_are_flagged_and_seven_are_not():
    with pytest.warns(SuiteSizeWarning, match="3 pairs; ASCE 7-22 Section 17.3.2 requires at least 7"):
        s = _scale(SUITE[:3])
    assert not s.meets_count and "fewer than 7 pairs" in s.summary()
    with warnings.catch_warnings():
        warnings.simplefilter("error", SuiteSizeWarning)
        assert "fewer" not in _scale().summary()


def test_the_bundled_pairs_scale_to_a_design_spectrum_target():
    pairs = [gm.load_pair(n) for n in gm.available_pairs()]
    with pytest.warns(SuiteSizeWarning):
        s = scale_pairs_asce7(pairs, TARGET, 2.0, 3.0)
    assert s.period_range == pytest.approx((1.5, 3.75))
    assert s.min_ratio == pytest.approx(1.0) and np.all(s.factors > 0)
    assert [p.name for p in s.pairs] == ["santamonica", "ferndale", "ridgecrest"]


@pytest.mark.parametrize(("args", "message"), [
    (([], TARGET, 0.4, 0.6), "no pairs given"),
    (([gm.load("elcentro")], TARGET, 0.4, 0.6), r"pairs\[0\] must be a ground_motions.RecordPair"),
    ((SUITE, TARGET, 0.6, 0.4), r"need 0 < t_upper <= t_lower .* got t_upper = 0.6 s, t_lower = 0.4 s"),
    ((SUITE, TARGET, 0.0, 0.4), r"need 0 < t_upper <= t_lower"),
    ((SUITE, "target", 0.4, 0.6), r"target must be a Spectrum, a callable"),
    ((SUITE, (np.array([1.0, 2.0]), np.array([1.0, 1.0])), 0.4, 0.6),
     r"the target is given for T = 1..2 s, not over the periods 0.3..0.75 s"),
    ((SUITE, lambda T: 0.0 * T, 0.4, 0.6), r"target PSA at T = 0.3 s is 0.0"),
])
def test_bad_inputs_are_value_errors_that_say_what_is_wrong(args, message):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SuiteSizeWarning)
        with pytest.raises(ValueError, match=message):
            scale_pairs_asce7(*args)


def test_a_silent_pair_cannot_be_scaled():
    silent = gm.RecordPair(gm.Record("z.1", 0.01, np.zeros(50)), gm.Record("z.2", 0.01, np.zeros(50)))
    with pytest.raises(ValueError, match="pair 'z' has zero RotD100 at T = 0.3 s"):
        _scale([*SUITE, silent])


# ------------------------------------------------------------------------- design values
def test_the_design_value_is_the_average_over_seven_or_more_pairs_and_the_maximum_over_fewer():
    seven = np.array([0.30, 0.32, 0.28, 0.41, 0.35, 0.33, 0.31])
    assert design_value(seven) == pytest.approx(seven.mean())
    assert design_value(seven[:6]) == pytest.approx(0.41)
    assert design_value(seven[:3], n_pairs=3) == pytest.approx(0.32)
    per_story = np.arange(14.0).reshape(7, 2)
    np.testing.assert_allclose(design_value(per_story), per_story.mean(axis=0))
    np.testing.assert_allclose(design_value(per_story[:2]), per_story[1])


@settings(max_examples=50, deadline=None)
@given(values=st.lists(st.floats(0.0, 10.0), min_size=1, max_size=12))
def test_the_design_value_never_exceeds_the_largest_and_is_the_largest_below_seven(values):
    v = design_value(values)
    assert v <= max(values) + 1e-12
    if len(values) < MIN_PAIRS:
        assert v == max(values)


@pytest.mark.parametrize(("args", "message"), [
    (([],), r"one value per pair along axis 0, got shape \(0,\)"),
    ((1.0,), r"one value per pair along axis 0, got shape \(\)"),
    (([1.0, 2.0], 3), r"n_pairs = 3 but 2 values were given"),
    (([1.0, float("nan")],), r"the value of pair 1 is not finite"),
])
def test_design_value_refuses_values_that_do_not_match_the_pairs(args, message):
    with pytest.raises(ValueError, match=message):
        design_value(*args)


def test_the_suite_plot_labels_its_axes_with_units():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = _scale(fraction=0.9)
    ax = gm.plot_scaled_suite(s)
    assert ax.get_xlabel() == "Period T [s]" and ax.get_ylabel() == "Pseudo-spectral acceleration [g]"
    labels = [ln.get_label() for ln in ax.lines]
    assert "suite average RotD100" in labels and "target (MCE$_R$)" in labels and "0.9 x target" in labels
    np.testing.assert_allclose(ax.lines[MIN_PAIRS].get_ydata(), s.average / gm.G)
    plt.close("all")
