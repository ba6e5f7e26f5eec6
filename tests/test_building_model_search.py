"""How the building's output-error fit searches (structures.shake_table.building_model): a global start
(CMA-ES) before the local least squares, for the baseline over every parameter and for an added
effect's refit over that effect's parameters and the superstructure's; and the robust local solve
in every simulation, its deviations from OpenSees counted and reported, never a lost candidate.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

import ground_motions
import structures
import structures.shake_table.output_error as oe
from rrfrei.laws import get
from structures.shake_table import ShakeTableRun
from structures.shake_table.building_model import BuildingModel
from structures.shake_table.simulation import BuildingData, Superstructure, simulate
from tests._shake_table_truth import PL, model_of


def _rastrigin(a: np.ndarray):
    """Residuals whose sum of squares sum_i (x_i - a_i)^2 + 10 sin^2(pi x_i) has its global
    minimum 0 at the integers ``a`` and a local one near every other integer point."""
    def resid(x):
        return np.concatenate([x - a, np.sqrt(10.0) * np.sin(np.pi * x)])
    return resid


def _batch(resid):
    """The residuals of a batch of points (what ``cma_start`` evaluates, a generation at a time)."""
    return lambda X: [resid(x) for x in X]


def test_the_global_start_leaves_the_basin_a_local_search_stays_in():
    """Started two units from the optimum, least squares stops in the next basin (cost 2 x 4);
    the CMA-ES start of the same box finds the global basin, and least squares from it the
    optimum."""
    a = np.array([1.0, -1.0, 2.0])
    resid = _rastrigin(a)
    x0 = a + 1.9
    lb, ub = a - 10.0, a + 10.0
    local = least_squares(resid, x0, bounds=(lb, ub))
    assert 2 * local.cost > 1.0  # stuck in a local basin
    xg = oe.cma_start(_batch(resid), x0, lb, ub, np.ones(3, bool), 600, seed=0)
    assert xg is not None
    polished = least_squares(resid, xg, bounds=(lb, ub))
    np.testing.assert_allclose(polished.x, a, atol=1e-6)


def test_the_global_start_moves_only_the_coordinates_it_is_given():
    a = np.array([1.0, -1.0, 2.0])
    x0 = a + 1.9
    free = np.array([True, False, True])
    xg = oe.cma_start(_batch(_rastrigin(a)), x0, a - 10.0, a + 10.0, free, 300, seed=1)
    assert xg is not None and xg[1] == x0[1] and np.all(np.abs(xg[free] - x0[free]) > 0)


def test_a_refit_searches_globally_over_the_added_effect_and_the_superstructure(truth, monkeypatch):
    """The baseline's global start varies every parameter; an added effect's refit (from the
    fitted baseline) varies the effect's parameters and the superstructure's stiffness scale and
    damping, the fitted isolator law held."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), {**PL, "qd": 0.8 * PL["qd"]})
    cal = BuildingData(tuple(runs), observed=("run1",))
    seen = []
    real = oe.cma_start

    def spy(resids, x0, lb, ub, free, evals, seed):
        seen.append((tuple(free), evals))
        return real(resids, x0, lb, ub, free, min(evals, 40), seed)

    monkeypatch.setattr(oe, "cma_start", spy)
    base = m.fit(cal, seed=0)
    aug = m.augment(["isolation_damping"])
    aug.fit(cal, seed=0, start=[base])
    names_b, names_a = m.layout.names, aug.layout.names
    assert seen[0] == ((True,) * len(names_b), m.global_evals)
    free_a = {n for n, f in zip(names_a, seen[1][0]) if f}
    assert free_a == {"c_iso", "k_scale", "zeta"} and seen[1][1] == aug.refit_global_evals


def _robust_case():
    """Loma Prieta under the three-story building on a Bouc-Wen layer with eta = 0.1: OpenSees'
    local iteration fails at some steps even in 64 substeps."""
    b = structures.load_building("three_story")
    rec = ground_motions.load("lomaprieta")
    n = rec.accel.size
    run = ShakeTableRun(name="lp", time=np.arange(n) * rec.dt, table_accel=np.asarray(rec.accel),
                        accel=np.zeros((n, 4)), disp=np.zeros((n, 4)),
                        masses=np.array([b.base_mass, *b.story_masses]),
                        level_names=("base", "f1", "f2", "roof"))
    spec = get("bouc_wen")
    p = spec.pack(dict(k_init=2000.0, qd=2.0, alpha1=0.33, alpha2=0.0, mu=2.0, eta=0.1, beta=0.5, gamma=0.5))
    return spec, p, Superstructure.of(b), BuildingData((run,))


def test_a_simulation_where_opensees_iteration_fails_completes_and_counts_its_deviations():
    spec, p, sup, data = _robust_case()
    tally: dict = {}
    st, out = simulate(spec, p, sup, data, tally=tally)
    assert st == 0 and np.all(np.isfinite(out["lp"]["isolator_disp"]))
    assert tally["robust_sims"] == 1 and tally["robust_steps"] >= 1


def test_the_fit_reports_the_robust_solves_deviations(truth, monkeypatch):
    """Every simulation of the search tallies one robust step: the fit counts the simulations and
    says so in its note."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    m.global_evals = 0
    real = BuildingModel.simulate

    def deviating(self, x, data, tally=None):
        if tally is not None:
            tally["robust_steps"] = tally.get("robust_steps", 0) + 2
            tally["robust_sims"] = tally.get("robust_sims", 0) + 1
        return real(self, x, data, tally)

    monkeypatch.setattr(BuildingModel, "simulate", deviating)
    fit = m.fit(BuildingData(tuple(runs), observed=("run1",)), seed=0)
    assert fit.robust_sims == fit.nfev > 0
    assert f"at {2 * fit.nfev} time steps of {fit.nfev} of {fit.nfev} simulations" in fit.note
    state = m.fit_state(fit)
    assert m.restore(state).robust_sims == fit.robust_sims


def test_with_a_global_search_a_refit_starts_once_per_given_fit(truth):
    """The global search's box holds the added effect's neutral value, so the local screen starts
    once per given fit (the effect at the catalogue's start); without a global search it starts
    at the neutral value too."""
    b, runs = truth
    m = model_of(runs, Superstructure.of(b), PL)
    base = m.fit(BuildingData(tuple(runs), observed=("run1",)), seed=0)
    aug = m.augment(["isolation_damping"])
    starts = aug.starts([base])
    assert len(starts) == 1 and starts[0]["c_iso"] > 0.0
    aug.refit_global_evals = 0
    assert sorted(s["c_iso"] > 0.0 for s in aug.starts([base])) == [False, True]


def test_the_global_start_searches_a_single_coordinate_too():
    """One free coordinate (CMA-ES needs two: a dummy one is added): a better point, the other
    coordinate held."""
    a = np.array([1.0, -1.0])
    resid = _rastrigin(a)
    x0 = a + np.array([1.9, 0.0])
    xg = oe.cma_start(_batch(resid), x0, a - 10.0, a + 10.0, np.array([True, False]), 200, seed=0)
    assert xg is not None and xg[1] == x0[1]
    assert resid(xg) @ resid(xg) < resid(x0) @ resid(x0)
