"""The synthetic shake-table generator (issue 27.7) is right on its own, before it judges the
diagnosis: its linear building is openseespy's, its energy balances, its isolation force is
-sum m_i a_i, and its runs are what the shake-table readers return, with noise on every channel.
"""

from __future__ import annotations

import numpy as np
import pytest

from structures.shake_table import ShakeTableRun, isolation_test
from structures.shake_table.synthetic import (
    DISP_NOISE_M,
    SyntheticBuilding,
    energy_balance,
    simulate_building,
    synthetic_sequence,
    table_motion,
    with_effect,
)

LINEAR = SyntheticBuilding(qd=0.0, alpha=0.1, c_iso=40.0)  # isolators: 2000 kN/m + 40 kN s/m


def _openseespy_linear(ops, b: SyntheticBuilding, ag: np.ndarray, dt: float) -> np.ndarray:
    """Relative displacements (n, L) [m] of the linear building by openseespy (1-D, zero-length
    springs and dashpots, Newmark average acceleration at dt / 10)."""
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    L = len(b.masses)
    ops.node(0, 0.0)
    ops.fix(0, 1)
    for i in range(L):
        ops.node(i + 1, 0.0)
        ops.mass(i + 1, b.masses[i])
    cst = 2.0 * b.zeta * np.asarray(b.stiffness) / b.omega1()
    ks = [b.alpha * b.k_init, *b.stiffness]
    cs = [b.c_iso, *cst]
    for j in range(L):  # element j between node j and j+1 (0: the isolators)
        ops.uniaxialMaterial("Elastic", 10 + j, ks[j])
        ops.uniaxialMaterial("Viscous", 100 + j, cs[j], 1.0)
        ops.uniaxialMaterial("Parallel", 1000 + j, 10 + j, 100 + j)
        ops.element("zeroLength", j + 1, j, j + 1, "-mat", 1000 + j, "-dir", 1)
    ops.timeSeries("Path", 1, "-dt", dt, "-values", *ag.tolist())
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.test("NormDispIncr", 1e-12, 20)
    ops.algorithm("Newton")
    ops.integrator("Newmark", 0.5, 0.25)
    ops.analysis("Transient")
    out = np.zeros((ag.size, L))
    sub = 10
    for i in range(1, ag.size):
        for _ in range(sub):
            assert ops.analyze(1, dt / sub) == 0
        out[i] = [ops.nodeDisp(j + 1, 1) for j in range(L)]
    ops.wipe()
    return out


def test_linear_building_is_the_openseespy_building(ops):
    ag, _ = table_motion(8.0, 50.0, seed=3)
    ag = 2.0 * ag
    d_ops = _openseespy_linear(ops, LINEAR, ag, 0.02)
    d, a, f, _ = simulate_building(LINEAR, ag, 0.02)
    peak = np.max(np.abs(d_ops), axis=0)
    assert np.max(np.abs(d - d_ops) / peak) < 5e-4
    # the drifts (the superstructure) too, not only the isolator mode
    dr, dr_ops = np.diff(d, axis=1), np.diff(d_ops, axis=1)
    assert np.max(np.abs(dr - dr_ops)) < 5e-4 * np.max(np.abs(dr_ops))


@pytest.mark.parametrize("effect, strength", [("none", 0.0), ("viscous_power", 0.5),
                                              ("stiffening", 3.0)])
def test_energy_input_equals_energy_stored_and_dissipated(effect, strength):
    b = with_effect(SyntheticBuilding(), effect, strength)
    ag, _ = table_motion(6.0, 500.0, seed=1)
    e = energy_balance(b, 2.0 * ag, 0.002, substeps=2)
    assert e["input"] > 1.0 and abs(e["error"]) < 1e-4


def test_isolation_force_is_minus_the_sum_of_mass_times_absolute_acceleration():
    b = with_effect(SyntheticBuilding(), "degradation", 1.0)
    ag, _ = table_motion(5.0, 50.0, seed=2)
    d, a, f, _ = simulate_building(b, 2.0 * ag, 0.02)
    np.testing.assert_allclose(-(a @ np.asarray(b.masses)), f, rtol=0, atol=1e-9 * np.max(np.abs(f)))


