"""Fragility against a real intensity measure: multiple stripe analysis at Sa(T_iso) in g.

An engineer reads a fragility curve against a spectral acceleration at the isolated period (or the
PGA), with stripes at which every record has the same intensity, spanning from where no analysis
exceeds the limit to where nearly all do; a record scale factor is not an intensity measure.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import ground_motions
from ground_motions import G, Record
from structures import load_building
from structures.propagation.stripes import IntensityMeasure, multiple_stripe_analysis, spanning_levels

RECORDS = ("rinaldi", "tabas")  # the two shortest bundled records


def _posterior(n: int = 6, seed: int = 1) -> pd.DataFrame:
    """Draws of the five-story building's own bouc_wen bearing, k_init and qd spread by 5 %."""
    b = load_building("five_story")
    base = dict(b.isolator.params)
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        p = dict(base)
        p["k_init"] *= math.exp(0.05 * rng.standard_normal())
        p["qd"] *= math.exp(0.05 * rng.standard_normal())
        rows.append(p)
    df = pd.DataFrame(rows)
    df.attrs["law"] = "bouc_wen"
    df.attrs["disp_range"] = (-0.03, 0.03)  # specimen m: the limit is 3 x 0.03 = 0.09 m prototype
    return df


def test_sa_of_a_record_scales_with_it_and_pga_is_the_peak_acceleration_in_g():
    rec = ground_motions.load("rinaldi")
    sa = IntensityMeasure(1.5)
    assert sa.of(rec.scaled(2.0)) == pytest.approx(2.0 * sa.of(rec), rel=1e-12)
    assert IntensityMeasure(None).of(rec) == pytest.approx(rec.pga / G)
    # a very stiff oscillator follows the ground: Sa(T -> 0) -> PGA
    assert IntensityMeasure(0.01).of(rec) == pytest.approx(rec.pga / G, rel=0.05)
    # resonance: a sine at the oscillator's period gives far more than its PGA
    t = np.arange(0, 20, 0.01)
    sine = Record("sine", 0.01, 0.1 * G * np.sin(2 * np.pi * t / 1.5))
    assert sa.of(sine) > 5 * 0.1
    assert "Sa(T_iso = 1.5 s, 5 % damping) [g]" == sa.label


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_an_intensity_measure_refuses_a_period_that_is_not_positive(bad):
    with pytest.raises(ValueError, match="period"):
        IntensityMeasure(bad)


def test_spanning_levels_reach_from_below_the_first_to_beyond_the_last_crossing():
    lv = spanning_levels({"a": 0.2, "b": 0.8}, 5)
    assert len(lv) == 5 and lv[0] < 0.2 and lv[-1] > 0.8
    assert np.all(np.diff(np.log(lv)) > 0)
    with pytest.raises(ValueError, match="at least 2"):
        spanning_levels({"a": 0.2}, 1)


@pytest.fixture(scope="module")
def msa():
    return multiple_stripe_analysis(_posterior(), "five_story", list(RECORDS), n_levels=5, n_samples=6,
                                    seed=0, progress=False)


def test_every_record_of_a_stripe_has_the_stripe_intensity(msa):
    b = load_building("five_story").with_isolator_params(_posterior().median(numeric_only=True).to_dict())
    t_iso = b.isolated_period(0.09)
    assert msa.im.period == pytest.approx(t_iso, rel=0.02)  # Sa at the isolated period at the limit
    assert msa.im.damping == 0.05
    for name in RECORDS:
        rec = ground_motions.load(name)
        assert msa.record_im[name] == pytest.approx(msa.im.of(rec))
        for level in msa.levels:
            scaled = rec.scaled(level * msa.responses.record_factors[name])
            assert msa.im.of(scaled) == pytest.approx(level, rel=1e-9)


def test_the_stripes_span_from_none_to_most_analyses_beyond_the_limit(msa):
    ex = msa.responses.exceedance()
    ex = ex[(ex["demand"] == "iso_disp_peak_m") & (ex["record"] == "all records")].sort_values("scale")
    assert ex["p_exceed"].iloc[0] <= 0.2
    assert ex["p_exceed"].iloc[-1] >= 0.8
    assert np.all(np.diff(ex["p_exceed"].to_numpy()) >= -0.2)  # demand grows with intensity


def test_the_fragility_is_against_sa_in_g_with_its_median_inside_the_stripes(msa):
    (fr,) = [f for f in msa.fragility() if f.demand == "iso_disp_peak_m"]
    assert fr.limit == pytest.approx(0.09)
    assert min(msa.levels) < fr.theta < max(msa.levels)
    assert 0.0 < fr.beta < 2.0
    assert set(fr.im) == set(msa.levels)
    assert msa.responses.im_label.startswith("Sa(T_iso = ") and msa.responses.im_label.endswith("[g]")
    fig = msa.plot_fragility()
    ax = fig.axes[0]
    assert "Sa(T_iso" in ax.get_xlabel() and "[g]" in ax.get_xlabel()
    assert "stripes" in ax.get_title() and "maximum likelihood" in ax.get_title()


def test_a_beta_the_stripes_do_not_resolve_is_said_not_reported_as_a_spread():
    """One stripe between none and all, the others all or none below and above it: theta can put
    that stripe at its share for any beta, the likelihood grows as beta -> 0, and the fit says so."""
    from structures.propagation.fragility import fit_fragility

    fr = fit_fragility([0.1, 0.16, 0.25, 0.4, 0.6], [24] * 5, [0, 0, 14, 24, 24], demand="d", limit=1.0)
    assert "only one stripe" in fr.note and "beta is not identified" in fr.note
    ok = fit_fragility([0.1, 0.16, 0.25, 0.4, 0.6], [24] * 5, [0, 3, 12, 20, 24], demand="d", limit=1.0)
    assert ok.note == "" and 0.1 < ok.beta < 1.0 and 0.16 < ok.theta < 0.4
