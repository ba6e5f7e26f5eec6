"""Newmark time stepping with Newton-Raphson on the isolator tangent (Numba kernels).

The chain ``[base, floor 1, ..., floor n]`` (displacements relative to the ground) obeys

    M a + C v + K_s u + F_iso(u_0, v_0) e_0 = -M 1 a_g(t)

with story springs/dashpots between neighbouring DOFs and the isolator layer between the ground
and the base (DOF 0).  Each step follows OpenSees' ``Newmark`` (displacement form,
``SRC/analysis/integrator/Newmark.cpp`` l.157-255) with ``Newton`` and ``NormDispIncr``:

1. predictor u = u_n, v = (1 - g/b) v_n + h (1 - g/(2b)) a_n, a = (1 - 1/(2b)) a_n - v_n/(b h),
   then the isolator is updated at that trial state;
2. Newton: K_eff du = p_{n+1} - M a - C v - K_s u - F_iso e_0 with
   K_eff = K_t + g/(b h) C + 1/(b h^2) M (K_t includes the isolator tangent);
3. u += du, v += g/(b h) du, a += du/(b h^2), isolator update; converged when ||du||_2 < tol;
4. commit (the law's trial state becomes its committed state).

The effective matrix is tridiagonal.  Its superstructure part depends on the step size only, so
it is eliminated once (from the roof down) and a Newton iteration costs one residual, one
forward/back substitution and one division by the base pivot (which carries the isolator
tangent); nothing is allocated in the time loop.  The law is called through the template slots
``law_step`` / ``law_step_robust``, bound per law (:func:`_kernels`).  A step whose Newton
iteration fails (no convergence in ``max_iter``, a law status < 0 or a
non-finite force) is retried from the committed state in 2, 4, ... 2^max_levels equal substeps
with the ground acceleration interpolated linearly.

Energy (relative formulation, trapezoidal increments, exact for g = 1/2, b = 1/4 up to the
Newton tolerance): input E_I = -sum (1/2)(a_g,n + a_g,n+1) 1^T M du, viscous E_D = sum
(1/2)(C v_n + C v_n+1)^T du, isolator work E_H = sum (1/2)(F_n + F_n+1) du_0; the kinetic and
recoverable strain energies are evaluated from the state.

Status codes: 0 converged; law codes (< 0, :data:`rrfrei.laws.STATUS_MESSAGES`); -4 Newton did
not converge even after subdivision.
"""

import math

import numpy as np
from numba import njit, prange

from rrfrei.laws.specialise import bindings, instantiate, unbound

# template slots (rrfrei.laws.specialise): the isolator law's step kernels, bound per law
SLOTS = ("law_step", "law_step_robust")
law_step = unbound("law_step")
law_step_robust = unbound("law_step_robust")

# rows of the work array W (each of length ndof)
_U, _V, _A, _UT, _VT, _AT, _DU, _R, _DI, _LO, _CP, _US, _VS, _AS = range(14)
N_WORK_ROWS = 14
# entries of the scalar work array S (the second half keeps a saved copy)
_FC, _EIN, _EVIS, _EISO, _AGC = range(5)
N_SCALARS = 10
# entries of the per-run summary ``out``
OUT_UPEAK, OUT_URES, OUT_VBPEAK, OUT_EISO, OUT_EERR, OUT_NSUB, OUT_NROBUST = range(7)
N_OUT = 7


@njit(cache=True, inline="always")
def _factor(m, ks, cs, cg, c1, c2, W):
    """Superstructure part of K_eff = K_t + c1 C + c2 M (constant for a given step size).

    Writes the off-diagonal W[_LO, j] (DOFs j-1, j) and the factors W[_CP, j] = l_j / d'_j,
    W[_DI, j] = 1 / d'_j of the elimination from the roof down; returns the base pivot d'_0
    without the isolator tangent (the only entry that changes between Newton iterations).
    """
    n = m.shape[0]
    d0 = 0.0
    for j in range(n - 1, -1, -1):
        dj = c2 * m[j] + c1 * cg[j]
        if j < n - 1:
            dj += ks[j] + c1 * cs[j]  # story j+1 above DOF j
        if j > 0:
            lj = -(ks[j - 1] + c1 * cs[j - 1])  # story j below DOF j
            dj -= lj
            W[_LO, j] = lj
        if j < n - 1:
            dj -= W[_LO, j + 1] * W[_CP, j + 1]
        if j > 0:
            W[_DI, j] = 1.0 / dj
            W[_CP, j] = W[_LO, j] / dj
        else:
            d0 = dj
    return d0


