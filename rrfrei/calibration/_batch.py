"""Template of the batched likelihood kernels (see :mod:`rrfrei.calibration.likelihood`).

Slot ``law_drive``: the law's whole-history driver (``drive(p, sc, st, disp, time, use_time,
substeps, force, tangent) -> (status, index)``, :func:`rrfrei.laws.specialise.history`), bound
per law by :func:`rrfrei.calibration.likelihood.batch_kernels`.  Each walker starts from its own
copies of the initial state ``state0`` (committed and trial).
"""

import math

import numpy as np
from numba import njit, prange

from rrfrei.laws.specialise import unbound

SLOTS = ("law_drive",)
law_drive = unbound("law_drive")
_LOG2PI = math.log(2.0 * math.pi)


@njit(parallel=True, cache=True)
def forces_batch(P, state0, disp, time, use_time, F, T, status):
    """Model force of every row of ``P`` along ``disp`` into ``F`` (rows), statuses into ``status``."""
    nw = P.shape[0]
    for w in prange(nw):
        # np.int64(1), not the literal 1: a literal argument compiles the law's loop a second time
        s, _ = law_drive(P[w], state0.copy(), state0.copy(), disp, time, use_time, np.int64(1), F[w], T[w])
        status[w] = s


@njit(parallel=True, cache=True)
def loglik_batch(P, state0, disp, time, use_time, obs, idx, sigma, rho, ar1, F, T, out):
    """Joint log-likelihood of every row of ``P`` (with its sigma, rho) into ``out``.

    The law runs along the whole ``disp``; the residuals are taken at the samples ``idx`` only
    (``obs`` holds the measured forces at those samples).
    """
    nw = P.shape[0]
    n = idx.shape[0]
    for w in prange(nw):
        s = sigma[w]
        if not s > 0.0:
            out[w] = -np.inf
            continue
        st, _ = law_drive(P[w], state0.copy(), state0.copy(), disp, time, use_time, np.int64(1), F[w], T[w])
        if st != 0:
            out[w] = -np.inf
            continue
        inv = 1.0 / (s * s)
        acc = 0.0
        if ar1:
            r = rho[w]
            if not abs(r) < 1.0:
                out[w] = -np.inf
                continue
            e0 = obs[0] - F[w, idx[0]]
            var0 = s * s / (1.0 - r * r)
            acc = -0.5 * e0 * e0 / var0 - 0.5 * math.log(var0) - 0.5 * _LOG2PI
            prev = e0
            for i in range(1, n):
                e = obs[i] - F[w, idx[i]]
                innov = e - r * prev
                acc += -0.5 * innov * innov * inv
                prev = e
            acc += (n - 1) * (-math.log(s) - 0.5 * _LOG2PI)
        else:
            for i in range(n):
                e = obs[i] - F[w, idx[i]]
                acc += -0.5 * e * e * inv
            acc += n * (-math.log(s) - 0.5 * _LOG2PI)
        out[w] = acc if np.isfinite(acc) else -np.inf
