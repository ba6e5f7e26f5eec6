"""Numba kernels of the PRF gap effects: permanent set and Mullins damage of the equilibrium network.

Pure functions over arrays and scalars (no Python objects; a status code, never an exception, from
the integrator).  The equations are in :mod:`rubber.gap` (Ogden & Roxburgh 1999; Dorfmann & Ogden
2004).  Units: MPa, s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rubber import integrate as _k

__all__ = ["augmented_nominal", "equilibrium_delta", "mullins_factor", "set_reference"]


@njit(cache=True)
def set_reference(lam, s, out):
    """lambda_p[j] = 1 + s (max(1, max_{i<=j} lambda_i) - 1): reference stretch after permanent set."""
    lmax = 1.0
    for j in range(lam.shape[0]):
        if lam[j] > lmax:
            lmax = lam[j]
        out[j] = 1.0 + s * (lmax - 1.0)


@njit(cache=True)
def mullins_factor(w, d, beta, out):
    """Ogden-Roxburgh eta[j] = 1 - d erf((W_max - W_j) / (beta W_max)), W_max the running maximum."""
    wmax = 0.0
    for j in range(w.shape[0]):
        if w[j] > wmax:
            wmax = w[j]
        if d == 0.0 or wmax <= 0.0:
            out[j] = 1.0
        else:
            out[j] = 1.0 - d * math.erf((wmax - w[j]) / (beta * wmax))


@njit(cache=True)
def equilibrium_delta(lam, eq, s, d, beta, out):
    """Delta_A (MPa) of the equilibrium Yeoh network with permanent set ``s`` and Mullins ``d, beta``."""
    m = lam.shape[0]
    lp = np.empty(m)
    set_reference(lam, s, lp)
    w = np.empty(m)
    for j in range(m):
        le = lam[j] / lp[j]
        out[j] = _k.yeoh_delta(le, eq[0], eq[1], eq[2])
        w[j] = _k.yeoh_energy(le, eq[0], eq[1], eq[2])
    eta = np.empty(m)
    mullins_factor(w, d, beta, eta)
    for j in range(m):
        out[j] = out[j] * eta[j]


@njit(cache=True)
def augmented_nominal(time, lam, eq, chains, rtol, s, d, beta, out):
    """Nominal stress of the augmented PRF model into ``out``; returns the integrator status.

    Same summation order as :func:`rubber.integrate.nominal_stress`, so neutral effect values
    (s = d = 0) give the base model bit for bit.
    """
    m = time.shape[0]
    k = chains.shape[0]
    u = np.empty((k, m))
    dch = np.empty((k + 1, m))
    diss = np.empty((k, m))
    st, na, nr = _k.simulate_kernel(time, lam, eq, chains, rtol, u, dch, diss)
    da = np.empty(m)
    equilibrium_delta(lam, eq, s, d, beta, da)
    for j in range(m):
        acc = da[j]
        for r in range(1, k + 1):
            acc += dch[r, j]
        out[j] = acc / lam[j]
    return st