@njit(cache=True)
def integrate(p, count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol, max_iter, max_levels,
              robust, store, W, sc, st, sc_save, S, U, VB, A, F, E, iters, levels, drift, acc, out):
    """One analysis from rest; the whole step logic in one flat loop.

    Parameters
    ----------
    p : law parameters (law scale); count, s : bearings and similitude.
    m (ndof) : masses [base, floors] [t]; ks, cs (ndof-1) story springs [kN/m] and dashpots
        [kN s/m]; cg (ndof) dashpots to the ground [kN s/m]; hts (ndof-1) story heights [m].
    state0 : the law's initial state.  ag : ground acceleration [m/s^2] every ``dt`` [s].
    gamma, beta, tol, max_iter, max_levels : Newmark, Newton and subdivision settings.
    robust : at the last subdivision level only (where the default would fail), the isolator
        uses its robust local solve (``law_step_robust``); an output step where it acted
        (OpenSees' local iteration failed) gets ``levels[k] = -1 - level`` (when storing) and is
        counted in ``out[OUT_NROBUST]``.  Everywhere else the steps are the default ones.
    store : write the histories ``U`` (relative displacement) and ``A`` (absolute acceleration)
        (nt, ndof), ``VB`` (story-1 shear), ``F`` (isolator force), ``E`` (nt, 5: input, kinetic,
        viscous, isolator work, story strain), ``iters``, ``levels``; otherwise these are not
        touched (pass small dummies).
    W, sc, st, sc_save, S : work arrays (N_WORK_ROWS x ndof, state x 3, N_SCALARS).
    drift, acc (ndof-1) : receive the peak |drift ratio| per story and the peak |absolute
        acceleration| per floor; out (N_OUT) : peak |u_0|, residual |u_0|, peak base shear,
        isolator work, energy error, number of subdivided steps, number of output steps where the
        robust local solve acted.

    Returns
    -------
    (status, index of the failing output step or -1).
    """
    n = m.shape[0]
    nt = ag.shape[0]
    nst = sc.shape[0]
    ns = S.shape[0] // 2
    # ---- at rest, initial acceleration solved exactly: a_0 = -a_g(0) 1 (no force at rest)
    for r in range(W.shape[0]):
        for j in range(n):
            W[r, j] = 0.0
    for j in range(n):
        W[_A, j] = -ag[0]
    for q in range(S.shape[0]):
        S[q] = 0.0
    S[_AGC] = ag[0]
    for q in range(nst):
        sc[q] = state0[q]
        st[q] = state0[q]
    for i in range(n - 1):
        drift[i] = 0.0
        acc[i] = 0.0
    for q in range(out.shape[0]):
        out[q] = 0.0
    if store:
        for j in range(n):
            U[0, j] = 0.0
            A[0, j] = 0.0
        F[0] = 0.0
        VB[0] = 0.0
        for q in range(E.shape[1]):
            E[0, q] = 0.0
        iters[0] = 0
        levels[0] = 0
    umax = 0.0
    vbmax = 0.0
    imb_max = 0.0
    ein_max = 0.0
    nsubdiv = 0
    nrobust = 0
    cc = count * s * s
    ck = count * s
    h_fact = -1.0
    d0 = 0.0
    for k in range(1, nt):
        ag0 = ag[k - 1]
        ag1 = ag[k]
        n_it = 0
        status = 0
        level = 0
        dev = False
        for level in range(max_levels + 1):
            if level == 1:  # the failed first try committed nothing: save the state at step k-1
                for j in range(n):
                    W[_US, j] = W[_U, j]
                    W[_VS, j] = W[_V, j]
                    W[_AS, j] = W[_A, j]
                for q in range(nst):
                    sc_save[q] = sc[q]
                for q in range(ns):
                    S[ns + q] = S[q]
            elif level > 1:  # restore it
                for j in range(n):
                    W[_U, j] = W[_US, j]
                    W[_V, j] = W[_VS, j]
                    W[_A, j] = W[_AS, j]
                for q in range(nst):
                    sc[q] = sc_save[q]
                for q in range(ns):
                    S[q] = S[ns + q]
            if level > 0:
                for q in range(nst):
                    st[q] = sc[q]
            nsub = 1 << level
            h = dt / nsub
            c1 = gamma / (beta * h)
            c2 = 1.0 / (beta * h * h)
            # superstructure part of K_eff = K_t + c1 C + c2 M (constant for this h): off-diagonal
            # W[_LO, j] (DOFs j-1, j), factors W[_CP, j] = l_j / d'_j and W[_DI, j] = 1 / d'_j of
            # the elimination from the roof down, and d0 = the base pivot without the isolator
            if h != h_fact:
                d0 = _factor(m, ks, cs, cg, c1, c2, W)
                h_fact = h
            status = 0
            for sub in range(nsub):
                agk = ag1 if sub == nsub - 1 else ag0 + (ag1 - ag0) * (sub + 1) / nsub
                # -- predictor
                for j in range(n):
                    W[_UT, j] = W[_U, j]
                    W[_VT, j] = (1.0 - gamma / beta) * W[_V, j] + h * (1.0 - gamma / (2.0 * beta)) * W[_A, j]
                    W[_AT, j] = (1.0 - 1.0 / (2.0 * beta)) * W[_A, j] - W[_V, j] / (beta * h)
                f = 0.0
                kt = 0.0
                converged = False
                for it in range(max_iter + 1):
                    norm = 0.0
                    if it > 0:
                        # -- residual at the current trial state
                        for j in range(n):
                            W[_R, j] = -m[j] * (agk + W[_AT, j]) - cg[j] * W[_VT, j]
                        W[_R, 0] -= f
                        for i in range(1, n):  # story i joins DOF i-1 and DOF i
                            fs = (ks[i - 1] * (W[_UT, i] - W[_UT, i - 1])
                                  + cs[i - 1] * (W[_VT, i] - W[_VT, i - 1]))
                            W[_R, i] -= fs
                            W[_R, i - 1] += fs
                        # -- K_eff du = R, eliminating from the roof down: only the last pivot
                        # (the base, d0 + isolator tangent) changes between iterations
                        for j in range(n - 1, 0, -1):
                            W[_R, j - 1] -= W[_CP, j] * W[_R, j]
                        W[_DU, 0] = W[_R, 0] / (d0 + kt)
                        for j in range(1, n):
                            W[_DU, j] = (W[_R, j] - W[_LO, j] * W[_DU, j - 1]) * W[_DI, j]
                        for j in range(n):
                            d = W[_DU, j]
                            W[_UT, j] += d
                            W[_VT, j] += c1 * d
                            W[_AT, j] += c2 * d
                            norm += d * d
                    # -- isolator update at the trial state (the only law call site)
                    ul = W[_UT, 0] / s
                    vl = W[_VT, 0] / s
                    if robust and level == max_levels:
                        fl, kl, status = law_step_robust(p, sc, ul, vl, h, st)
                        if status > 0:  # the robust solve acted: a deviation from OpenSees
                            status = 0
                            dev = True
                    else:
                        fl, kl, status = law_step(p, sc, ul, vl, h, st)
                    f = cc * fl
                    kt = ck * kl
                    n_it += 1 if it > 0 else 0
                    if status != 0:
                        break
                    if not (math.isfinite(f) and math.isfinite(kt) and math.isfinite(norm)):
                        status = -3
                        break
                    if it > 0 and math.sqrt(norm) < tol:
                        converged = True
                        break
                if status == 0 and not converged:
                    status = -4
                if status != 0:
                    break
                # -- commit: energy increments (trapezoidal), then trial -> committed
                e_in = 0.0
                e_vis = 0.0
                agm = 0.5 * (S[_AGC] + agk)
                for j in range(n):
                    dj = W[_UT, j] - W[_U, j]
                    e_in -= m[j] * agm * dj
                    e_vis += 0.5 * cg[j] * (W[_V, j] + W[_VT, j]) * dj
                for i in range(1, n):
                    dd = (W[_UT, i] - W[_UT, i - 1]) - (W[_U, i] - W[_U, i - 1])
                    e_vis += 0.5 * cs[i - 1] * ((W[_V, i] - W[_V, i - 1]) + (W[_VT, i] - W[_VT, i - 1])) * dd
                S[_EIN] += e_in
                S[_EVIS] += e_vis
                S[_EISO] += 0.5 * (S[_FC] + f) * (W[_UT, 0] - W[_U, 0])
                S[_FC] = f
                S[_AGC] = agk
                for j in range(n):
                    W[_U, j] = W[_UT, j]
                    W[_V, j] = W[_VT, j]
                    W[_A, j] = W[_AT, j]
                for q in range(nst):
                    sc[q] = st[q]
            if status == 0:
                break
        if store:
            iters[k] = n_it
            levels[k] = -1 - level if dev else level
        if status != 0:
            if store:
                for j in range(n):
                    U[k, j] = W[_U, j]
            out[OUT_UPEAK] = umax
            out[OUT_NSUB] = nsubdiv
            out[OUT_NROBUST] = nrobust
            return status, k
        if level > 0:
            nsubdiv += 1
        if dev:
            nrobust += 1
        # -- output step k: stored energies, peaks, histories
        ek = 0.0
        es = 0.0
        for j in range(n):
            ek += 0.5 * m[j] * W[_V, j] * W[_V, j]
        for i in range(1, n):
            d = W[_U, i] - W[_U, i - 1]
            es += 0.5 * ks[i - 1] * d * d
            dr = abs(d) / hts[i - 1]
            if dr > drift[i - 1]:
                drift[i - 1] = dr
            aa = abs(W[_A, i] + ag1)
            if aa > acc[i - 1]:
                acc[i - 1] = aa
        u0 = abs(W[_U, 0])
        if u0 > umax:
            umax = u0
        vb = ks[0] * (W[_U, 1] - W[_U, 0]) + cs[0] * (W[_V, 1] - W[_V, 0])
        if abs(vb) > vbmax:
            vbmax = abs(vb)
        imb = abs(S[_EIN] - ek - S[_EVIS] - S[_EISO] - es)
        if imb > imb_max:
            imb_max = imb
        if abs(S[_EIN]) > ein_max:
            ein_max = abs(S[_EIN])
        if store:
            for j in range(n):
                U[k, j] = W[_U, j]
                A[k, j] = W[_A, j] + ag1
            F[k] = S[_FC]
            VB[k] = vb
            E[k, 0] = S[_EIN]
            E[k, 1] = ek
            E[k, 2] = S[_EVIS]
            E[k, 3] = S[_EISO]
            E[k, 4] = es
    out[OUT_UPEAK] = umax
    out[OUT_URES] = abs(W[_U, 0])
    out[OUT_VBPEAK] = vbmax
    out[OUT_EISO] = S[_EISO]
    out[OUT_EERR] = imb_max / ein_max if ein_max > 0.0 else 0.0
    out[OUT_NSUB] = nsubdiv
    out[OUT_NROBUST] = nrobust
    return 0, -1


