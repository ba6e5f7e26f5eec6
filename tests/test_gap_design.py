"""Design quantities, property modification factors and building bounds (issue 12 point 5).

Physical facts first: the closed forms of a linear spring with a dashpot and of an
elastic-perfectly-plastic loop, lambdas of identical and of scragged cycles, the homogeneity of
the bound laws, then the building: a stronger, stiffer isolator moves less and sends more shear
up, and a neutral effect is the base law bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ground_motions
import rrfrei.io as rio
import structures
from rrfrei import laws, simulate_force
from rrfrei.gap.design import (
    DM_FACTOR,
    QUANTITIES,
    PropertyModification,
    bound_params,
    design_displacements,
    design_gap,
    design_quantities,
    kn_power,
    plot_design_gap,
    property_modification,
)
from rrfrei.io import ShearTest
from rrfrei.laws.effects import EFFECTS
from structures import time_history_batch
from structures.propagation.consequences import building_consequences, plot_consequences

M = 400  # samples per cycle (divisible by 4: the peaks are samples)


def _sine(d, n_cycles=3, period=2.0, m=M):
    t = np.arange(n_cycles * m + 1) * period / m
    return t, d * np.sin(2 * math.pi * t / period)


def _epp(u, k0, fy):
    """Elastic-perfectly-plastic force (return mapping), independent of the law table."""
    f = np.zeros_like(u)
    for i in range(1, u.size):
        trial = f[i - 1] + k0 * (u[i] - u[i - 1])
        f[i] = min(max(trial, -fy), fy)
    return f


def _kelvin(k=100.0, c=5.0, d=0.02, period=2.0, n_cycles=3):
    t, u = _sine(d, n_cycles, period)
    w = 2 * math.pi / period
    f = k * u + c * d * w * np.cos(w * t)
    return ShearTest("kelvin", t, u, f), (k, c, d, w)


# ------------------------------------------------------------------------- closed forms
def test_spring_and_dashpot_loop_has_the_closed_form_k_eff_beta_edc_and_qd():
    """F = k u + c du/dt, u = d sin(w t): k_eff = k, EDC = pi c w d^2, beta = c w / (2 k), and
    the force at u = 0 is the dashpot's c w d."""
    test, (k, c, d, w) = _kelvin()
    df = design_quantities(test)
    cyc = df[df["scope"] == "cycle"]
    assert len(cyc) == 3
    np.testing.assert_allclose(cyc["k_eff"], k, rtol=1e-12)
    np.testing.assert_allclose(cyc["amplitude"], d, rtol=1e-12)
    np.testing.assert_allclose(cyc["edc"], math.pi * c * w * d * d, rtol=1e-4)  # inscribed polygon
    np.testing.assert_allclose(cyc["beta_eff"], c * w / (2 * k), rtol=1e-4)
    np.testing.assert_allclose(cyc["qd"], c * w * d, rtol=1e-4)
    row = df.iloc[-1]
    assert row["scope"] == "test" and row["cycle"] == -1
    assert row["k_eff"] == pytest.approx(k, rel=1e-12)
    assert row["f_dd"] == pytest.approx(k * d, rel=1e-12)  # at the peak the dashpot force is 0


