"""A prediction beyond the calibrated range says so (issue 28.8), by one mechanism for every model.

- rubber: a test beyond the fitted stretch range, or within 10 % of a chain's locking stretch, is
  named with its file and stretch by ``python -m rubber predict`` (stderr, and per file in
  ``--json``) and by the fit report;
- isolator calibrations: ``rrfrei.calibration.predict`` of a test whose displacement leaves the
  calibration test's range warns and carries the record;
- one helper (:mod:`rrfrei.extrapolation`) for these and the buildings' ``extrapolated`` flag.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rrfrei.extrapolation import ExtrapolationWarning, approaching, beyond, exceeds
from rubber import PRESETS
from rubber.__main__ import main as rubber_main
from rubber.extrapolation import check, locking_stretch, stretch_range
from rubber.io import VHB4910, load_vhb4910, write_test
from rubber.io import Test as RubberTest
from rubber.protocols import protocol2

# a PRF model whose chain B locks at a uniaxial stretch of 4.36 (N = 6.5), the situation of the
# issue: a fit to tests up to stretch 3 predicting tests up to 5.4
PARAMS = PRESETS["A"].replace(N_B=6.5, N_C=30.0)
FITTED = (1.0, 3.0)


@given(st.floats(1.0001, 1e4))
def test_at_the_locking_stretch_the_eight_chain_stretch_is_sqrt_n(n):
    lam = locking_stretch(n)
    assert lam > 1.0
    assert math.sqrt((lam**2 + 2.0 / lam) / 3.0) == pytest.approx(math.sqrt(n), rel=1e-12)


def test_the_locking_stretch_grows_as_sqrt_3n_and_is_1_for_a_chain_locked_at_rest():
    assert locking_stretch(1e6) == pytest.approx(math.sqrt(3e6), rel=1e-6)
    assert locking_stretch(0.5) == 1.0
    assert locking_stretch(6.5) == pytest.approx(4.3637, abs=1e-4)
    with pytest.raises(ValueError, match="N = "):
        locking_stretch(-1.0)


def _relaxation(level: float, name: str) -> RubberTest:
    t, lam = protocol2(levels=(level,), hold=30.0)
    return RubberTest(name, t, lam, np.full(t.size, 0.1))


def test_rubber_check_flags_beyond_the_fitted_range_and_near_a_lock_not_inside():
    inside = _relaxation(2.0, "inside")
    past = _relaxation(3.5, "past")
    vhb = load_vhb4910()  # to stretch 5.41: beyond the range and past chain B's lock (4.36)
    found = check(PARAMS, [inside, past, vhb], fitted_range=FITTED)
    by = {}
    for e in found:
        by.setdefault(e.source, []).append(e)
    assert "inside" not in by
    assert [(e.kind, e.limit) for e in by["past"]] == [("beyond", 3.0)]
    assert by["past"][0].value == pytest.approx(3.5)
    kinds = {e.kind: e for e in by[vhb.name]}
    assert kinds["beyond"].value == pytest.approx(vhb.stretch.max())
    assert kinds["near"].limit == pytest.approx(locking_stretch(6.5))
    assert "chain B" in kinds["near"].reason and "passes the locking stretch" in kinds["near"].message
    # 10 % margin: a test to 0.92 of the lock is flagged, one to 0.85 is not
    lock = locking_stretch(6.5)
    near = check(PARAMS, [_relaxation(0.92 * lock, "n92"), _relaxation(0.85 * lock, "n85")])
    assert [e.source for e in near] == ["n92"]


def test_rubber_predict_names_the_file_and_the_stretch_and_json_carries_it_per_file(tmp_path, capsys):
    inside = tmp_path / "relax_2.csv"
    past = tmp_path / "relax_3p5.csv"
    write_test(inside, _relaxation(2.0, "relax_2"))
    write_test(past, _relaxation(3.5, "relax_3p5"))
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"params": PARAMS.as_dict(), "stretch_range": list(FITTED)}))

    assert rubber_main(["predict", "--params", str(params), str(inside), str(past), str(VHB4910),
                        "--json"]) == 0
    out = capsys.readouterr()
    doc = json.loads(out.out)
    assert set(doc["f"]) == {inside.name, past.name, VHB4910.name}
    ext = doc["extrapolation"]
    assert ext[str(inside)] == []
    assert [(e["kind"], e["value"], e["limit"]) for e in ext[str(past)]] == [("beyond", 3.5, 3.0)]
    assert {e["kind"] for e in ext[str(VHB4910)]} == {"beyond", "near"}
    warned = [ln for ln in out.err.splitlines() if ln.startswith("warning:")]
    assert any(str(past) in ln and "stretch 3.5" in ln and "fitted stretch range" in ln for ln in warned)
    assert any(str(VHB4910) in ln and "locking stretch" in ln for ln in warned)
    assert not any(str(inside) in ln for ln in warned)


def test_rubber_predict_without_a_fitted_range_still_checks_the_locks(tmp_path, capsys):
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"params": PARAMS.as_dict()}))
    assert rubber_main(["predict", "--params", str(params), str(VHB4910), "--json"]) == 0
    out = capsys.readouterr()
    assert [e["kind"] for e in json.loads(out.out)["extrapolation"][str(VHB4910)]] == ["near"]
    assert "no stretch_range" in out.err


def test_a_fit_records_its_stretch_range_and_reports_fitted_tests_near_a_lock():
    from rubber import fit

    t, lam = protocol2(levels=(1.5, 2.5), hold=5.0)
    from rubber.prf import simulate

    test = RubberTest("two_levels", t, lam, simulate(PRESETS["A"], t, lam).nominal)
    r = fit(test, seed=0, restarts=1, max_evals=40, polish=False)
    assert r.stretch_range == stretch_range([test]) == (1.0, pytest.approx(2.5))
    locks = [locking_stretch(c) for c in r.params.to_model().chains]
    near = any(2.5 >= 0.9 * lk for lk in locks)
    assert bool(r.extrapolation) == near
    assert ("warning:" in r.summary()) == near
    assert "fitted stretch range 1 to 2.5" in r.summary()


def test_the_helper_checks_both_sides_or_magnitudes_and_flags_near_a_hard_limit():
    assert beyond("t", "displacement", [-0.01, 0.02], (-0.02, 0.02)) == []
    two = beyond("t", "displacement", [-0.03, 0.05], (-0.02, 0.02), unit="m")
    assert [(e.value, e.limit) for e in two] == [(0.05, 0.02), (-0.03, -0.02)]
    assert "t: displacement 0.05 m goes beyond" in two[0].message
    (peak,) = beyond("run", "displacement", [-0.03, 0.01], (-0.02, 0.025), symmetric=True)
    assert peak.value == 0.03 and peak.limit == 0.025 and peak.ratio == pytest.approx(1.2)
    assert beyond("t", "x", [1.0 + 1e-12], (0.0, 1.0)) == []  # round-off is inside
    assert approaching("t", "stretch", [3.93], 4.36, reason="a lock") is not None
    assert approaching("t", "stretch", [3.92], 4.36, reason="a lock") is None
    np.testing.assert_array_equal(exceeds([0.01, -0.03, 0.02], 0.02), [False, True, False])


def test_an_isolator_prediction_beyond_the_calibrated_displacement_warns_and_says_so():
    from rrfrei.calibration import ConvergenceWarning, calibrate, predict
    from rrfrei.io import ShearTest

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 4.0, 161)
    small = 0.02 * np.sin(2 * np.pi * t)
    cal_test = ShearTest("small", t, small, 800.0 * small + 0.05 * rng.standard_normal(t.size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        cal = calibrate(cal_test, "linear", walkers=8, steps=150, seed=1, progress=False)
    large = ShearTest("large", t, 2.5 * small, 800.0 * 2.5 * small)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        held = predict(cal, large, n=50, seed=0)
    said = [str(w.message) for w in caught if issubclass(w.category, ExtrapolationWarning)]
    assert len(said) == 2 and "large: displacement 0.05 m goes beyond" in said[0], said
    assert [(e.kind, e.source) for e in held.extrapolation] == [("beyond", "large"), ("beyond", "large")]
    assert held.as_dict()["extrapolation"][0]["limit"] == pytest.approx(small.max())
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExtrapolationWarning)
        own = predict(cal, cal_test, n=50, seed=0)
    assert own.extrapolation == ()
