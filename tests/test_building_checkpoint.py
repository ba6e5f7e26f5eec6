"""A rerun with the same checkpoint folder reuses every building fit, an added effect's refit too:
nothing already computed is fitted again."""

from __future__ import annotations

import pytest

from rrfrei.budget import TimeBudget
from rrfrei.gap.checkpoint import Checkpoint, _fit_or_restore
from structures.shake_table.simulation import BuildingData, Superstructure
from tests._shake_table_truth import PL, model_of


def test_an_effects_refit_is_restored_from_the_checkpoint_not_fitted_again(truth, tmp_path, monkeypatch):
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    cal = BuildingData(tuple(runs), observed=("run1",))
    monkeypatch.setattr(m, "global_evals", 10)
    monkeypatch.setattr(m, "max_nfev", 2)
    aug = m.augment(["isolation_damping"])
    budget = TimeBudget.of(None, "test")
    ck = Checkpoint(tmp_path, m, cal, 0)  # the engine keys the folder by the baseline model
    base = _fit_or_restore(ck, "baseline", m, cal, budget, seed=0)
    fit = _fit_or_restore(ck, "effect-isolation_damping", aug, cal, budget, seed=0, start=[base])

    def refit(*a, **k):
        raise AssertionError("fitted again although the checkpoint holds the fit")

    monkeypatch.setattr(aug, "fit", refit)
    monkeypatch.setattr(m, "fit", refit)
    again = Checkpoint(tmp_path, m, cal, 0)
    assert _fit_or_restore(again, "baseline", m, cal, budget, seed=0).names == base.names
    back = _fit_or_restore(again, "effect-isolation_damping", aug, cal, budget, seed=0, start=[base])
    assert back.names == fit.names and "c_iso" in back.names
    assert back.x_opt == pytest.approx(fit.x_opt, rel=0, abs=0)
    assert again.reused == ["baseline", "effect-isolation_damping"]
