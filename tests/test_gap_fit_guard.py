"""The multi-start least-squares guard of the gap engine's fits (rrfrei.gap.model): a start that
only creeps is stopped, a start cut after its screen continues only while it can still win."""

import numpy as np
from scipy.optimize import least_squares

from rrfrei.gap.fitting import STALL_ITERATIONS, STALL_REL, _Guard, _worth_continuing


class _Step:
    def __init__(self, cost):
        self.fun = np.array([np.sqrt(2.0 * cost)])


def _feed(guard, costs):
    """Iterations fed to the guard until it stops the search (their number) or all ran (None)."""
    for i, c in enumerate(costs, 1):
        try:
            guard(_Step(c))
        except StopIteration:
            return i
    return None


def test_a_creeping_start_is_stopped_once_its_window_gains_less_than_the_threshold():
    # cost falls by a fraction r per iteration: over the window it gains about W r
    slow = 1.0 * (1.0 - 0.2 * STALL_REL / STALL_ITERATIONS) ** np.arange(200)
    fast = 1.0 * (1.0 - 5.0 * STALL_REL / STALL_ITERATIONS) ** np.arange(200)
    assert _feed(_Guard(None), slow) == STALL_ITERATIONS + 1
    assert _feed(_Guard(None), fast) is None


def test_the_screen_cuts_after_its_iterations_and_says_so():
    g = _Guard(5)
    assert _feed(g, 1.0 - 0.1 * np.arange(10) / 10) == 5 and g.cut
    g = _Guard(None)
    assert _feed(g, 1.0 - 0.1 * np.arange(10) / 10) is None and not g.cut


def test_a_cut_start_continues_when_it_leads_or_descends_fast_enough_to_lead():
    flat = list(np.linspace(1.0, 0.99, 30))
    assert _worth_continuing(flat, lead=0.99)            # it is the leader
    assert _worth_continuing(flat, lead=0.95)            # within 5 %
    assert not _worth_continuing(flat, lead=0.5)         # creeps at twice the leader's cost
    steep = list(np.linspace(2.0, 1.0, 30))              # 0.34 per 10 iterations
    assert _worth_continuing(steep, lead=0.5)


def test_the_guard_stops_a_real_creeping_least_squares_and_keeps_its_point():
    # Rosenbrock's valley from a far start: trust-region steps creep along the banana
    def r(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0], 1e-3 * x[0]])

    x0 = np.array([-1.9, 2.0])
    free = least_squares(r, x0, method="trf", diff_step=1e-6, max_nfev=5000)
    g = _Guard(3)
    cut = least_squares(r, x0, method="trf", diff_step=1e-6, max_nfev=5000, callback=g)
    assert g.cut and cut.status == -2 and cut.nfev < free.nfev
    assert np.isclose(cut.cost, 0.5 * float(cut.fun @ cut.fun))
    assert cut.jac.shape == (3, 2) and cut.cost >= free.cost