def work_arrays(ndof: int, state_size: int):
    """(W, sc, st, sc_save, S) for :func:`integrate`."""
    return (np.zeros((N_WORK_ROWS, ndof)), np.zeros(state_size), np.zeros(state_size), np.zeros(state_size),
            np.zeros(N_SCALARS))


@njit(cache=True, parallel=True)
def batch(P, count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol, max_iter, max_levels,
          robust, n_blocks, status, drift, acc, out):
    """Run the parameter sets ``P`` (runs, n_params) in ``n_blocks`` parallel blocks.

    Each block allocates its work arrays once and runs its analyses one after another (one thread
    per analysis at a time).  Per run: ``status``, ``drift`` / ``acc`` rows and ``out`` rows as in
    :func:`integrate`.
    """
    runs = P.shape[0]
    n = m.shape[0]
    nst = state0.shape[0]
    for b in prange(n_blocks):
        W = np.zeros((N_WORK_ROWS, n))
        sc = np.zeros(nst)
        st = np.zeros(nst)
        sc_save = np.zeros(nst)
        S = np.zeros(N_SCALARS)
        U = np.zeros((1, n))
        F = np.zeros(1)
        E = np.zeros((1, 5))
        it = np.zeros(1, dtype=np.int64)
        lo = (runs * b) // n_blocks
        hi = (runs * (b + 1)) // n_blocks
        for r in range(lo, hi):
            res = integrate(P[r], count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol,
                            max_iter, max_levels, robust, False, W, sc, st, sc_save, S, U, F, U, F, E, it, it,
                            drift[r], acc[r], out[r])
            status[r] = res[0]