def test_a_sequence_is_shake_table_runs_with_state_carried_and_noise_on_every_channel():
    b = with_effect(SyntheticBuilding(), "degradation", 1.0)
    runs = synthetic_sequence(b, (0.5, 1.5), seed=4, noise=0.03, disp_noise=2e-4, duration=6.0, tail_s=0.0)
    clean = synthetic_sequence(b, (0.5, 1.5), seed=4, noise=0.0, disp_noise=0.0, duration=6.0, tail_s=0.0)
    assert [r.name for r in runs] == ["SYN1", "SYN2"]
    for r, c in zip(runs, clean):
        assert isinstance(r, ShakeTableRun) and r.rate_hz == pytest.approx(50.0)
        isolation_test(r)  # the pipeline's isolation loop reads it
        # accelerometers: 3 % of each channel's RMS; displacement transducers: 0.2 mm on every level
        for x, y in ((r.table_accel, c.table_accel), (r.accel, c.accel)):
            e = (x - y).reshape(len(x), -1)
            rms = np.sqrt(np.mean(y.reshape(len(y), -1) ** 2, axis=0))
            np.testing.assert_allclose(np.std(e, axis=0), 0.03 * rms, rtol=0.15)
        np.testing.assert_allclose(np.std(r.disp - c.disp, axis=0), 2e-4, rtol=0.15)
    # the second run starts where the first left the building (degraded): its loop is weaker
    # than the same motion on a virgin building
    fresh = synthetic_sequence(b, (1.5,), seed=4, noise=0.0, disp_noise=0.0, duration=6.0, tail_s=0.0)[0]
    f2 = -(clean[1].accel @ clean[1].masses)
    f0 = -(fresh.accel @ fresh.masses)
    assert np.max(np.abs(f2)) < np.max(np.abs(f0))
    assert clean[1].meta["truth"]["effect"] == "degradation"


def test_a_recovering_softening_softens_after_a_large_excursion_and_recovers_between_runs():
    """Within a run the damage follows the largest excursion quickly and holds after it (it
    recovers over minutes); the unrecorded hour between runs restores the layer: the same motion
    run again gives the same loop, unlike the same runs without that rest."""
    b = with_effect(SyntheticBuilding(), "recovering_softening", 0.4)
    ag, _ = table_motion(20.0, 50.0, seed=3)
    d, _, _, state = simulate_building(b, 1.5 * ag, 0.02)
    reached = np.tanh(np.max(np.abs(d[:, 0])) / b.effect_params()["x_r"])
    assert 0.5 * reached < state[-1] <= reached  # held after the excursion (tau_rec = 300 s)
    kw = dict(seed=3, noise=0.0, disp_noise=0.0, duration=20.0, tail_s=0.0)
    again = synthetic_sequence(b, (1.5, 1.5), **kw)
    carried = synthetic_sequence(with_effect(b, "recovering_softening", 0.4, gap_s=0.0), (1.5, 1.5), **kw)

    def repeat_gap(runs):  # how far the second run's isolator displacement is from the first's
        u0, u1 = runs[0].isolator_disp, runs[1].isolator_disp
        return float(np.sqrt(np.mean((u1 - u0) ** 2) / np.mean(u0**2)))

    assert repeat_gap(again) < 0.01
    assert repeat_gap(carried) > 0.05


def test_a_displacement_transducer_is_as_noisy_on_a_small_run_as_on_a_large_one():
    """A transducer's noise is set by its range and its channel, not by the motion: the roof's
    displacement noise is the same on a run at a third of the table motion (the earlier model,
    2 % of each level's RMS, made it smaller there in proportion to the motion)."""
    b = SyntheticBuilding()
    kw = dict(seed=5, duration=6.0, tail_s=0.0, rest_s=0.0)
    noisy = synthetic_sequence(b, (0.5, 1.5), noise=0.02, **kw)
    clean = synthetic_sequence(b, (0.5, 1.5), noise=0.0, disp_noise=0.0, **kw)
    sd = [np.std(n.disp - c.disp, axis=0) for n, c in zip(noisy, clean)]
    np.testing.assert_allclose(sd[0], DISP_NOISE_M, rtol=0.15)
    np.testing.assert_allclose(sd[0], sd[1], rtol=0.2)
    assert np.std(clean[1].disp[:, -1]) > 2.0 * np.std(clean[0].disp[:, -1])


def test_a_run_records_the_free_vibration_after_the_table_stops():
    b = SyntheticBuilding()
    run = synthetic_sequence(b, (1.0,), seed=6, noise=0.0, disp_noise=0.0, duration=4.0, tail_s=3.0)[0]
    assert run.time[-1] == pytest.approx(7.0)
    tail = run.time > 4.0
    assert np.all(run.table_accel[tail] == 0.0)
    # the building still moves after the table stops, and its motion dies out
    roof = run.accel[:, -1]
    assert np.max(np.abs(roof[tail])) > 0.0
    assert np.max(np.abs(roof[run.time > 6.0])) < np.max(np.abs(roof[run.time <= 4.0]))


def test_bad_inputs_name_the_field():
    with pytest.raises(ValueError, match="effect = 'creep'"):
        SyntheticBuilding(effect="creep")
    with pytest.raises(ValueError, match="peaks"):
        synthetic_sequence(SyntheticBuilding(), (1.0, -2.0))
    with pytest.raises(ValueError, match="disp_noise = -0.001"):
        synthetic_sequence(SyntheticBuilding(), (1.0,), disp_noise=-1e-3)
    with pytest.raises(ValueError, match="tail_s = -1"):
        synthetic_sequence(SyntheticBuilding(), (1.0,), tail_s=-1.0)
