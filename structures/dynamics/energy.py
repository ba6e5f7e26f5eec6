"""Energy balance of a shear-building time history (relative formulation).

With displacements relative to the ground, the work of the effective earthquake load equals the
energy stored and dissipated in the building (Uang & Bertero 1990, "relative" input energy):

    E_I = E_K + E_D + E_H + E_S

* ``input``     E_I = -int a_g 1^T M du_rel;
* ``kinetic``   E_K = (1/2) v_rel^T M v_rel;
* ``viscous``   E_D = int v^T C du (story dashpots and, with Rayleigh damping, floor dashpots);
* ``isolator``  E_H = int F_iso du_0, the work done on the isolator layer: its hysteretic (and,
  for laws with a dashpot, viscous) dissipation plus its recoverable elastic energy, which is
  small once the motion has died out;
* ``strain``    E_S = (1/2) sum k_i drift_i^2, the recoverable strain energy of the stories.

The integrals are accumulated with the trapezoidal rule over each step's increment, which is the
exact work of the Newmark average-acceleration scheme (g = 1/2, b = 1/4): for it the imbalance is
only the Newton residual, so ``energy_error`` checks the implementation (forces, velocities and
the isolator coupling) rather than the time step.  Other (g, b) show their numerical damping as
an imbalance.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

TERMS = ("input", "kinetic", "viscous", "isolator", "strain")
"""Names of the energy histories [kN m], in the row order of the kernel's energy array."""


def as_dict(E: np.ndarray) -> dict[str, np.ndarray]:
    """Energy histories by name from the kernel's (5, n_steps) array (one row per term)."""
    return {name: E[i] for i, name in enumerate(TERMS)}


def imbalance(energy: Mapping[str, np.ndarray]) -> np.ndarray:
    """E_I - (E_K + E_D + E_H + E_S) over time [kN m]."""
    return energy["input"] - (energy["kinetic"] + energy["viscous"] + energy["isolator"] + energy["strain"])


def balance_error(energy: Mapping[str, np.ndarray]) -> float:
    """max_t |imbalance(t)| / max_t |E_I(t)| (0 when no energy was put in)."""
    top = float(np.max(np.abs(energy["input"]))) if len(energy["input"]) else 0.0
    if top == 0.0:
        return 0.0
    return float(np.max(np.abs(imbalance(energy))) / top)
