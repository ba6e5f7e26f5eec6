"""Differential tests: every OpenSees law equals openseespy 3.7.1 under displacement control.

The peer is the element itself driven by ``tests/opensees_harness.py`` (reference section 6).
Required: max|F - F_os| / max|F_os| <= 1e-9 on the calibration protocol and on
hypothesis-generated histories; and where a law's local Newton fails, OpenSees' element reports
its failure (``update()`` warning) at the same sample.
"""

import numpy as np
import pytest
from _law_strategies import LAW_PARAMS, histories
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from opensees_harness import check_against_opensees, element_force, element_force_recorder

import rrfrei
from rrfrei.protocols import protocol1

pytestmark = pytest.mark.opensees

PROTOCOL_PARAMS = {
    "plasticity": [
        dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0),
        dict(k_init=3e4, qd=40.0, alpha1=0.02, alpha2=0.2, mu=2.7),
    ],
    "bouc_wen": [
        dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5),
        dict(k_init=2e3, qd=5.0, alpha1=0.05, alpha2=0.05, mu=1.5, eta=1.37, beta=0.8, gamma=-0.3),
        dict(k_init=50.0, qd=0.3, alpha1=0.3, alpha2=-0.02, mu=3.0, eta=4.2, beta=2.0, gamma=0.9),
    ],
    "elastomeric_x": [
        dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0),
        dict(fy=20.0, alpha=0.08, gr=900.0, d1=0.1, d2=0.6, tr=0.01, n=20.0, tc=0.01, cd=5.0),
    ],
    "hdr": [
        dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4, c4=5e3),
        dict(a1=800.0, a2=1e5, a3=0.0, b1=30.0, b2=-2e3, b3=40.0, c1=0.0, c2=1e5, c3=0.9, c4=0.0),
    ],
}


@pytest.mark.parametrize(
    "law, p", [(law, p) for law, ps in PROTOCOL_PARAMS.items() for p in ps],
    ids=lambda x: x if isinstance(x, str) else None,
)
def test_protocol1_force_equals_opensees(ops, law, p):
    _, u = protocol1()
    check_against_opensees(ops, law, p, u)


@pytest.mark.parametrize("law", list(LAW_PARAMS))
def test_recorder_fast_path_equals_step_by_step_harness(ops, law):
    """The benchmark's one-analyze() recorder path returns the same forces (17 digits)."""
    _, u = protocol1(rate=5.0)
    p = PROTOCOL_PARAMS[law][0]
    f_step, _, _ = element_force(ops, law, p, u)
    np.testing.assert_allclose(element_force_recorder(ops, law, p, u), f_step, rtol=1e-15, atol=0)


def _law_and_params():
    return st.sampled_from(list(LAW_PARAMS)).flatmap(lambda law: st.tuples(st.just(law), LAW_PARAMS[law]()))


@given(lp=_law_and_params(), disp=histories())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_random_histories_equal_opensees(ops, lp, disp):
    law, p = lp
    check_against_opensees(ops, law, p, disp)


@pytest.mark.slow
@pytest.mark.parametrize("law", list(LAW_PARAMS))
@given(data=st.data())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
def test_random_histories_equal_opensees_sweep(ops, law, data):
    p = data.draw(LAW_PARAMS[law]())
    disp = data.draw(histories(max_size=300))
    check_against_opensees(ops, law, p, disp)


def test_bouc_wen_local_newton_failure_matches_opensees_and_names_sample_and_state(ops):
    """A step far beyond u_y with a steep exponent defeats the 25-iteration Newton in both."""
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0, eta=9.181247277429936,
             beta=0.1979643833210143, gamma=0.28589263260021625)
    disp = np.array([0.001, 0.002, -0.169674])
    with pytest.raises(ValueError, match=r"failed at sample 2 .*did not converge; committed state "
                                         r"\[.*\], failed trial state \["):
        rrfrei.simulate_force("bouc_wen", p, disp)
    _, _, fail_os = element_force(ops, "bouc_wen", p, disp)
    assert fail_os == 2