@pytest.mark.parametrize("ratio", [3.0, 5.0, 20.0])
def test_epp_loop_qd_is_the_yield_force_and_edc_is_4_fy_d_minus_dy(ratio):
    """An elastic-perfectly-plastic loop of amplitude d = ratio * dy: Qd = F(u=0) = Fy,
    k_eff = Fy / d, EDC = 4 Fy (d - dy), beta_eff = 2 (1 - dy/d) / pi, F(DD) = Fy."""
    k0, fy = 1000.0, 5.0
    dy = fy / k0
    d = ratio * dy
    t, u = _sine(d, n_cycles=4)
    test = ShearTest("epp", t, u, _epp(u, k0, fy))
    df = design_quantities(test)
    cyc = df[(df["scope"] == "cycle") & (df["cycle"] > 0)]  # the first one starts virgin
    np.testing.assert_allclose(cyc["qd"], fy, rtol=1e-12)
    np.testing.assert_allclose(cyc["k_eff"], fy / d, rtol=1e-12)
    np.testing.assert_allclose(cyc["edc"], 4 * fy * (d - dy), rtol=2e-3)  # sampled corners
    np.testing.assert_allclose(cyc["beta_eff"], 2 * (1 - dy / d) / math.pi, rtol=2e-3)
    assert df.iloc[-1]["qd"] == pytest.approx(fy, rel=1e-12)
    assert df.iloc[-1]["f_dd"] == pytest.approx(fy, rel=1e-12)


def test_plasticity_law_without_hardening_has_qd_equal_to_its_characteristic_strength():
    """The law table's `plasticity` with alpha1 = alpha2 = 0 is elastic-perfectly-plastic."""
    qd, k0 = 2.0, 400.0
    t, u = _sine(10 * qd / k0, n_cycles=3)
    f = simulate_force("plasticity", {"k_init": k0, "qd": qd, "alpha1": 0.0, "alpha2": 0.0, "mu": 2.0}, u)
    df = design_quantities(ShearTest("plast", t, u, f))
    np.testing.assert_allclose(df.loc[df["cycle"] > 0, "qd"], qd, rtol=1e-9)


def test_dd_defaults_to_the_largest_level_and_dm_to_one_and_a_half_dd():
    """Protocol 1 (levels 5, 10, 20, 30 mm): DD = 30 mm, its three cycles are the test row's mean;
    DM = 45 mm lies beyond the test, so F(DM) is NaN (never extrapolated); a given DM inside is
    read on the envelope."""
    test = rio.load_test("protocol1")
    dd, dm = design_displacements(test.disp)
    assert dd == pytest.approx(0.030, rel=0.02) and dm == pytest.approx(DM_FACTOR * dd, rel=1e-12)
    df = design_quantities(test)
    cyc = df[df["scope"] == "cycle"]
    assert len(cyc) == 12 and cyc["at_dd"].sum() == 3
    assert df.iloc[-1]["k_eff"] == pytest.approx(cyc.loc[cyc["at_dd"], "k_eff"].mean(), rel=1e-12)
    assert math.isnan(df.iloc[-1]["f_dm"]) and df.iloc[-1]["f_dd"] > 0
    small = design_quantities(test, dd=0.020, dm=0.030).iloc[-1]
    assert small["dd"] == 0.020 and small["dm"] == 0.030
    assert 0 < small["f_dd"] < small["f_dm"] == pytest.approx(df.iloc[-1]["f_dd"], rel=1e-12)


def test_dd_of_an_off_centre_history_is_its_largest_cycle_amplitude():
    """Cycles from -10 mm to +30 mm (as earthquake loops often are): DD = 20 mm, the cycles'
    amplitude, so the test row holds their mean; F(DD) is read on the side that reaches it."""
    t = np.arange(5 * M + 1) * 2.0 / M
    u = 0.01 - 0.02 * np.cos(2 * math.pi * t / 2.0)
    u[0] = 0.0
    test = ShearTest("offset", t, u, 100.0 * u)
    df = design_quantities(test)
    assert df.iloc[-1]["dd"] == pytest.approx(0.02, rel=1e-9)
    assert df.loc[df["scope"] == "cycle", "at_dd"].all()
    assert df.iloc[-1]["k_eff"] == pytest.approx(100.0, rel=1e-9)
    assert df.iloc[-1]["f_dd"] == pytest.approx(2.0, rel=1e-9)
    wide = design_quantities(test, dd=0.018, tol=0.2)
    narrow = design_quantities(test, dd=0.018)
    assert wide["at_dd"].all() and not narrow.loc[narrow["scope"] == "cycle", "at_dd"].any()


