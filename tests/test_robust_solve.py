"""The opt-in robust local solve of Bouc-Wen (``local_solver="robust"``, issue 16.4).

* the default stays OpenSees: same forces, same failure sample, and the failure now names the
  way forward (``local_solver='robust'``);
* with eta < 1, |z|^(eta-1) is unbounded at z = 0 and OpenSees' 25 Newton iterations stall
  there; the robust solve then finds the root of the same backward-Euler equation (residual at
  rounding level) and says where it did so (a deviation from OpenSees);
* wherever OpenSees' iteration converges, the robust run *is* the OpenSees run (bit for bit),
  and the bracketed solver alone finds OpenSees' root to 1e-12 where that root is unique;
* physics of the robust result: |z| <= (beta + gamma)^(-1/eta), closed cycles dissipate;
* the shear-building time history with ``local_solver="robust"`` completes where the default
  fails even after subdivision, and the energy still balances.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ground_motions
import rrfrei
import structures
from rrfrei.errors import NumericalFailure
from rrfrei.laws import bouc_wen as bw
from rrfrei.laws import get, specialise
from rrfrei.simulate import LocalSolverDeviation
from structures import Isolator

SPEC = get("bouc_wen")


def bearing(eta, gamma, beta=0.5):
    """k_init = 1000 kN/m, qd = 10 kN, alpha1 = 0.1: u_y = 11.1 mm."""
    return dict(k_init=1000.0, qd=10.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=eta, beta=beta,
                gamma=gamma)


def coarse_history(period, n=400):
    """Growing cycles sampled at 1-2 u_y per step, with a superposed wobble: many reversals and
    steps that land z near 0."""
    k = np.arange(1, n + 1)
    return 0.04 * np.sin(2 * np.pi * k / period) * np.minimum(1.0, k / 100) + 0.01 * np.sin(0.7 * k)


# (eta, gamma, period of the history, sample where OpenSees' iteration fails: measured with the
# OpenSees-only code before the robust solve existed, and equal to drive_exact's)
FAILING = [(0.51, 0.5, 23, 88), (0.51, -0.25, 41, 95), (0.3, 0.25, 41, 49)]


def _raw(fn, p, u, *extra, substeps=1):
    P = SPEC.pack(p)
    F = np.full(u.size, np.nan)
    T = np.full(u.size, np.nan)
    sc = np.zeros(5)
    st_ = np.zeros(5)
    status = fn(P, sc, st_, u, np.zeros(u.size), False, substeps, F, T, *extra)
    return status, F, sc, st_


def z_of(p, u, F):
    """z from the force (alpha2 = 0): F = qd z + alpha1 k_init u."""
    return (F - p["alpha1"] * p["k_init"] * u) / p["qd"]


def residual(p, u, z):
    """Backward-Euler residual of every step and its scale (the magnitudes of its terms)."""
    uy = p["qd"] / ((1 - p["alpha1"]) * p["k_init"])
    du = np.diff(np.concatenate(([0.0], u)))
    zc = np.concatenate(([0.0], z[:-1]))
    r = du / uy
    t = p["gamma"] + p["beta"] * np.sign(z * du)
    res = z - zc - r * (1.0 - np.abs(z) ** p["eta"] * t)
    scale = np.abs(z) + np.abs(zc) + np.abs(r) * (1.0 + np.abs(z) ** p["eta"] * abs(t))
    return res, scale


def robust(p, u, **kw):
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        F = rrfrei.simulate_force("bouc_wen", p, u, local_solver="robust", **kw)
    devs = [w.message for w in rec if issubclass(w.category, LocalSolverDeviation)]
    return F, devs


# ----------------------------------------------------------------------- the default and its failure
@pytest.mark.parametrize("eta, gamma, period, fail", FAILING)
def test_default_is_opensees_and_its_failure_names_the_sample_and_the_robust_option(
        eta, gamma, period, fail):
    p = bearing(eta, gamma)
    u = coarse_history(period)
    with pytest.raises(NumericalFailure, match=rf"failed at sample {fail} .*did not converge.*"
                                               r"local_solver='robust'"):
        rrfrei.simulate_force("bouc_wen", p, u)
    assert _raw(bw.drive_exact, p, u)[0] == (-2, fail)


# ------------------------------------------------------------------------- the robust solve acts
@pytest.mark.parametrize("eta, gamma, period, fail", FAILING)
def test_robust_completes_solves_the_step_equation_and_reports_where_it_deviated(
        eta, gamma, period, fail):
    p = bearing(eta, gamma)
    u = coarse_history(period)
    F, devs = robust(p, u)
    assert np.all(np.isfinite(F))
    # reported: one warning naming the count and the first sample, samples on the warning
    assert len(devs) == 1
    samples = devs[0].samples
    assert samples[0] == fail and devs[0].law == "bouc_wen"
    assert f"at {samples.size} sample(s) (sample {fail}" in str(devs[0])
    # before the first deviation the run is OpenSees' (bit for bit)
    _, F_os, _, _ = _raw(specialise.history(bw.SPEC), p, u)
    np.testing.assert_array_equal(F[:fail], F_os[:fail])
    # every step, robust or not, solves the backward-Euler equation of z
    res, scale = residual(p, u, z_of(p, u, F))
    assert np.all(np.abs(res) <= 1e-12 * scale)
    assert np.all(np.abs(res[samples]) <= 1e-13 * scale[samples])
    # and at the reported samples OpenSees' iteration fails (or stops away from a root) on this
    # trajectory
    P = SPEC.pack(p)
    for i in samples[:5]:
        dev = np.zeros(i, dtype=np.int64)
        s, _, sc, st_ = _raw(specialise.history(bw.SPEC, True), p, u[:i], dev)
        assert s == (0, -1)
        f, kt, status = bw.step(P, sc, u[i], 0.0, 1.0, st_)
        r = (u[i] - sc[0]) / (P[1] / ((1 - P[2]) * P[0]))
        assert status in (-1, -2) or not bw.near_root(sc[1], r, st_[1], eta, 0.5, gamma)


@pytest.mark.parametrize("eta", [0.3, 0.51])
def test_robust_root_at_and_across_z_equal_zero_with_eta_below_one(eta):
    """f'(z) ~ |z|^(eta-1) is infinite at z = 0: a committed z = 0 (virgin) or tiny, and a step
    whose root is 0 exactly, are solved to rounding."""
    beta, gamma = 0.5, 0.5
    for zc in (0.0, 1e-300, -1e-12, 3e-8):
        for r in (0.2, -0.2, 3.0, -1e-9):
            z, status, it = bw.solve_bracketed(zc, r, eta, beta, gamma)
            assert status == 0 and it < 200
            f = z - zc - r * (1.0 - abs(z) ** eta * (gamma + beta * np.sign(z * r)))
            assert abs(f) <= 4e-16 * (abs(z) + abs(zc) + abs(r) * (1 + abs(z) ** eta))
    # z_C = -r: the root is z = 0 exactly (f(0) = -z_C - r = 0)
    assert bw.solve_bracketed(-0.25, 0.25, eta, beta, gamma)[:2] == (0.0, 0)


# --------------------------------------------------------------- equal to OpenSees where it converges
@settings(max_examples=50, deadline=None)
@given(eta=st.floats(0.2, 6.0), beta=st.floats(0.05, 3.0), gamma_frac=st.floats(-0.99, 1.0),
       qd=st.floats(0.05, 10.0), alpha1=st.floats(0.0, 0.9), amp=st.floats(1e-3, 0.2),
       n=st.integers(20, 300), seed=st.integers(0, 2**31 - 1), substeps=st.sampled_from([1, 1, 3]))
def test_robust_run_is_the_opensees_run_wherever_opensees_converges(eta, beta, gamma_frac, qd,
                                                                   alpha1, amp, n, seed, substeps):
    p = dict(k_init=100.0, qd=qd, alpha1=alpha1, alpha2=0.01, mu=2.0, eta=eta, beta=beta,
             gamma=gamma_frac * beta)
    rng = np.random.default_rng(seed)
    u = np.cumsum(rng.normal(0.0, amp / np.sqrt(n), n)) + amp * np.sin(np.linspace(0, 6, n))
    F_r, devs = robust(p, u, substeps=substeps)
    F_o = _raw(specialise.history(bw.SPEC), p, u, substeps=substeps)[1]
    first = devs[0].samples[0] if devs else u.size
    np.testing.assert_array_equal(F_r[:first], F_o[:first])
    try:
        rrfrei.simulate_force("bouc_wen", p, u, substeps=substeps)
    except NumericalFailure as exc:  # the robust solve acted at (or, see below, before) it
        fail = int(str(exc).split("failed at sample ")[1].split()[0])
        assert first <= fail
    else:
        # where OpenSees completes, a deviation is a step where it "converged" away from a root
        for i in devs[0].samples if devs and substeps == 1 else ():
            dev = np.zeros(i, dtype=np.int64)
            _, _, sc, st_ = _raw(specialise.history(bw.SPEC, True), p, u[:i], dev)
            P = SPEC.pack(p)
            _, _, status = bw.step(P, sc, u[i], 0.0, 1.0, st_)
            r = (u[i] - sc[0]) / (P[1] / ((1 - P[2]) * P[0]))
            assert status != 0 or not bw.near_root(sc[1], r, st_[1], eta, beta, p["gamma"])


@settings(max_examples=50, deadline=None)
@given(eta=st.floats(0.25, 6.0), beta=st.floats(0.01, 3.0), gamma_frac=st.floats(-0.999, 1.0),
       zc_frac=st.floats(-1.0, 1.0), tiny=st.booleans(), log_r=st.floats(-6.0, 1.0),
       sign=st.sampled_from([-1.0, 1.0]))
def test_bracketed_solver_finds_opensees_root_where_it_is_unique(eta, beta, gamma_frac, zc_frac,
                                                                tiny, log_r, sign):
    """gamma <= beta makes f strictly increasing in z (for du > 0; odd symmetry otherwise), so
    OpenSees' converged iterate and the bracketed root are the same root: equal to 1e-12.

    (For gamma > beta and |du| >> u_y, f has spurious roots beyond the bound on the side opposite
    to du, which OpenSees' iteration sometimes converges to; the robust run keeps OpenSees'
    result wherever it converges, tested above.)"""
    gamma = gamma_frac * beta
    zmax = (beta + gamma) ** (-1.0 / eta)
    zc = zc_frac * zmax * (1e-7 if tiny else 1.0)
    r = sign * 10.0**log_r
    p = SPEC.pack(dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=eta, beta=beta,
                       gamma=gamma))
    uy = 1.0 / 90.0
    sc = np.array([0.0, zc, 0.0, 0.0, 0.0])
    st_ = sc.copy()
    _, _, status = bw.step(p, sc, r * uy, 0.0, 1.0, st_)
    z, s2, _ = bw.solve_bracketed(zc, (r * uy) / uy, eta, beta, gamma)
    assert s2 == 0 and abs(z) <= zmax * (1 + 1e-15)
    if status == 0 and bw.near_root(zc, r, st_[1], eta, beta, gamma):
        assert abs(z - st_[1]) <= 1e-12 * max(1.0, abs(z))
    elif status == 0:  # OpenSees stopped away from a root (its step fell below 1e-12 near z = 0)
        assert abs(st_[1]) < 1e-6 and eta < 1.0
        sc2 = sc.copy()
        st2 = sc.copy()
        _, _, s_rob = bw.step_robust(p, sc2, r * uy, 0.0, 1.0, st2)
        assert s_rob == bw.STATUS_ROBUST and st2[1] == z


def test_opensees_false_convergence_near_zero_is_caught_by_the_robust_step():
    """z_C = 1e-308, du/u_y = -1, eta = 0.5: OpenSees' Newton step from z_C is ~1e-154 (f' ~
    |z|^-1/2), so it reports convergence at z ~ 0 where f = 1; the root is -(3 - sqrt 5)/2."""
    p = SPEC.pack(dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=0.5, beta=1.0,
                       gamma=0.0))
    sc = np.array([0.0, 1e-308, 0.0, 0.0, 0.0])
    st_ = sc.copy()
    assert bw.step(p, sc, -1.0 / 90.0, 0.0, 1.0, st_)[2] == 0 and abs(st_[1]) < 1e-100
    st_ = sc.copy()
    assert bw.step_robust(p, sc, -1.0 / 90.0, 0.0, 1.0, st_)[2] == bw.STATUS_ROBUST
    assert st_[1] == pytest.approx(-(3.0 - np.sqrt(5.0)) / 2.0, rel=1e-15)


# ------------------------------------------------------------------------- physics of the result
@pytest.mark.parametrize("eta, gamma, period, fail", FAILING)
def test_robust_z_stays_bounded_and_closed_cycles_dissipate(eta, gamma, period, fail):
    p = bearing(eta, gamma)
    zmax = (p["beta"] + p["gamma"]) ** (-1.0 / eta)
    # whole cycles of the failing history's shape: u returns to 0 every `period` samples
    k = np.arange(1, 8 * period + 1)
    u = 0.04 * np.sin(2 * np.pi * k / period) + 0.01 * np.sin(2 * np.pi * 3 * k / period)
    F, devs = robust(p, u)
    z = z_of(p, u, F)
    assert np.max(np.abs(z)) <= zmax * (1 + 1e-12)
    F2, _ = robust(p, coarse_history(period))
    assert np.max(np.abs(z_of(p, coarse_history(period), F2))) <= zmax * (1 + 1e-12)
    # work of the trapezoidal rule over every full cycle after the first (the elastic part
    # alpha1 k_init u integrates to zero over a closed cycle)
    uu = np.concatenate(([0.0], u))
    FF = np.concatenate(([0.0], F))
    for c in range(1, 8):
        sl = slice(c * period, (c + 1) * period + 1)
        w = np.sum(0.5 * (FF[sl][1:] + FF[sl][:-1]) * np.diff(uu[sl]))
        assert w > 0.0


# --------------------------------------------------------------------------------- time history
def building(eta, qd, gamma=0.5):
    b = structures.load_building("three_story")
    p = dict(k_init=260.0, qd=qd, alpha1=0.33, alpha2=0.0, mu=2.0, eta=eta, beta=0.5, gamma=gamma)
    return replace(b, isolator=Isolator("bouc_wen", p, b.isolator.count, b.isolator.length_scale))


def test_time_history_robust_completes_where_the_default_fails_after_subdivision():
    """Loma Prieta on eta = 0.3: OpenSees' local iteration fails at step 1617 even in 64 substeps."""
    b = building(eta=0.3, qd=0.3)
    rec = ground_motions.load("lomaprieta")
    with pytest.raises(structures.ConvergenceError, match=r"step 1617\) failed even in 64 substeps"
                                                         r".*local_solver='robust'"):
        structures.time_history(b, rec)
    with pytest.warns(LocalSolverDeviation, match=r"at 1 time step\(s\) \(time step 1617\)"):
        r = structures.time_history(b, rec, local_solver="robust")
    np.testing.assert_array_equal(r.robust_steps, [1617])
    assert r.summary()["robust_steps"] == 1
    assert np.all(np.isfinite(r.isolator_force))
    assert r.energy_error < 1e-9
    assert r.energy_error == pytest.approx(structures.dynamics.energy.balance_error(r.energy), rel=1e-9)
    assert r.energy["isolator"][-1] > 0.0
    # up to the failing step it is the default analysis
    head = ground_motions.Record(rec.name, rec.dt, rec.accel[:1617], rec.meta)
    ref = structures.time_history(b, head)
    np.testing.assert_array_equal(r.isolator_disp[:1617], ref.isolator_disp)
    # the batch kernel counts the robust steps per run
    P = np.tile(b.isolator.packed(), (2, 1))
    out = structures.time_history_batch(b, rec, P, n_blocks=1, local_solver="robust")
    assert out["converged"].all() and list(out["robust_steps"]) == [1, 1]
    assert out["iso_disp_peak"][0] == pytest.approx(r.summary()["isolator_disp_peak"], rel=1e-13)
    assert not structures.time_history_batch(b, rec, P[:1], n_blocks=1)["converged"].any()


