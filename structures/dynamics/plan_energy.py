"""Energy balance of a plan-building time history (both horizontal directions).

The equations of motion of each direction d = x, y (relative to the ground),

    M a_d + C_d v_d + K_d u_d + F_d(u_b, v_b) e_0 = -M 1 a_g,d,

dotted with du_d and integrated give one balance per direction (:mod:`structures.dynamics.energy`):

    E_I,d = E_K,d + E_D,d + E_H,d + E_S,d,

where E_H,d = int F_d du_0,d is the work of the isolator force's d component.  The isolator
couples the directions, but it does so through F alone, so each balance closes on its own; their
sum is the balance of the plan building,

    E_I = E_K + E_D + E_H + E_S,    E_H = int F . du_b  (the line integral in plan),

with E_H the work done on the isolator layer along its orbit: its hysteretic dissipation (for a
circular yield surface qd times the plastic path length, not the sum of the two axes' own
loops) plus its recoverable elastic energy.  Trapezoidal increments make every term the exact
work of the average-acceleration Newmark scheme (g = 1/2, b = 1/4), so the imbalance is the
Newton residual only (:mod:`structures.dynamics.plan_newmark`).  Units: kN m.
"""

from __future__ import annotations

import numpy as np

from structures.dynamics.energy import TERMS, as_dict, balance_error

__all__ = ["TERMS", "balance_error", "by_direction", "total"]


def by_direction(E: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The x and y energy histories by name [kN m] from the kernel's (2, 5, n) array."""
    if E.ndim != 3 or E.shape[0] != 2 or E.shape[1] != len(TERMS):
        raise ValueError(
            f"E must be a (2, {len(TERMS)}, n) array (direction, term, step), got shape {E.shape}"
        )
    return as_dict(E[0]), as_dict(E[1])


def total(E: np.ndarray) -> dict[str, np.ndarray]:
    """The plan building's energy histories by name [kN m]: the sum of the two directions'."""
    x, y = by_direction(E)
    return {name: x[name] + y[name] for name in TERMS}
