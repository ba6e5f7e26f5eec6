"""Gap diagnosis: definitions, segmentation, screens, the engine's rules, CLI (the validation
table: tests/test_gap_validate.py)."""

import json

import numpy as np
import pytest

from rrfrei import simulate_force
from rrfrei.app.cli import main
from rrfrei.gap import diagnose_gap
from rrfrei.gap.catalogue import ScreenContext, screen_all
from rrfrei.gap.diagnose import _monotone_amplitude
from rrfrei.gap.model import white_noise
from rrfrei.gap.residuals import cycle_levels, gap, segment_table, systematic_gap
from rrfrei.gap.validate import FIXED, make_tests
from rrfrei.io import ShearTest
from rrfrei.protocols import protocol

PL = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}


def test_gap_is_nrmse_and_its_systematic_part_removes_the_noise_variance():
    y = np.array([1.0, -1.0, 1.0, -1.0])
    f = y + np.array([0.2, -0.2, 0.2, -0.2])
    assert gap(y, f) == pytest.approx(0.2)
    assert systematic_gap(y, f, 0.0) == pytest.approx(0.2)
    assert systematic_gap(y, f, 0.12) == pytest.approx(np.sqrt(0.04 - 0.0144))
    assert systematic_gap(y, f, 0.3) == 0.0


def test_white_noise_level_ignores_a_smooth_systematic_misfit():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 100, 4000)
    r = 0.5 * np.sin(2 * np.pi * t / 10) + rng.normal(0, 0.05, t.size)
    assert white_noise(r) == pytest.approx(0.05, rel=0.1)


def test_protocol1_has_four_amplitude_levels_of_three_cycles_each():
    t, u = protocol(1)
    seg = cycle_levels(u)
    assert seg.level_amp == pytest.approx([0.005, 0.01, 0.02, 0.03], rel=0.01)
    for lev in range(4):
        cycles = set(seg.cycle[seg.level == lev])
        assert len(cycles) == 3
        first = set(seg.cycle[(seg.level == lev) & seg.first])
        assert first == {min(cycles)}
    assert _monotone_amplitude(ShearTest("p1", t, u, np.sin(u)))
    t2, u2 = protocol(2)
    assert not _monotone_amplitude(ShearTest("p2", t2, u2, np.sin(u2)))


def test_segment_shares_sum_to_one_on_every_axis_and_name_the_misfit_segment():
    t, u = protocol(1)
    f = simulate_force("plasticity", PL, u, time=t)
    rng = np.random.default_rng(1)
    y = f + rng.normal(0, 0.01, f.size) + np.where(u > 0, 0.1 * f, 0.0)  # misfit only for u > 0
    test = ShearTest("t", t, u, y)
    table = segment_table(test, f, f - 0.02, f + 0.02, 0.01)
    for axis, grp in table.groupby("axis"):
        assert grp.error_share.sum() == pytest.approx(1.0), axis
    top = table.iloc[0]
    assert (top.axis, top.segment) in {("sign", "u >= 0")} or top.excess > 10
    sign = table[table.axis == "sign"].set_index("segment")
    assert sign.loc["u >= 0", "error_share"] > 0.9
    assert sign.loc["u < 0", "rms_over_noise"] == pytest.approx(1.0, rel=0.15)


def _ctx(y, f, t, u, has_time=True):
    from rrfrei.energy import dissipated_energy
    from rrfrei.gap.model import velocity

    test = ShearTest("t", t, u, y, has_time=has_time)
    return ScreenContext(disp=u, vel=velocity(test), force_pred=f, resid=y - f,
                         energy=dissipated_energy(u, y), first_cycle=cycle_levels(u).first,
                         has_time=has_time)


@pytest.mark.parametrize("effect,values", [("rate", {"rate_c": 10.0}), ("asymmetry", {"asym": 0.15}),
                                           ("rollover", {"roll_k": -20.0, "roll_onset": 0.012})])
def test_the_signature_screen_of_an_effect_ranks_it_first_on_its_own_residuals(effect, values):
    t, u = protocol(1)
    f = simulate_force("plasticity", PL, u, time=t)
    y = simulate_force(f"plasticity+{effect}", {**PL, **values}, u, time=t)
    scores = screen_all(_ctx(y, f, t, u))
    assert max(scores, key=lambda k: scores[k] if np.isfinite(scores[k]) else -1) == effect


def test_rate_cannot_be_judged_without_a_time_column():
    t, u = protocol(1)
    tests = make_tests("control", 0, reduced=True)
    cal = ShearTest("no-time", np.arange(len(tests[0])), tests[0].disp, tests[0].force, has_time=False)
    rep = diagnose_gap(cal, "plasticity", fixed=FIXED, effects=["rate", "asymmetry"], draws=50)
    assert [s.effect for s in rep.ranking] == ["asymmetry"]
    assert any("rate effects cannot be judged" in n for n in rep.notes)
    assert rep.as_dict()["gap_before"]["holdout"] is None


