"""ElastomericBearingBoucWen (OpenSees v3.7.1, ``ElastomericBearingBoucWen2d.cpp``).

Smooth Bouc-Wen hysteresis (Wen's form, A = 1) plus linear and nonlinear hardening::

    k0 = (1 - alpha1) k_init,  k2 = alpha1 k_init,  k3 = alpha2 k_init,  u_y = qd / k0
    dz/du = (1/u_y) [A - |z|^eta (gamma + beta sgn(z du))]
    F     = qd z + k2 u + k3 sgn(u) |u|^mu

Integration (update, l.455-504), one backward-Euler step over the whole increment
du = u - u_C, solved for z by scalar Newton from the current *trial* z (not z_C)::

    f(z)  = z - z_C - (du/u_y) [A - |z|^eta (gamma + beta sgn(z du))]
    f'(z) = 1 + (du/u_y) eta |z|^(eta-1) sgn(z) (gamma + beta sgn(z du))

with |z| replaced by DBL_EPSILON when z == 0, iterating while |f/f'| >= 1e-12 and
iter < 25.  Status -2 if the loop ends with iter >= 25 (so a solve that converges exactly on the
25th iteration also fails, as in OpenSees), -1 if |f'| <= DBL_EPSILON.  The tangent is the
continuous-model one, k_t = k0 [A - |z|^eta (gamma + beta sgn(z du))] + k2 + k3 mu |u|^(mu-1).
When du == 0 exactly nothing is recomputed: force and tangent are those of the previous call.

The result depends on the step size (implicit integration over each increment); see
``rrfrei.simulate_force(substeps=...)``.

Identifiability: the force is exactly invariant under (qd, beta, gamma) -> (c qd, c^eta beta,
c^eta gamma) for any c > 0 (z scales by 1/c, u_y by c, and the backward-Euler step with them), so
one cyclic test can never fix all three.  Calibration therefore holds ``beta`` at 0.5 (``hold``
in its ParamSpec) and samples gamma, which spans the loop shapes gamma/beta in (-1, 2]; give a
prior for ``beta`` to sample it anyway (and expect a ridge).

State (float64[5])::

    [0] u      trial (committed, in sc) shear displacement [m]
    [1] z      hysteretic variable [-]
    [2] q      shear force of the last update() call [kN]
    [3] dk     tangent of the last call minus the initial tangent k_init [kN/m]
               (stored as an offset so the virgin state, all zeros, is parameter-free)
    [4] |z|^(eta-1) at z = [1] (a cache; 0 = not cached)

Speed (same iterates as OpenSees, fewer ``pow`` calls): integer ``eta`` (1, 2, 3) is
specialised; otherwise |z|^(eta-1) is carried from call to call in the state and, once Newton
has nearly converged (relative change of |z| below 1e-6), updated by a second-order Taylor step
instead of a ``pow`` call; |z|^eta = |z| |z|^(eta-1).  The iterates agree with a plain port to
about 1e-16.

Whole histories (:func:`rrfrei.laws.specialise.history`): the one history loop
(:mod:`rrfrei.laws._history`) with this law's step as its local solver and, in its fast-run
slot, the fast solver of :mod:`rrfrei.laws._bouc_wen_fast` (non-integer eta: Halley's method on
a Taylor polynomial of the power, used where a Kantorovich guard certifies that OpenSees'
Newton iteration converges to the same root; forces agree with :data:`drive_exact`, OpenSees'
iteration at every step, to ~1e-15, with the same status and failure sample).

Robust local solve (opt-in, ``local_solver="robust"``; a deviation from OpenSees):
:func:`step_robust` runs :func:`step` unchanged and, only where it fails or stops away from a
root, solves the same equation on a bracket (:mod:`rrfrei.laws._bouc_wen_robust`, which
proves the bracket), returning status :data:`STATUS_ROBUST`.
"""

from dataclasses import replace

