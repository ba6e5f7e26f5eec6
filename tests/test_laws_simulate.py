"""simulate_force at the public boundary: clear ValueErrors, and the kernel contract."""

import numpy as np
import pytest

import rrfrei
from rrfrei.laws import get
from rrfrei.laws.specialise import history

BW = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5)
U = np.linspace(0.0, 0.02, 20)


@pytest.mark.parametrize(
    "law, params, disp, match",
    [
        ("boucwen", BW, U, r"unknown law 'boucwen'; available laws: .*bouc_wen"),
        ("bouc_wen", {k: v for k, v in BW.items() if k != "eta"}, U, r"missing parameter\(s\) eta"),
        ("bouc_wen", {**BW, "zeta": 1.0}, U, r"no parameter\(s\) 'zeta'"),
        ("bouc_wen", {**BW, "alpha1": 1.5}, U, r"alpha1 = 1.5 - is outside its physical bounds"),
        ("bouc_wen", {**BW, "qd": 0.0}, U, r"qd = 0 kN is outside"),
        ("bouc_wen", {**BW, "beta": 0.2, "gamma": -0.3}, U, r"beta \+ gamma = -0.1 must be > 0"),
        ("bouc_wen", {**BW, "eta": float("nan")}, U, r"eta = nan is not finite"),
        ("elastomeric_x", dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002), U,
         r"missing parameter\(s\) n"),
        ("bouc_wen", BW, [0.0, np.nan, 0.01], r"disp is not finite at index 1"),
        # (n, 2) is a path in plan (bouc_wen has a bidirectional form): other shapes are refused
        ("bouc_wen", BW, np.zeros((4, 2, 1)), r"disp must be a 1-D array, got shape \(4, 2, 1\)"),
        ("bouc_wen", BW, np.zeros((4, 3)), r"disp must be an \(n, 2\) array .*got shape \(4, 3\)"),
        ("bouc_wen", BW, [], r"disp must have at least 1"),
    ],
)
def test_bad_input_raises_value_error_naming_the_field(law, params, disp, match):
    with pytest.raises(ValueError, match=match):
        rrfrei.simulate_force(law, params, disp)


def test_bad_time_and_substeps_raise():
    with pytest.raises(ValueError, match="time must be strictly increasing"):
        rrfrei.simulate_force("bouc_wen", BW, U, time=np.zeros_like(U))
    with pytest.raises(ValueError, match="time has 3 values but disp has 20"):
        rrfrei.simulate_force("bouc_wen", BW, U, time=[0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="substeps must be a positive integer"):
        rrfrei.simulate_force("bouc_wen", BW, U, substeps=0)


def test_kernel_failure_names_sample_status_and_state():
    p = {**BW, "eta": 9.181247277429936, "beta": 0.1979643833210143, "gamma": 0.28589263260021625}
    with pytest.raises(ValueError, match=r"failed at sample 1 \(disp = -0.169674 m\): the law's local "
                                         r"Newton iteration did not converge; committed state \[ *1\.0+e-03"):
        rrfrei.simulate_force("bouc_wen", p, [0.001, -0.169674])


@pytest.mark.parametrize("law, p", [
    ("bouc_wen", {**BW, "eta": 1.6}),
    ("bouc_wen", {**BW, "eta": 2.0}),
    ("elastomeric_x", dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0, cd=4.0)),
    ("hdr", dict(a1=60.0, a2=2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4, c4=20.0)),
    ("plasticity", dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.05, mu=2.0)),
    ("linear", dict(k=100.0, c=3.0)),
])
def test_whole_history_driver_equals_step_by_step_dispatch(law, p):
    """The per-law drive loop (fast path) gives the results of the law's step kernel called
    step by step (as Newmark calls it), with time, velocity and substeps: bit-identical, except
    Bouc-Wen with a non-integer eta, whose history driver solves OpenSees' implicit equation
    with its own guarded solver (``rrfrei.laws.bouc_wen``, "Fast solver") and so lands on the
    same root to rounding, not to the bit (tests/test_bouc_wen_solver.py holds it to
    drive_exact)."""
    spec = get(law)
    packed = spec.pack(p)
    t = np.linspace(0.0, 4.0, 81)
    u = 0.02 * np.sin(2 * np.pi * t / 2.0) + 0.002 * np.cos(7 * t)
    f, k = rrfrei.simulate_force(law, p, u, time=t, substeps=3, return_tangent=True)
    exact = law != "bouc_wen" or float(p["eta"]).is_integer()
    scale = float(np.max(np.abs(f)))
    sc = np.array(spec.initial_state)
    st = sc.copy()
    u_prev, t_prev = 0.0, t[0]
    for i in range(u.size):
        du = (u[i] - u_prev) / 3
        dt = (t[i] - t_prev) / 3
        v, dt_eff = (0.0, 1.0) if i == 0 else (du / dt, dt)
        for j in range(3):
            uj = u[i] if j == 2 else u_prev + du * (j + 1)
            fj, kj, status = spec.step(packed, sc, uj, v, dt_eff, st)
            assert status == 0
            sc[:] = st
        if exact:
            assert fj == f[i] and kj == k[i]
        else:
            assert fj == pytest.approx(f[i], rel=1e-13, abs=1e-13 * scale)
            assert kj == pytest.approx(k[i], rel=1e-13, abs=1e-13 * packed[0])
        u_prev, t_prev = u[i], t[i]
    force = np.empty_like(u)
    tang = np.empty_like(u)
    sc = np.array(spec.initial_state)
    assert history(spec)(packed, sc, sc.copy(), u, t, True, 3, force, tang) == (0, -1)
    assert np.array_equal(force, f)  # the law's history driver is what simulate_force calls


@pytest.mark.parametrize("law, p, k0", [
    ("bouc_wen", BW, 100.0),
    ("elastomeric_x", dict(fy=1.0, alpha=0.25, gr=500.0, d2=0.08, tr=0.002, n=15.0),
     500.0 * 3.14159 / 4 * 0.08**2 / 0.03 / 0.25),
    ("hdr", dict(a1=60.0, a2=2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4, c4=20.0),
     60.0),
])
def test_zero_first_increment_returns_the_initial_stiffness(law, p, k0):
    """OpenSees keeps k_t of the virgin element when the increment is exactly zero."""
    f, k = rrfrei.simulate_force(law, p, [0.0, 0.0], return_tangent=True)
    assert np.all(f == 0.0)
    np.testing.assert_allclose(k, k0, rtol=1e-12)
