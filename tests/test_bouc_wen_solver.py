"""The fast Bouc-Wen history solver (:mod:`rrfrei.laws._bouc_wen_fast`, the fast-run slot of the
law's history loop) against the plain OpenSees iteration (``bouc_wen.drive_exact``,
:func:`rrfrei.laws.bouc_wen.step` at every step): same forces, same failures, and the fast path
is really taken where the guard allows it and refused where it must be."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from rrfrei.laws import _bouc_wen_fast as fast
from rrfrei.laws import bouc_wen as bw
from rrfrei.laws import get, specialise

SPEC = get("bouc_wen")
DRIVE = specialise.history(SPEC)  # the history loop with the fast solver in its slot


def _hist(n=2000, amp=0.04):
    k = np.arange(1, n + 1)
    return (0.002 + amp * k / n) * np.sin(2 * np.pi * k / 200)


def _run(fn, p, u, substeps=1):
    P = SPEC.pack(p)
    F = np.full(u.size, np.nan)
    T = np.full(u.size, np.nan)
    sc = np.zeros(5)
    st_ = np.zeros(5)
    status = fn(P, sc, st_, u, np.zeros(u.size), False, substeps, F, T)
    return status, F, T, sc, st_


def _fast_count(p, u):
    """Number of sub-steps the fast solver does (the rest go to step())."""
    P = SPEC.pack(p)
    c, x16, x32, stop = fast.fast_constants(P[5])
    lim = np.array([x16, x32, stop])
    sc = np.zeros(5)
    st_ = np.zeros(5)
    F = np.empty(u.size)
    T = np.empty(u.size)
    k = done = 0
    while k < u.size:
        k2 = fast._fast_run(P, c, lim, sc, st_, u, k, 1, F, T)
        done += k2 - k
        if k2 >= u.size:
            break
        v, dt = 0.0, 1.0
        f, kt, status = bw.step(P, sc, u[k2], v, dt, st_)
        assert status == 0
        sc[:] = st_
        k = k2 + 1
    return done


BASE = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.37, beta=0.6, gamma=0.4)


def test_fast_path_is_taken_and_matches_exact_iteration():
    u = _hist()
    s0, F0, T0, sc0, _ = _run(bw.drive_exact, BASE, u)
    s1, F1, T1, sc1, _ = _run(DRIVE, BASE, u)
    assert s0 == s1 == (0, -1)
    assert np.max(abs(F1 - F0)) <= 1e-13 * np.max(abs(F0))
    assert np.max(abs(T1 - T0)) <= 1e-12 * np.max(abs(T0))
    assert abs(sc1[1] - sc0[1]) <= 1e-13
    assert _fast_count(BASE, u) >= 0.95 * u.size


def test_integer_eta_uses_step_only():
    u = _hist(400)
    P = SPEC.pack({**BASE, "eta": 1.0})
    s0, F0, *_ = _run(bw.drive_exact, {**BASE, "eta": 1.0}, u)
    s1, F1, *_ = _run(DRIVE, {**BASE, "eta": 1.0}, u)
    assert s0 == s1 and np.array_equal(F0, F1)
    assert P[5] == 1.0


def test_guard_refuses_near_zero_and_for_huge_steps():
    ee, bmax, emax = 1.37 * 0.37, 0.0, 1.5**1.37
    # z_A tiny: the Kantorovich ball would contain z = 0
    z, r, t = 1e-4, 0.05, 1.0
    G = r * t * z**1.37
    assert not fast._guard(ee, bmax, emax, r, 0.0, z, G, 1 / z, G - r, 1 + G * 1.37 / z)
    # a regular step passes
    z = 0.5
    G = r * t * z**1.37
    assert fast._guard(ee, bmax, emax, r, 0.0, z, G, 1 / z, G - r, 1 + G * 1.37 / z)
    # |z| beyond the size margin (ulp of z too coarse for OpenSees' 1e-12 tolerance)
    z = 100.0
    G = r * t * z**1.37
    assert not fast._guard(ee, bmax, emax, r, 0.0, z, G, 1 / z, G - r, 1 + G * 1.37 / z)


def test_wild_parameters_fall_back_and_fail_at_the_same_sample():
    # large eta and gamma < 0 with big steps: OpenSees' Newton fails; both drivers must agree
    p = dict(k_init=1e4, qd=0.05, alpha1=0.0, alpha2=0.0, mu=2.0, eta=5.3, beta=0.1, gamma=-0.05)
    u = _hist(600, amp=0.05)
    s0, F0, *_ = _run(bw.drive_exact, p, u)
    s1, F1, *_ = _run(DRIVE, p, u)
    assert s0 == s1
    m = np.isfinite(F0)
    assert np.array_equal(m, np.isfinite(F1))
    assert np.max(abs(F1[m] - F0[m]), initial=0.0) <= 1e-12 * max(np.max(abs(F0[m]), initial=0.0), 1e-300)


@settings(max_examples=150, deadline=None)
@given(eta=st.floats(0.2, 6.0).filter(lambda e: e not in (1.0, 2.0, 3.0)),
       beta=st.floats(0.05, 3.0), gamma=st.floats(-3.0, 3.0),
       qd=st.floats(0.01, 10.0), k_init=st.floats(10.0, 1e5), alpha1=st.floats(0.0, 0.9),
       amp=st.floats(1e-4, 0.2), n=st.integers(20, 400), substeps=st.sampled_from([1, 1, 3]),
       seed=st.integers(0, 2**31 - 1))
def test_random_fast_equals_exact(eta, beta, gamma, qd, k_init, alpha1, amp, n, substeps, seed):
    if beta + gamma <= 1e-3:
        return
    p = dict(k_init=k_init, qd=qd, alpha1=alpha1, alpha2=0.0, mu=2.0, eta=eta, beta=beta,
             gamma=gamma)
    rng = np.random.default_rng(seed)
    u = np.cumsum(rng.normal(0.0, amp / np.sqrt(n), n)) + amp * np.sin(np.linspace(0, 6, n))
    u[rng.random(n) < 0.05] = u[0]  # repeated values (du == 0)
    s0, F0, T0, sc0, st0 = _run(bw.drive_exact, p, u, substeps)
    s1, F1, T1, sc1, st1 = _run(DRIVE, p, u, substeps)
    assert s0 == s1
    m = np.isfinite(F0)
    assert np.array_equal(m, np.isfinite(F1))
    scale = max(np.max(abs(F0[m]), initial=0.0), 1e-300)
    assert np.max(abs(F1[m] - F0[m]), initial=0.0) <= 1e-9 * scale
    if s0[0] != 0:  # same committed state at the failure
        assert abs(sc1[1] - sc0[1]) <= 1e-9 * max(1.0, abs(sc0[1]))
