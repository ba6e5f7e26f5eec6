"""gap-validate (issue 12.4): generator forms unlike the catalogue, seeded cases, controls, the
parallel resumable table, its report and CLI; slow: the reduced run, and a subset of the table that
covers every form of every effect (seeds 0-2, :data:`SUBSET_SEEDS`) against the issue's goals (the
full table is the command of docs/gap/validation.md)."""

import json
import math
import time

import numpy as np
import pandas as pd
import pytest

from rrfrei.app.cli import main
from rrfrei.gap.catalogue import catalogue
from rrfrei.gap.validate import CASES, validate
from rrfrei.gap.validation import (
    CONTROLS,
    FIXED,
    FORMS,
    FULL,
    REDUCED,
    VERDICTS,
    Case,
    Settings,
    ValidationResult,
    cases,
    make_case_tests,
    run_case,
    run_table,
)
from rrfrei.gap.validation import run as run_module
from rrfrei.gap.validation.report import markdown, write

ISSUE_12_EFFECTS = ("degradation", "mullins", "rollover", "rate", "asymmetry", "slip", "stiffening",
                    "pinching", "scragging")


def _effect_part(effect: str, form: str, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free force with the effect at mid-size minus the base force, protocol 1 (10 Hz)."""
    d = make_case_tests(Case(effect, form, seed), rate=10.0, size_quantile=0.5, noise=("gaussian", 0.0))
    base = make_case_tests(Case("control", "gaussian_0.5%", seed), rate=10.0, noise=("gaussian", 0.0))
    return d.tests[0].force - base.tests[0].force, base.tests[0].force


def test_every_effect_of_issue_12_has_three_forms_of_different_shape():
    assert set(FORMS) == set(ISSUE_12_EFFECTS)
    for effect, forms in FORMS.items():
        assert len(forms) >= 3 and len({f.name for f in forms}) == len(forms), effect
        parts = {f.name: _effect_part(effect, f.name)[0] for f in forms}
        for a in parts:
            for b in parts:
                if a < b:  # different shape: no rescaling of one effect part gives the other
                    x, y = parts[a], parts[b]
                    k = float(x @ y / (y @ y))
                    assert np.linalg.norm(x - k * y) > 0.08 * np.linalg.norm(x), (effect, a, b)


@pytest.mark.parametrize("effect,form", [("mullins", "erf_energy"), ("asymmetry", "tanh_disp")])
def test_the_fitted_catalogue_effect_does_not_reproduce_the_form_to_noise_level(effect, form):
    """The catalogue's own kernel, refitted to noise-free data of the form as the diagnosis fits
    it (the primary fit and every variant), still misses by more than the table's largest noise
    (2 % of the peak force): the form is not the kernel.  Most forms are within it on the
    calibration protocol (docs/gap/validation.md, "How far each form is from the catalogue"),
    and yet tell apart on the held-out protocols; these two are not, whatever the fit."""
    from rrfrei.gap.model import IsolatorModel
    from rrfrei.gap.residuals import gap
    from rrfrei.laws import get

    data = make_case_tests(Case(effect, form, 0), rate=5.0, size_quantile=1.0, noise=("gaussian", 0.0))
    test = data.tests[0]
    model = IsolatorModel(get("plasticity"), fixed=FIXED, draws=20)
    for variant in ("", *model.augment([effect]).variants(effect)):
        fit = model.augment([effect], variants={effect: variant}).fit(test, seed=0)
        rms = float(np.sqrt(np.mean((test.force - fit.predict(test).mean) ** 2)))
        assert rms > 0.02 * np.abs(test.force).max(), variant
        assert gap(test.force, fit.predict(test).mean) > 0.02, variant


def test_forms_change_the_force_in_the_direction_of_their_physics():
    u = make_case_tests(Case("control", "gaussian_0.5%", 0), rate=10.0).tests[0].disp
    d, fb = _effect_part("degradation", "cycle_count")
    assert np.all(d * fb <= 1e-12) and np.any(d * fb < 0)  # |F| fades
    d, _ = _effect_part("stiffening", "exponential")
    assert np.all(d * u >= -1e-12) and np.any(d * u > 0)  # stiffer with |u|
    d, _ = _effect_part("rollover", "quadratic")
    assert np.all(d * u <= 1e-12) and np.all(d[np.abs(u) < 0.01] == 0)  # softer beyond its onset only
    slip = make_case_tests(Case("slip", "elastic_plastic", 0), rate=10.0, size_quantile=0.0,
                           noise=("gaussian", 0.0)).tests[0]
    _, fb = _effect_part("slip", "elastic_plastic")
    assert np.abs(slip.force).max() <= FORMS["slip"][0].size_at(0.0) * np.abs(fb).max() + 1e-9  # capped


def test_a_case_is_seeded_and_reproducible_and_independent_of_the_others():
    a = make_case_tests(Case("asymmetry", "sided_strength", 3), rate=5.0)
    b = make_case_tests(Case("asymmetry", "sided_strength", 3), rate=5.0)
    c = make_case_tests(Case("asymmetry", "sided_strength", 4), rate=5.0)
    for x, y in zip(a.tests, b.tests):
        np.testing.assert_array_equal(x.force, y.force)
    assert a.size == b.size and a.noise_sd == b.noise_sd
    assert not np.array_equal(a.tests[0].force, c.tests[0].force)
    assert Case("rate", "maxwell", 1).base == "bouc_wen" and Case("rate", "maxwell", 2).base == "plasticity"


def test_sizes_are_stratified_small_to_large_over_ten_seeds():
    for effect, forms in FORMS.items():
        for f in forms:
            q = sorted(Case(effect, f.name, s).size_quantile() for s in range(10))
            assert [int(10 * x) for x in q] == list(range(10)), f.label
            lo, hi = f.size_range
            assert lo < hi and f.size_at(0.0) == lo and f.size_at(1.0) == pytest.approx(hi)


def test_controls_have_the_noise_of_their_name():
    def noise(name):
        d = make_case_tests(Case("control", name, 0), rate=20.0)
        base = make_case_tests(Case("control", name, 0), rate=20.0, noise=("gaussian", 0.0))
        return np.concatenate([t.force - b.force for t, b in zip(d.tests, base.tests)]), d

    e, d = noise("ar1_0.8")
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(0.8, abs=0.05)
    e, d = noise("student_t3")
    kurt = np.mean((e - e.mean()) ** 4) / e.var() ** 2
    assert kurt > 4.5  # heavy tails (Gaussian: 3)
    e, d = noise("gaussian_3%")
    assert e.std() == pytest.approx(d.noise_sd * np.abs(d.tests[0].force).max(), rel=0.1)
    assert d.effect_gap == 0.0 and set(CONTROLS) >= {"gaussian_0.5%", "gaussian_3%", "student_t3", "ar1_0.8"}


def test_cases_follow_the_catalogue_and_reject_unknown_names():
    known = catalogue()
    cl = cases(2)
    effects = {c.effect for c in cl} - {"control"}
    assert effects == {e for e in FORMS if e in known}  # new catalogue effects join when they exist
    assert len(cl) == 2 * (3 * len(effects) + len(CONTROLS))
    assert len(cases([0], forms="rotate", controls=())) == len(effects)
    with pytest.raises(ValueError, match="creep"):
        cases(1, effects=["creep"])
    with pytest.raises(ValueError, match="seeds"):
        cases(0)
    with pytest.raises(ValueError, match="forms"):
        cases(1, forms="some")


def _fake_row(case, settings=FULL, deadline=None):
    verdict = case.effect if case.effect != "control" else "none"
    if case.effect == "mullins":
        verdict = "degradation"
    return {"key": case.key, "effect": case.effect, "form": case.form, "seed": case.seed, "base": case.base,
            "settings": settings.signature, "size": 0.1, "size_quantile": 0.5, "noise": "gaussian",
            "noise_sd": 0.01, "effect_gap": 0.1, "verdict": verdict, "combination": verdict,
            "gap_before": 0.1, "gap_after": 0.02, "systematic_before": 0.1, "systematic_after": 0.02,
            "shrink": 0.8 if verdict not in VERDICTS else float("nan"), "best": verdict, "best_shrink": 0.8,
            "seconds": 0.0, "note": ""}


def test_the_table_runs_in_two_processes_checkpoints_each_case_and_a_rerun_resumes(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(run_module, "run_case", _fake_row)
    cl = cases([0, 1], effects=["degradation", "mullins"], controls=("ar1_0.8",))
    ck = tmp_path / "cases.jsonl"
    res = run_table(cl, FULL, workers=2, checkpoint=ck, progress=False)
    assert list(res.cases.key) == [c.key for c in cl]  # in case order, whatever finished first
    assert len(ck.read_text().splitlines()) == len(cl)
    monkeypatch.setattr(run_module, "run_case", lambda *a: calls.append(a) or _fake_row(*a))
    again = run_table(cl, FULL, workers=1, checkpoint=ck, progress=False)
    assert calls == [] and again.reused == len(cl)
    pd.testing.assert_frame_equal(again.cases, res.cases, check_dtype=False)
    other = Settings(rate=10.0, draws=100)  # other settings: nothing reused
    run_table(cl[:1], other, workers=1, checkpoint=ck, progress=False)
    assert len(calls) == 1


def test_a_case_past_the_table_deadline_is_not_run():
    row = run_case(Case("rate", "maxwell", 0), REDUCED, deadline=time.time() - 1.0)
    assert row["verdict"] == "not run"
    res = ValidationResult(pd.DataFrame([row, _fake_row(Case("rate", "maxwell", 1))]))
    assert res.not_run == 1 and len(res.effect_cases) == 1


def test_summaries_and_report_say_plainly_which_goals_are_missed(tmp_path):
    cl = cases([0, 1], effects=["degradation", "mullins"], controls=("ar1_0.8",))
    rows = [_fake_row(c) for c in cl]
    rows[-1]["verdict"] = "slip"  # a false alarm on the last control
    res = ValidationResult(pd.DataFrame(rows), FULL, 12.0)
    conf = res.confusion
    assert list(conf.index) == ["degradation", "mullins", "control"]
    assert list(conf.columns)[-3:] == list(VERDICTS) and "slip" in conf.columns
    assert conf.loc["mullins", "degradation"] == 6 and conf.loc["degradation", "degradation"] == 6
    assert res.accuracy == 0.5 and res.false_alarms == 1
    per = res.top1("effect")
    assert per.loc["mullins", "miss_rate"] == 1.0 and per.loc["degradation", "top1"] == 1.0
    g = res.goals()
    assert not g["top1_per_effect_ge_95"]["met"] and g["top1_per_effect_ge_95"]["missed_by"] == ["mullins"]
    assert not g["no_false_alarm"]["met"] and g["shrink_ge_50_when_named"]["met"]
    md = markdown(res)
    assert "**missed** for mullins (0 %)" in md and "no false alarm: **missed** (1 of 2 controls" in md
    assert "shrink >= 50 % whenever an effect is named: **met**" in md
    paths = write(res, tmp_path)
    data = json.loads(paths["validation.json"].read_text())
    assert data["false_alarms"] == 1 and data["confusion"]["mullins"]["degradation"] == 6
    floats = [v for r in data["cases"] for v in r.values() if isinstance(v, float)]
    assert all(math.isfinite(v) for v in floats)  # NaN written as null
    assert paths["validation_confusion.png"].stat().st_size > 0


def test_cli_writes_the_report_json_figure_and_checkpoint(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(run_module, "run_case", _fake_row)
    out = tmp_path / "gv"
    code = main(["gap-validate", "--seeds", "1", "--effects", "slip", "--out", str(out), "--workers", "1",
                 "--no-progress"])
    assert code == 0
    text = capsys.readouterr().out
    assert "false alarms 0 of 4 controls" in text and "top-1 100 %" in text
    for name in ("validation.md", "validation.json", "validation_confusion.png", "validation_cases.jsonl"):
        assert (out / name).stat().st_size > 0
    assert "--effects slip" in (out / "validation.md").read_text()


SUBSET_SEEDS = (0, 1, 2)
"""The slow tier's share of the table of docs/gap/validation.md (seeds 0-9, written by
``rrfrei gap-validate --seeds 10``): seeds 0, 1 and 2 of every form of every catalogue effect and
of the four controls, 93 of the 310 cases.  Each form is drawn at the size strata b, b+3 and b+6
of its ten (``Case.size_quantile``: b = (3 seed + crc) mod 10), so every form is tried once in the
smallest four tenths of its size range and once in the largest four, on both base laws (even
seeds plasticity, odd seeds bouc_wen).  About 260 s of CPU (the table's 967 s: odd seeds cost
twice the even ones), 2 processes."""


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    """(the subset's result, its checkpoint): every case of :data:`SUBSET_SEEDS` diagnosed in two
    processes, each finished case written to the checkpoint (which the reduced run reads)."""
    ck = tmp_path_factory.mktemp("gap_validate") / "validation_cases.jsonl"
    return validate(list(SUBSET_SEEDS), workers=2, checkpoint=ck), ck


@pytest.mark.slow
def test_reduced_run_names_each_withheld_effect_by_its_first_form_and_no_effect_on_the_controls(table):
    """Seed 0, each effect of issue 7 by its first form at the size seed 0 draws (5 Hz, 50
    draws), and the four controls: the reduced run of issue 7.  Its 10 cases are cases of the
    table's subset with the same settings (``REDUCED`` is ``FULL``), so the run resumes every one
    of them from the subset's checkpoint instead of diagnosing them a second time."""
    full, ck = table
    res = validate([0], reduced=True, forms="first", cases=CASES, checkpoint=ck)
    assert len(res.cases) == len(CASES) - 1 + len(CONTROLS)
    # every row is the subset's own, timings included: nothing was diagnosed a second time
    mine = full.cases.set_index("key").loc[list(res.cases.key)].reset_index()
    pd.testing.assert_frame_equal(res.cases.reset_index(drop=True), mine[list(res.cases.columns)],
                                  check_dtype=False)
    e, c = res.effect_cases, res.control_cases
    wrong = e[e.effect != e.verdict]
    assert wrong.empty, wrong[["key", "verdict", "best", "best_shrink"]].to_string()
    assert (e.shrink >= 0.5).all(), e[["key", "shrink"]].to_string()
    assert len(c) == len(CONTROLS) and res.false_alarms == 0
    assert c.verdict.isin(["none", "unexplained"]).all(), c[["key", "verdict"]].to_string()
    assert res.confusion.shape == (len(CASES), len(CASES) - 1 + len(VERDICTS))


@pytest.mark.slow
def test_table_subset_runs_every_case_of_every_form_and_names_no_effect_on_a_control(table):
    res, _ = table
    assert res.not_run == 0
    expected = {(e, f.name) for e, forms in FORMS.items() if e in catalogue() for f in forms}
    for seed in SUBSET_SEEDS:  # every form of every catalogue effect, on each seed
        got = set(map(tuple, res.effect_cases.loc[res.effect_cases.seed == seed, ["effect", "form"]].values))
        assert got == expected, seed
    assert len(res.control_cases) == len(CONTROLS) * len(SUBSET_SEEDS)
    assert res.false_alarms == 0, res.control_cases[["key", "verdict"]].to_string()


@pytest.mark.slow
def test_table_subset_names_every_effect_top1_95(table):
    """The table's goal is top-1 >= 95 % for each effect over its 30 cases (3 forms x 10 seeds:
    at most one miss; met in docs/gap/validation.md, slip 29 of 30, the others 30 of 30).  The
    subset has 9 cases per effect, where 95 % would be 9 of 9, a stricter goal than the table's:
    one miss in nine is what a top-1 rate of 95 % gives in 30 % of subsets (binomial, 9 draws),
    and the table's own slip miss (the smooth slider at seed 0) is in the subset.  So the
    per-effect bound is the table's own count, at most one miss per effect (two or more in nine
    happen with probability 7 % at a rate of 95 %, 23 % at 90 %, 56 % at 80 %), and the pooled
    bound is the goal's rate itself: top-1 >= 95 % over the 81 effect cases of the subset (at
    most 4 misses), which a rate of 90 % passes with probability 8 %."""
    res, _ = table
    per = res.top1("effect")
    assert (per.cases == 3 * len(SUBSET_SEEDS)).all(), per.to_string()
    assert (per.cases - per.named <= 1).all(), per.to_string()
    assert per.named.sum() >= 0.95 * per.cases.sum(), per.to_string()


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "issue 12 goal not met (docs/gap/validation.md): 4 named cases of the table shrink the held-out "
    "systematic gap by less than 50 % (40 before the effect variants, 53 before the rate strength "
    "and slip's static capacity, 72 before the slack, travel and exponent kernels; median 0.86, "
    "min 0.43): rollover cubic at its two smallest sizes (0.45 at seed 0, 0.43 at seed 6: the smooth "
    "variant does not pass the block test against the hinge), a smooth slider (0.498, seed 2) and a "
    "smooth knee (0.495, seed 6); two of them (seeds 0 and 2) are in the slow tier's subset; "
    "strict: a pass means the goal is met on the subset, then rerun the table"))
def test_table_subset_shrinks_the_held_out_gap_by_half_whenever_an_effect_is_named(table):
    res, _ = table
    s = res.shrink_named
    assert (s >= 0.5).all(), res.ran.loc[s.index[s < 0.5], ["key", "verdict", "shrink"]].to_string()