def test_time_history_robust_is_the_default_wherever_the_default_completes():
    """eta = 0.51 on San Fernando: the default heals its local failures by subdivision, so the
    robust solve (which acts only at the last subdivision level) never acts; without
    subdivision it acts at the failing step."""
    b = building(eta=0.51, qd=1.4)
    rec = ground_motions.load("sanfernando")
    rec = ground_motions.Record(rec.name, rec.dt, rec.accel[:1000], rec.meta)
    ref = structures.time_history(b, rec)
    assert ref.subdivided_steps.size > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = structures.time_history(b, rec, local_solver="robust")
    np.testing.assert_array_equal(r.isolator_disp, ref.isolator_disp)
    np.testing.assert_array_equal(r.isolator_force, ref.isolator_force)
    assert r.robust_steps.size == 0
    with pytest.raises(structures.ConvergenceError, match="step 461"):
        structures.time_history(b, rec, max_subdivisions=0)
    with pytest.warns(LocalSolverDeviation):
        r0 = structures.time_history(b, rec, max_subdivisions=0, local_solver="robust")
    assert r0.robust_steps[0] == 461 and r0.energy_error < 1e-9


# ------------------------------------------------------------------------------------ the option
def test_local_solver_option_is_validated_and_robust_is_only_offered_where_it_exists():
    p = bearing(0.51, 0.5)
    u = coarse_history(23)[:50]
    with pytest.raises(ValueError, match=r"local_solver = 'newton' is invalid: expected one of "
                                         r"\('opensees', 'robust'\)"):
        rrfrei.simulate_force("bouc_wen", p, u, local_solver="newton")
    ex = dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0)
    np.testing.assert_array_equal(rrfrei.simulate_force("elastomeric_x", ex, u, local_solver="robust"),
                                  rrfrei.simulate_force("elastomeric_x", ex, u))
    with pytest.raises(ValueError, match="not available for the bidirectional form of law 'bouc_wen'"):
        rrfrei.simulate_force("bouc_wen", p, np.column_stack([u, 0.5 * u]), local_solver="robust")
    pl = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0)
    np.testing.assert_array_equal(rrfrei.simulate_force("plasticity", pl, u, local_solver="robust"),
                                  rrfrei.simulate_force("plasticity", pl, u))
    with pytest.raises(ValueError, match="local_solver = 'fast' is invalid"):
        structures.time_history(building(0.51, 1.4), ground_motions.load("elcentro"), local_solver="fast")