def test_monotonic_push_has_only_the_test_row_with_the_force_at_dd():
    test = rio.load_test("protocol4")
    df = design_quantities(test)
    assert list(df["scope"]) == ["test"]
    assert math.isnan(df.iloc[0]["k_eff"]) and df.iloc[0]["f_dd"] > 0


def test_design_gap_is_zero_for_a_perfect_prediction_and_lambda_minus_one_for_a_scaled_one():
    """Scaling the force by 1.1 scales k_eff, EDC, Qd and the forces by 1.1; beta_eff is a ratio."""
    test = rio.load_test("protocol1")
    gap = design_gap(test, None, test.force, 1.1 * test.force, dm=0.03)
    assert tuple(gap.index) == QUANTITIES
    np.testing.assert_allclose(gap["rel_err_before"], 0.0, atol=1e-14)
    expected = [0.1, 0.0, 0.1, 0.1, 0.1, 0.1]
    np.testing.assert_allclose(gap["rel_err_after"], expected, atol=1e-12)
    assert gap.loc["k_eff", "unit"] == "kN/m" and gap.loc["qd", "unit"] == "kN"
    assert gap["after"].notna().all()


def test_the_design_gap_figure_shows_relative_errors_in_percent():
    test = rio.load_test("protocol1")
    gap = design_gap(test, None, 0.9 * test.force, 1.02 * test.force)
    fig = plot_design_gap(gap, title="protocol1")
    ax = fig.axes[0]
    assert "[%]" in ax.get_xlabel()
    widths = sorted(round(p.get_width(), 9) for p in ax.patches)
    assert widths[0] == pytest.approx(-10.0) and widths[-1] == pytest.approx(2.0)
    assert len(ax.get_yticklabels()) == 5  # F(DM) is beyond the test: left out


def test_design_gap_names_a_misaligned_prediction():
    test = rio.load_test("protocol1")
    with pytest.raises(ValueError, match="pred_before has shape"):
        design_gap(test, None, test.force[:-1])


# ------------------------------------------------------------------------- lambdas
def test_identical_cycles_and_tests_give_lambda_test_one():
    test, _ = _kelvin()
    other, _ = _kelvin()
    pm = property_modification([test, other], lambda_ae=(1.0, 1.0), lambda_spec=(1.0, 1.0))
    assert pm.n_cycles == 6 and pm.tests == ("kelvin", "kelvin")
    for p in ("k_eff", "qd", "edc"):
        assert pm.test_max[p] == pytest.approx(1.0, abs=1e-9)
        assert pm.test_min[p] == pytest.approx(1.0, abs=1e-9)
        assert pm.lambda_max[p] == pytest.approx(1.0, abs=1e-9)
        assert pm.upper[p] == pytest.approx(pm.nominal[p], rel=1e-9)
        assert pm.lower[p] == pytest.approx(pm.nominal[p], rel=1e-9)


def test_a_stiffer_first_cycle_gives_lambda_max_above_one_and_lambda_min_below():
    """Scragging: the first cycle 20 % stronger; the nominal is the three-cycle mean 1.0667, so
    lambda_test,max = 1.2 / 1.0667 = 1.125 and lambda_test,min = 1 / 1.0667 = 0.9375."""
    test, _ = _kelvin()
    f = test.force.copy()
    f[: M + 1] *= 1.2
    scragged = ShearTest("scragged", test.time, test.disp, f)
    pm = property_modification(scragged, lambda_spec=(1.0, 1.0))
    assert pm.test_max["k_eff"] == pytest.approx(1.2 / (3.2 / 3), rel=1e-9)
    assert pm.test_min["k_eff"] == pytest.approx(1.0 / (3.2 / 3), rel=1e-9)
    for p in ("k_eff", "qd", "edc"):
        assert pm.lambda_max[p] > 1.0 > pm.lambda_min[p]
        assert pm.upper[p] > pm.nominal[p] > pm.lower[p]


