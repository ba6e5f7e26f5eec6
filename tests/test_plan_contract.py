"""The plan-law contract: an (n, 2) path goes to the law's coupled bidirectional form."""

import numpy as np
import pytest

from rrfrei import simulate_force
from rrfrei.laws import plan


def test_linear_plan_law_is_two_independent_springs_and_its_dashpot():
    t = np.linspace(0.0, 2.0, 81)
    d = np.c_[0.02 * np.sin(3 * t), 0.01 * np.cos(2 * t)]
    f, k = simulate_force("linear", {"k": 50.0, "c": 3.0}, d, time=t, return_tangent=True)
    for a in (0, 1):
        np.testing.assert_array_equal(f[:, a], simulate_force("linear", {"k": 50.0, "c": 3.0},
                                                              d[:, a], time=t))
    np.testing.assert_allclose(k[-1], (50.0 + 3.0 / (t[1] - t[0])) * np.eye(2), rtol=1e-12)


def test_plan_laws_share_the_parameters_of_their_unidirectional_law():
    for name in plan.names():
        assert plan.get(name).law.name == name


@pytest.mark.parametrize(
    ("disp", "words"),
    [
        (np.zeros((4, 3)), "(n, 2)"),
        (np.zeros((0, 2)), "(n, 2)"),
        (np.array([[0.0, 0.0], [np.nan, 0.0]]), "sample 1, component x"),
    ],
)
def test_bad_plan_paths_name_the_problem(disp, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        simulate_force("linear", {"k": 1.0}, disp)


def test_a_law_without_a_plan_form_says_which_laws_have_one():
    with pytest.raises(ValueError, match="no coupled bidirectional form.*linear"):
        simulate_force("linear+rate", {"k": 1.0}, np.zeros((3, 2)))