import numpy as np
from numba import njit

from rrfrei.laws._bouc_wen_fast import fast_run, fast_setup
from rrfrei.laws._bouc_wen_robust import (  # noqa: F401
    STATUS_ROBUST,
    near_root,
    solve_bracketed,
    solve_robust,
)
from rrfrei.laws._util import DBL_EPSILON, bearing_constants, powabs, sgn
from rrfrei.laws.plasticity import PARAMS as _PLASTICITY_PARAMS
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, elastomeric_bearing, register

A = 1.0
MAX_ITER = 25
TOL = 1e-12


TAYLOR_MAX = 1e-6
"""Largest relative change of |z| for which |z|^(eta-1) is updated by a 2nd-order Taylor step
instead of ``pow`` (relative error <= C(eta-1, 3) 1e-18, below 1e-15 for eta <= 10)."""


@njit(cache=True, inline="always")
def _pm1(za, eta):
    """|z|^(eta-1) for |z| = za > 0, with eta = 1, 2, 3 specialised."""
    if eta == 1.0:
        return 1.0
    if eta == 2.0:
        return za
    if eta == 3.0:
        return za * za
    return za ** (eta - 1.0)


@njit(cache=True, inline="always")
def _constants(p):
    """(k_init, qd, k0, k2, k3, mu, eta, beta, gamma) of a parameter row (module docstring)."""
    k_init, qd, k0, k2, k3, mu = bearing_constants(p)
    return k_init, qd, k0, k2, k3, mu, p[5], p[6], p[7]


@njit(cache=True, inline="always")
def _force_tangent(p, u, du, z, pe, st):
    """Force q = qd z + k2 u + k3 sgn(u) |u|^mu [kN] and tangent k_t = k0 dz/du + k2 +
    k3 mu |u|^(mu-1) [kN/m] at the solved z (``pe`` = |z|^eta), dz/du = A - |z|^eta (gamma +
    beta sgn(z du)); stored as ``st[2] = q``, ``st[3] = k_t - k_init`` (module docstring)."""
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    dzdu = A - pe * (gamma + beta * sgn(z * du))
    q = qd * z + k2 * u
    kt = k0 * dzdu + k2
    if k3 != 0.0:
        q += k3 * sgn(u) * powabs(u, mu)
        kt += k3 * mu * powabs(u, mu - 1.0)
    st[2] = q
    st[3] = kt - k_init
    return q, kt


@njit(cache=True, error_model="numpy")
def step(p, sc, u, v, dt, st):
    """Bouc-Wen bearing shear force [kN], tangent [kN/m] and status (see the module docstring)."""
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    du = u - sc[0]
    st[0] = u
    if du == 0.0:  # OpenSees keeps q and k_t of the previous update() call
        return st[2], st[3] + k_init, 0
    uy = qd / k0
    r = du / uy
    zc = sc[1]
    z = st[1]
    special = eta == 1.0 or eta == 2.0 or eta == 3.0
    e1 = eta - 1.0
    e2 = 0.5 * (eta - 2.0)
    za = abs(z)
    if za == 0.0:
        za = DBL_EPSILON
    pm1 = st[4]  # |z|^(eta-1) cached by the previous call for this same z (0: not cached)
    if special or not pm1 > 0.0:
        pm1 = _pm1(za, eta)
    it = 0
    while True:
        tmp1 = gamma + beta * sgn(z * du)
        f = z - zc - r * (A - pm1 * za * tmp1)
        df = 1.0 + r * eta * pm1 * sgn(z) * tmp1
        if abs(df) <= DBL_EPSILON:
            st[1] = z
            st[4] = 0.0
            return st[2], st[3] + k_init, -1
        dz = f / df
        z -= dz
        it += 1
        za_new = abs(z)
        if za_new == 0.0:
            za_new = DBL_EPSILON
        if special:
            pm1 = _pm1(za_new, eta)
        else:
            rel = (za_new - za) / za
            if abs(rel) < TAYLOR_MAX:
                pm1 = pm1 * (1.0 + e1 * rel * (1.0 + e2 * rel))
            else:
                pm1 = za_new ** e1
        za = za_new
        if not (abs(dz) >= TOL and it < MAX_ITER):
            break
    st[1] = z
    st[4] = pm1
    if it >= MAX_ITER:
        return st[2], st[3] + k_init, -2
    q, kt = _force_tangent(p, u, du, z, pm1 * abs(z), st)  # |z|^eta (0 at z == 0)
    return q, kt, 0