def test_lambdas_combine_by_asce_7_22_eqs_17_2_1_and_17_2_2():
    test, _ = _kelvin()
    pm = property_modification(test, lambda_ae=(0.9, 1.2), lambda_spec=(0.85, 1.15))
    assert pm.lambda_max["k_eff"] == pytest.approx((1 + 0.75 * 0.2) * 1.15, rel=1e-9)
    assert pm.lambda_min["k_eff"] == pytest.approx((1 - 0.75 * 0.1) * 0.85, rel=1e-9)
    lo, hi = pm.law_lambdas()
    assert lo == min(pm.lambda_min.values()) and hi == max(pm.lambda_max.values())
    assert set(pm.table().columns) >= {"nominal", "lambda_min", "lambda_max", "lower", "upper"}
    assert pm.to_dict()["lambda_spec"] == [0.85, 1.15]


@pytest.mark.parametrize("kw, match", [
    ({"lambda_ae": (1.1, 1.2)}, "lambda_ae"),
    ({"lambda_spec": (0.9,)}, "lambda_spec"),
    ({"amplitude": 0.5}, "reference amplitude"),
])
def test_bad_lambda_inputs_are_named(kw, match):
    test, _ = _kelvin()
    with pytest.raises(ValueError, match=match):
        property_modification(test, **kw)


# ------------------------------------------------------------------------- bound laws
@pytest.mark.parametrize("unit, power", [("kN", 1), ("kN/m", 1), ("kN/m^3", 1), ("kN*s/m", 1),
                                         ("1/kN*m", -1), ("1/m^3", 0), ("-", 0), ("m", 0)])
def test_kn_power_reads_the_registry_units(unit, power):
    assert kn_power(unit) == power


def test_every_registered_parameter_unit_has_a_kn_power_of_minus_one_zero_or_one():
    """Every law and effect of the tables has force-like, inverse or force-free parameters."""
    specs = [(name, laws.get(name).params) for name in laws.names()]
    specs += [(name, e.params) for name, e in EFFECTS.items()]
    for name, params in specs:
        for p in params:
            assert kn_power(p.unit) in (-1, 0, 1), (name, p.name, p.unit)


@pytest.mark.parametrize("law, params", [
    ("linear", {"k": 50.0, "c": 2.0}),
    ("plasticity", {"k_init": 260.0, "qd": 1.4, "alpha1": 0.33, "alpha2": 0.0, "mu": 2.0}),
    ("bouc_wen", {"k_init": 260.0, "qd": 1.4, "alpha1": 0.33, "alpha2": 0.0, "mu": 2.0, "eta": 1.0,
                  "beta": 0.5, "gamma": 0.5}),
    ("bouc_wen+degradation", {"k_init": 260.0, "qd": 1.4, "alpha1": 0.33, "alpha2": 0.0, "mu": 2.0,
                              "eta": 1.0, "beta": 0.5, "gamma": 0.5, "deg_rate": 2.0}),
])
def test_the_bound_law_force_is_lambda_times_the_nominal_force(law, params):
    """Force-like parameters x lambda (a fade rate per unit work / lambda): F_bound = lambda F."""
    t, u = _sine(0.03, n_cycles=3, period=4.0)
    nominal = simulate_force(law, params, u, time=t)
    for lam in (0.7, 1.3):
        bound = simulate_force(law, bound_params(law, params, lam), u, time=t)
        np.testing.assert_allclose(bound, lam * nominal, rtol=1e-9, atol=1e-12 * np.max(np.abs(nominal)))
    assert bound_params(law, params, 1.0) == laws.get(law).as_dict(laws.get(law).pack(params))