def _kernel_tests(effect_values: dict, seed: int = 0) -> list[ShearTest]:
    """Protocols 1-4 (10 Hz) of ``plasticity+degradation`` with ``effect_values``, 1 % noise."""
    rng = np.random.default_rng(seed)
    out = []
    for k in (1, 2, 3, 4):
        t, u = protocol(k, rate=10.0)
        f = simulate_force("plasticity+degradation", {**PL, **effect_values}, u, time=t)
        out.append(ShearTest(f"protocol{k}", t, u, f + rng.normal(0, 0.01 * np.abs(f).max(), f.size)))
    return out


@pytest.mark.parametrize("values,variant", [
    ({"deg_rate": 0.0, "deg_travel": 0.25, "deg_exp": 0.15}, "cycles"),  # fades with the cycle count
    ({"deg_rate": 0.08}, ""),  # fades with the work: the primary fit stands
])
def test_a_variant_stands_for_its_effect_only_when_the_held_out_blocks_ask_for_it(values, variant):
    tests = _kernel_tests(values)
    rep = diagnose_gap(tests[0], "plasticity", holdout=tests[1:], fixed=FIXED, effects=["degradation"],
                       draws=30, combine=False)
    top = rep.ranking[0]
    assert rep.verdict == "degradation" and top.variant == variant
    assert top.label == ("degradation (cycles)" if variant else "degradation")
    assert rep.as_dict()["ranking"][0]["variant"] == variant
    assert any("variant 'cycles'" in n for n in rep.notes) == bool(variant)
    if variant:  # the fit that stands is the variant's: its amplitude exponent moved off 1
        assert top.params["deg_exp"] < 0.6
    else:
        assert top.params["deg_exp"] == 1.0


def test_a_variant_is_checked_where_it_is_given():
    from rrfrei.gap.model import IsolatorModel

    m = IsolatorModel("plasticity", fixed=FIXED).augment(["degradation"], variants={"degradation": "cycles"})
    assert m.variant == {"degradation": "cycles"} and m.variants("rollover") == ("smooth",)
    assert m.augment(["rate"]).variant == {"degradation": "cycles"}  # kept when effects are added
    t = make_tests("control", 0, reduced=True)[0]
    assert m.checkpoint_key(t) != IsolatorModel("plasticity+degradation", fixed=FIXED).checkpoint_key(t)
    with pytest.raises(ValueError, match="effect 'degradation' has no variant 'fast'; its variants: cycles"):
        IsolatorModel("plasticity+degradation", variants={"degradation": "fast"})
    with pytest.raises(ValueError, match="variant 'smooth' given for effect 'rollover'"):
        IsolatorModel("plasticity+degradation", variants={"rollover": "smooth"})


def _write(test: ShearTest, path):
    path.write_text("time_s,disp_m,force_kN\n" + "\n".join(
        f"{a:.6f},{b:.8f},{c:.8f}" for a, b, c in zip(test.time, test.disp, test.force)))
    return path


def test_cli_gap_prints_the_json_summary_and_writes_the_report(tmp_path, capsys):
    tests = make_tests("asymmetry", 0, reduced=True)
    p1, p2 = _write(tests[0], tmp_path / "p1.csv"), _write(tests[1], tmp_path / "p2.csv")
    code = main(["gap", str(p1), "--law", "plasticity", "--holdout", str(p2), "--effects", "asymmetry",
                 "rate", "--out", str(tmp_path / "out"), "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"law", "verdict", "evidence", "diagnosis", "combination", "where", "ranking",
                        "gap_before", "gap_after"}
    assert out["diagnosis"] == "asymmetry" and out["combination"][0] == "asymmetry"
    assert out["verdict"] == "asymmetry" and out["evidence"]["named"]["effect"] == "asymmetry"
    assert set(out["where"][0]) == {"axis", "segment", "error_share", "coverage"}
    assert set(out["ranking"][0]) == {"effect", "variant", "delta_elpd", "se", "shrink_calibration",
                                      "shrink_holdout", "passes_rule", "named", "why", "calibration_blocks",
                                      "holdout_blocks", "shrink", "shrink_on"}
    assert out["gap_after"]["holdout"] < out["gap_before"]["holdout"]
    for name in ("report.md", "gap_map.png", "loops.png", "ranking.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0


@pytest.mark.parametrize("argv,msg", [
    (["gap", "missing.csv", "--law", "plasticity"], "missing.csv"),
    (["gap", "protocol1", "--law", "nolaw"], "unknown law 'nolaw'"),
    (["gap", "protocol1", "--law", "plasticity", "--effects", "creep"], "unknown effect 'creep'"),
    (["gap-validate", "--seeds", "0"], "positive integer"),
])
def test_cli_user_errors_are_one_line_on_stderr_with_exit_2(argv, msg, capsys):
    with pytest.raises(SystemExit) if argv[0] == "gap-validate" else _nullctx() as exc:
        code = main(argv)
    code = exc.value.code if argv[0] == "gap-validate" else code
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert msg in err and "\n" not in err


class _nullctx:
    def __enter__(self):
        return None

    def __exit__(self, *a):
        return False


def test_cli_help_shows_an_example(capsys):
    for cmd in ("gap", "gap-validate"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        assert "Example:" in capsys.readouterr().out