def _check(p: np.ndarray) -> None:
    if p[2] >= 1.0:
        raise ValueError(f"law 'bouc_wen': alpha1 = {p[2]:g} must be < 1")
    if p[6] + p[7] <= 0.0:
        raise ValueError(
            f"law 'bouc_wen': beta + gamma = {p[6] + p[7]:g} must be > 0 (bounded hysteretic "
            "variable z)"
        )


def __getattr__(attr: str):
    """``drive_exact``: OpenSees' own iteration (:func:`step`) at every sub-step of a history,
    the reference the fast solver is tested against: the history loop
    (:mod:`rrfrei.laws._history`) with :func:`step` as its local solver and no fast-run slot
    (contract of :func:`rrfrei.laws._history.drive`)."""
    if attr == "drive_exact":
        from rrfrei.laws import specialise

        return specialise.history(SPEC, fast=False)
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


@njit(cache=True, error_model="numpy")
def step_robust(p, sc, u, v, dt, st):
    """:func:`step`, and where OpenSees' iteration fails (status -1 or -2) or stops away from a
    root (:func:`near_root`), the root of the same equation by :func:`solve_robust` from
    the committed z (status :data:`STATUS_ROBUST`): bracketed, and from a committed state beyond
    the bound where no root exists, from that state projected onto the bound.

    Force and tangent as in :func:`step` (same expressions) at the bracketed root; the |z|^(eta-1)
    cache is cleared.  Status -1 / -2 only for a non-finite state or step.
    """
    q, kt, status = step(p, sc, u, v, dt, st)
    k_init, qd, k0, k2, k3, mu, eta, beta, gamma = _constants(p)
    du = u - sc[0]
    uy = qd / k0
    if status == 0:
        if du == 0.0 or near_root(sc[1], du / uy, st[1], eta, beta, gamma):
            return q, kt, 0
    elif status != -1 and status != -2:
        return q, kt, status
    z, st2 = solve_robust(sc[1], du / uy, eta, beta, gamma)
    if st2 != 0:
        return q, kt, status
    st[1] = z
    st[4] = 0.0
    q, kt = _force_tangent(p, u, du, z, abs(z) ** eta, st)
    return q, kt, STATUS_ROBUST


SPEC = register(
    LawSpec(
        name="bouc_wen",
        step=step,
        step_robust=step_robust,
        fast_run=fast_run,
        fast_setup=fast_setup,
        params=(_PLASTICITY_PARAMS[0], replace(_PLASTICITY_PARAMS[1], lower=1e-9))
        + _PLASTICITY_PARAMS[2:]
        + (
            ParamSpec("eta", "-", 0.1, 10.0, "Bouc-Wen exponent", Prior("uniform", 0.5, 5.0)),
            ParamSpec("beta", "-", 0.0, 5.0, "coefficient of the sign-dependent term",
                      Prior("uniform", 0.0, 2.0), hold=0.5),
            ParamSpec("gamma", "-", -5.0, 5.0, "coefficient of the constant term",
                      Prior("uniform", -1.0, 1.0)),
        ),
        state_size=5,
        description="OpenSees ElastomericBearingBoucWen: smooth Bouc-Wen hysteresis (A = 1).",
        opensees=elastomeric_bearing("elastomericBearingBoucWen"),
        check=_check,
    )
)