# =============================================================================================
# public API
# =============================================================================================
import warnings  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

from rrfrei.laws import STATUS_MESSAGES  # noqa: E402
from rrfrei.simulate import deviation_warning, robust_hint, robust_local_solve  # noqa: E402
from structures import energy as _energy  # noqa: E402

_DEFAULT_MAX_ITER = 50
_DEFAULT_LEVELS = 6


def _kernels(spec):
    """This module's kernels (:func:`integrate`, :func:`batch`) with the law ``spec`` bound
    (an instance of this module as a template, :mod:`rrfrei.laws.specialise`)."""
    return instantiate(__name__, bindings(spec), spec.name)


class ConvergenceError(RuntimeError):
    """A time step failed even after subdivision (the message names record, time and state)."""


@dataclass(frozen=True, eq=False)
class Response:
    """Time history of a shear building (arrays over the output times).

    Attributes
    ----------
    record : name of the ground motion.
    time : (n,) [s].
    isolator_disp, isolator_force : (n,) layer displacement [m] and force [kN].
    floor_disp : (n, stories) floor displacement relative to the ground [m], roof last.
    drift, drift_ratio : (n, stories) story drift [m] (floor i minus floor i-1, the base slab
        below story 1) and drift / story height [-].
    floor_accel_abs : (n, stories) absolute floor acceleration [m/s^2], roof last.
    base_accel_abs : (n,) absolute acceleration of the base slab [m/s^2].
    base_shear : (n,) shear force in story 1 (spring + dashpot), i.e. above the isolators [kN].
    energy : dict of (n,) energy histories [kN m] (see :mod:`structures.energy`).
    energy_error : max |imbalance| / max |input energy| [-].
    newton_iterations : (n,) Newton iterations per output step (summed over substeps).
    subdivided_steps : indices of the output steps that needed substeps.
    robust_steps : indices of the output steps where ``local_solver="robust"`` replaced
        OpenSees' failed local iteration (a deviation from OpenSees; empty by default).
    """

    record: str
    time: np.ndarray
    isolator_disp: np.ndarray
    isolator_force: np.ndarray
    floor_disp: np.ndarray
    drift: np.ndarray
    drift_ratio: np.ndarray
    floor_accel_abs: np.ndarray
    base_accel_abs: np.ndarray
    base_shear: np.ndarray
    energy: dict
    energy_error: float
    newton_iterations: np.ndarray
    subdivided_steps: np.ndarray
    robust_steps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def summary(self) -> dict[str, float]:
        """Peak demands (absolute values): isolator displacement [m] and force [kN], residual
        isolator displacement [m], peak drift ratio [-], peak roof and floor absolute
        accelerations [m/s^2], base shear [kN], isolator work [kN m], energy error, steps."""
        return {
            "isolator_disp_peak": float(np.max(np.abs(self.isolator_disp))),
            "isolator_disp_residual": float(abs(self.isolator_disp[-1])),
            "isolator_force_peak": float(np.max(np.abs(self.isolator_force))),
            "drift_ratio_peak": float(np.max(np.abs(self.drift_ratio))),
            "roof_accel_abs_peak": float(np.max(np.abs(self.floor_accel_abs[:, -1]))),
            "floor_accel_abs_peak": float(np.max(np.abs(self.floor_accel_abs))),
            "base_shear_peak": float(np.max(np.abs(self.base_shear))),
            "isolator_work": float(self.energy["isolator"][-1]),
            "energy_error": float(self.energy_error),
            "newton_iterations_mean": (
                float(np.mean(self.newton_iterations[1:])) if self.time.size > 1 else 0.0
            ),
            "subdivided_steps": int(self.subdivided_steps.size),
            "robust_steps": int(self.robust_steps.size),
        }


