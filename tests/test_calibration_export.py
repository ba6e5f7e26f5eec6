"""The exported OpenSees command builds an element that openseespy accepts and that reproduces
the law (peer check, issue 16.2): for every law, the printed ``ops.element(...)`` is executed in
openseespy, the element is driven over protocol 1 by displacement control, and its force must
equal :func:`rrfrei.simulate_force` at rtol 1e-9 (numbers are printed at full precision)."""

from __future__ import annotations

import numpy as np
import pytest
from opensees_harness import command_force

from rrfrei.calibration.results import opensees_command
from rrfrei.laws import OPENSEES_LAWS, get
from rrfrei.protocols import protocol1
from rrfrei.simulate import simulate_force

# ordinary specimen-scale values with every term active (alpha2 != 0, eta non-integer, hdr damage)
PARAMS = {
    "plasticity": dict(k_init=260.123456789, qd=1.4, alpha1=0.33, alpha2=0.05, mu=2.5),
    "bouc_wen": dict(k_init=260.123456789, qd=1.4, alpha1=0.33, alpha2=0.05, mu=2.5, eta=1.37,
                     beta=0.6, gamma=0.4),
    "elastomeric_x": dict(fy=1.4, alpha=0.33, gr=513.0, d1=0.01, d2=0.08, tr=0.002, n=15.0, tc=0.0,
                          cd=0.0),
    "hdr": dict(a1=150.0, a2=1.6e4, a3=2.3e6, b1=1.2, b2=550.0, b3=200.0, c1=30.0, c2=30.0, c3=0.8,
                c4=0.5),
}


@pytest.mark.opensees
@pytest.mark.parametrize("law", OPENSEES_LAWS)
def test_exported_command_runs_in_openseespy_and_reproduces_the_law(ops, law):
    _, u = protocol1()
    u = u[::4]
    params = PARAMS[law]
    command = opensees_command(get(law), params)
    assert "e+" in command or "." in command  # floats, at full precision (repr)
    theirs = command_force(ops, law, command, u)
    ours = simulate_force(law, params, u)
    np.testing.assert_allclose(theirs, ours, rtol=1e-9, atol=1e-9 * np.max(np.abs(ours)))


def test_exported_numbers_are_printed_at_full_precision():
    p = {"k_init": 1234.5678901234567, "qd": 2.000000000000001, "alpha1": 0.1, "alpha2": 0.0, "mu": 2.0}
    cmd = opensees_command(get("plasticity"), p)
    assert repr(1234.5678901234567) in cmd and repr(2.000000000000001) in cmd