def test_a_parameter_at_its_upper_bound_sentinel_stays_there():
    params = {"k_init": 260.0, "qd": 1.4, "alpha1": 0.33, "alpha2": 0.0, "mu": 2.0, "eta": 1.0,
              "beta": 0.5, "gamma": 0.5, "slip_force": 1e12}
    out = bound_params("bouc_wen+slip", params, 1.5)
    assert out["slip_force"] == 1e12 and out["qd"] == pytest.approx(2.1)


def test_law_bounds_scale_by_the_envelope_lambdas():
    test, _ = _kelvin()
    pm = property_modification(test)
    b = pm.law_bounds("linear", {"k": 50.0})
    lo, hi = pm.law_lambdas()
    assert b["upper"]["k"] == pytest.approx(50.0 * hi) and b["lower"]["k"] == pytest.approx(50.0 * lo)
    assert b["nominal"]["c"] == 0.0
    assert isinstance(pm, PropertyModification)
    with pytest.raises(ValueError, match="prop"):
        pm.law_lambdas("stiffness")


# ------------------------------------------------------------------------- building
RECORDS = ["elcentro", "rinaldi", "tabas"]


@pytest.fixture(scope="module")
def five_story():
    return structures.load_building("five_story")


def test_upper_bound_isolators_move_less_and_send_more_shear_than_lower_bound(five_story):
    df = building_consequences("bouc_wen", dict(five_story.isolator.params), (0.7, 1.4), records=RECORDS)
    assert df["converged"].all()
    med = df[df["record"] == "median"].set_index("bound")
    assert med.loc["upper", "iso_disp_peak"] < med.loc["lower", "iso_disp_peak"]
    assert med.loc["upper", "base_shear_peak"] > med.loc["lower", "base_shear_peak"]
    assert set(df["record"]) == {*RECORDS, "median"}
    assert df.attrs["seconds"] >= 0.0


def test_the_nominal_row_is_the_building_itself(five_story):
    """The nominal bound of the base law is the bundled building's own analysis."""
    df = building_consequences("bouc_wen", dict(five_story.isolator.params), (0.8, 1.2), records=["elcentro"])
    row = df[(df["record"] == "elcentro") & (df["bound"] == "nominal")].iloc[0]
    rec = ground_motions.load("elcentro")
    ref = time_history_batch(five_story, rec, five_story.isolator.packed()[None, :])
    assert row["iso_disp_peak"] == ref["iso_disp_peak"][0]
    assert row["base_shear_peak"] == ref["base_shear_peak"][0]


def test_a_neutral_effect_gives_the_base_law_bit_for_bit(five_story):
    df = building_consequences("bouc_wen+degradation", dict(five_story.isolator.params), (0.8, 1.25),
                               effect_params={"deg_rate": 0.0}, records=RECORDS[:2])
    base = df[df["effect"] == "none"]
    aug = df[df["effect"] == "degradation"]
    assert len(base) == len(aug) == 3 * 3
    np.testing.assert_array_equal(base["iso_disp_peak"].to_numpy(), aug["iso_disp_peak"].to_numpy())
    np.testing.assert_array_equal(base["base_shear_peak"].to_numpy(), aug["base_shear_peak"].to_numpy())


def test_building_consequences_names_wrong_inputs(five_story):
    p = dict(five_story.isolator.params)
    with pytest.raises(ValueError, match="effect_params"):
        building_consequences("bouc_wen+degradation", p, (0.8, 1.2), records=["elcentro"])
    with pytest.raises(ValueError, match="names no effect"):
        building_consequences("bouc_wen", p, (0.8, 1.2), effect_params={"deg_rate": 1.0})
    with pytest.raises(ValueError, match="lambdas"):
        building_consequences("bouc_wen", p, (1.2, 0.8), records=["elcentro"])


def test_the_figure_labels_both_demands_with_units(five_story):
    df = building_consequences("bouc_wen", dict(five_story.isolator.params), (0.8, 1.2), records=["elcentro"])
    fig = plot_consequences(df, title="five-story")
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["peak isolator displacement [mm]", "peak base shear [kN]"]