def _options(gamma, beta, tol, max_iter, max_subdivisions):
    g = float(gamma)
    b = float(beta)
    if not (np.isfinite(g) and g > 0.0):
        raise ValueError(f"gamma = {gamma!r} is invalid: expected a finite number > 0 (0.5 is standard)")
    if not (np.isfinite(b) and b > 0.0):
        raise ValueError(f"beta = {beta!r} is invalid: expected a finite number > 0 (0.25 is standard)")
    t = float(tol)
    if not (np.isfinite(t) and t > 0.0):
        raise ValueError(f"tol = {tol!r} is invalid: expected a finite number > 0 [m]")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter = {max_iter!r} is invalid: expected an integer >= 1")
    if (isinstance(max_subdivisions, bool) or not isinstance(max_subdivisions, (int, np.integer))
            or not 0 <= max_subdivisions <= 20):
        raise ValueError(
            f"max_subdivisions = {max_subdivisions!r} is invalid: expected an integer in [0, 20]"
        )
    return g, b, t, int(max_iter), int(max_subdivisions)


def _ground(record, dt) -> tuple[str, np.ndarray, float]:
    """(name, ground acceleration [m/s^2] at the analysis step, step [s])."""
    name = str(getattr(record, "name", "record"))
    try:
        rdt = float(record.dt)
        acc = np.asarray(record.accel, dtype=float)
    except (AttributeError, TypeError, ValueError):
        raise ValueError(
            f"record must be a ground_motions.Record (dt [s], accel [m/s^2]), got {type(record).__name__}"
        ) from None
    if not (np.isfinite(rdt) and rdt > 0.0):
        raise ValueError(f"record {name!r}: dt = {rdt!r} is invalid: expected a finite number > 0 s")
    if acc.ndim != 1 or acc.size < 2:
        raise ValueError(
            f"record {name!r}: accel must be a 1-D array of at least 2 values, got shape {acc.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(acc))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"record {name!r}: accel[{i}] = {float(acc[i])!r} (t = {i * rdt:g} s) is not finite")
    if dt is None or float(dt) == rdt:
        return name, np.ascontiguousarray(acc), rdt
    h = float(dt)
    if not (np.isfinite(h) and 0.0 < h <= rdt):
        raise ValueError(
            f"dt = {dt!r} is invalid for record {name!r}: expected 0 < dt <= the record step {rdt:g} s "
            "(the record is interpolated linearly onto the finer step)"
        )
    duration = (acc.size - 1) * rdt
    n = int(np.floor(duration / h * (1.0 + 1e-12))) + 1
    return name, np.interp(np.arange(n) * h, np.arange(acc.size) * rdt, acc), h


def _model(building):
    from structures.building import ShearBuilding

    if not isinstance(building, ShearBuilding):
        raise ValueError(f"building must be a ShearBuilding, got {type(building).__name__}")
    iso = building.isolator
    spec = iso.spec
    m = np.concatenate(([building.base_mass], building.story_masses))
    ks = np.asarray(building.story_stiffness, dtype=float)
    cs, cg = building.damping_coefficients()
    hts = np.asarray(building.story_heights, dtype=float)
    return spec, iso, m, ks, np.ascontiguousarray(cs), np.ascontiguousarray(cg), hts


def time_history(
    building,
    record,
    *,
    gamma: float = 0.5,
    beta: float = 0.25,
    dt: float | None = None,
    tol: float = 1e-12,
    max_iter: int = _DEFAULT_MAX_ITER,
    max_subdivisions: int = _DEFAULT_LEVELS,
    local_solver: str = "opensees",
) -> Response:
    """Nonlinear time history of ``building`` under the ground acceleration ``record``.

    Newmark (``gamma``, ``beta``) with Newton-Raphson on the isolator tangent, started from rest
    (a_0 = -a_g(0) exactly); the steps are those of OpenSees' Newmark + Newton + NormDispIncr
    (see :mod:`structures.newmark`), so with ``record.accel[0] == 0`` the result matches an
    openseespy model of the same building (``record.with_leading_zero()``).

    Parameters
    ----------
    building : :class:`structures.ShearBuilding` whose isolator has parameters.
    record : ``ground_motions.Record`` (``dt`` [s], ``accel`` [m/s^2]).
    dt : analysis step [s]; None uses the record's step, a smaller one interpolates the record
        linearly.
    tol : Newton convergence on ||du||_2 [m] (OpenSees NormDispIncr).
    max_iter : Newton iterations per (sub)step before the step is subdivided.
    max_subdivisions : a failing step is retried in 2, 4, ... 2^max_subdivisions substeps.
    local_solver : ``"opensees"`` (default): the isolator law's own OpenSees local iteration.
        ``"robust"`` (Bouc-Wen; see :func:`rrfrei.simulate_force`): at the last subdivision level
        only, i.e. where the default would raise, a failed (or falsely converged) OpenSees local
        iteration is replaced by the bracketed safeguarded Newton solve of the same equation.
        The response is the default one wherever the default completes; the output steps where
        the robust solve
        acted are ``Response.robust_steps`` and are named by a
        :class:`rrfrei.simulate.LocalSolverDeviation` warning.

    Raises
    ------
    ValueError : bad building, record (non-finite values), dt or options.
    ConvergenceError : a step failed at every subdivision; names the record, time and state.
    """
    g, b, t, it, lv = _options(gamma, beta, tol, max_iter, max_subdivisions)
    spec, iso, m, ks, cs, cg, hts = _model(building)
    robust = robust_local_solve(spec, local_solver)
    p = iso.packed()
    name, ag, h = _ground(record, dt)
    n, ndof = ag.size, m.size
    U = np.empty((n, ndof))
    A = np.empty((n, ndof))
    F = np.empty(n)
    VB = np.empty(n)
    E = np.empty((n, len(_energy.TERMS)))
    iters = np.zeros(n, dtype=np.int64)
    levels = np.zeros(n, dtype=np.int64)
    W, sc, st, sc_save, S = work_arrays(ndof, spec.state_size)
    drift_pk = np.zeros(ndof - 1)
    acc_pk = np.zeros(ndof - 1)
    out = np.zeros(N_OUT)
    status, k = _kernels(spec).integrate(
        p, float(iso.count), float(iso.length_scale), m, ks, cs, cg, hts,
        np.array(spec.initial_state, dtype=float), ag, h, g, b, t, it, lv, robust, True,
        W, sc, st, sc_save, S, U, VB, A, F, E, iters, levels, drift_pk, acc_pk, out)
    if status != 0:
        raise ConvergenceError(
            f"record {name!r}: the step to t = {k * h:.6g} s (step {k}) failed even in "
            f"{2 ** lv} substeps: {STATUS_MESSAGES.get(int(status), f'status {status}')}; state at "
            f"t = {(k - 1) * h:.6g} s: isolator displacement {U[k - 1, 0]:.6g} m, force "
            f"{F[k - 1]:.6g} kN, base shear {VB[k - 1]:.6g} kN; law {spec.name!r} with parameters "
            f"{spec.as_dict(p)}, {iso.count} bearings, length_scale {iso.length_scale:g}"
            + robust_hint(spec, status, robust)
        )
    robust_steps = np.flatnonzero(levels < 0)
    if robust_steps.size:
        warnings.warn(deviation_warning(spec.name, robust_steps, "time step"), stacklevel=2)
    levels = np.where(levels < 0, -1 - levels, levels)
    energy = _energy.as_dict(E)
    drift = U[:, 1:] - U[:, :-1]
    return Response(
        record=name,
        time=np.arange(n) * h,
        isolator_disp=U[:, 0],
        isolator_force=F,
        floor_disp=U[:, 1:],
        drift=drift,
        drift_ratio=drift / hts,
        floor_accel_abs=A[:, 1:],
        base_accel_abs=A[:, 0],
        base_shear=VB,
        energy=energy,
        energy_error=float(out[OUT_EERR]),
        newton_iterations=iters,
        subdivided_steps=np.flatnonzero(levels > 0),
        robust_steps=robust_steps,
    )


def time_history_batch(
    building,
    record,
    params,
    *,
    gamma: float = 0.5,
    beta: float = 0.25,
    dt: float | None = None,
    tol: float = 1e-12,
    max_iter: int = _DEFAULT_MAX_ITER,
    max_subdivisions: int = _DEFAULT_LEVELS,
    n_blocks: int | None = None,
    local_solver: str = "opensees",
) -> dict[str, np.ndarray]:
    """Peak demands of ``building`` under ``record`` for many isolator parameter sets.

    Runs m analyses in parallel (Numba ``prange`` over blocks of runs; each block preallocates
    its work arrays).  Same integration as :func:`time_history`.

    Parameters
    ----------
    params : (m, n_params) array in the law's ``param_names`` order (law scale, before
        similitude); every row is validated by the law.
    n_blocks : number of parallel blocks (default: 4 per Numba thread, at most m).
    local_solver : as in :func:`time_history`; ``robust_steps`` counts, per run, the output steps
        where the robust solve acted (no warning is issued here).

    Returns
    -------
    dict of arrays over the m runs: ``iso_disp_peak`` [m], ``iso_disp_residual`` [m] (|u_0| at
    the end), ``iso_disp_max_abs`` [m] (= peak; for a failed run the largest reached before it
    failed), ``drift_peak`` (m, stories) [-], ``floor_acc_peak`` (m, stories) absolute
    [m/s^2], ``base_shear_peak`` [kN], ``iso_energy``
    (isolator work at the end) [kN m], ``energy_error`` [-], ``subdivided_steps``,
    ``robust_steps``, ``status``
    (0 = converged) and ``converged`` (bool).  Runs that failed hold NaN demands.
    """
    import numba

    g, b, t, it, lv = _options(gamma, beta, tol, max_iter, max_subdivisions)
    spec, iso, m, ks, cs, cg, hts = _model(building)
    robust = robust_local_solve(spec, local_solver)
    name, ag, h = _ground(record, dt)
    P = np.asarray(params, dtype=float)
    if P.ndim == 1:
        P = P[None, :]
    if P.ndim != 2 or P.shape[1] != len(spec.param_names):
        raise ValueError(
            f"params must be an (m, {len(spec.param_names)}) array for law {spec.name!r} "
            f"({', '.join(spec.param_names)}), got shape {P.shape}"
        )
    for r in range(P.shape[0]):
        try:
            spec.pack(P[r])
        except ValueError as exc:
            raise ValueError(f"params row {r}: {exc}") from None
    P = np.ascontiguousarray(P)
    runs = P.shape[0]
    nst = m.size - 1
    if n_blocks is None:
        n_blocks = 4 * numba.get_num_threads()
    nb = max(1, min(int(n_blocks), runs))
    status = np.zeros(runs, dtype=np.int64)
    drift = np.zeros((runs, nst))
    acc = np.zeros((runs, nst))
    res = np.zeros((runs, N_OUT))
    if runs:
        _kernels(spec).batch(P, float(iso.count), float(iso.length_scale), m, ks, cs, cg, hts,
              np.array(spec.initial_state, dtype=float), ag, h, g, b, t, it, lv, robust, nb, status,
              drift, acc, res)
    ok = status == 0
    u_peak = res[:, OUT_UPEAK].copy()
    out = {
        "iso_disp_peak": u_peak,
        "iso_disp_residual": res[:, OUT_URES].copy(),
        "drift_peak": drift,
        "floor_acc_peak": acc,
        "base_shear_peak": res[:, OUT_VBPEAK].copy(),
        "iso_energy": res[:, OUT_EISO].copy(),
        "energy_error": res[:, OUT_EERR].copy(),
    }
    for arr in out.values():
        arr[~ok] = np.nan
    n_sub = res[:, OUT_NSUB].astype(np.int64)
    out["iso_disp_max_abs"] = res[:, OUT_UPEAK].copy()  # failed runs: the largest before failing
    out["subdivided_steps"] = n_sub
    out["robust_steps"] = res[:, OUT_NROBUST].astype(np.int64)
    out["status"] = status
    out["converged"] = ok
    return out
