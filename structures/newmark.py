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

The effective matrix is tridiagonal and solved in place (Thomas algorithm, no allocation).  A
step whose Newton iteration fails (no convergence in ``max_iter``, a law status < 0 or a
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

from rrfrei.laws.kernel import step as law_step

# rows of the work array W (each of length ndof)
_U, _V, _A, _UT, _VT, _AT, _DU, _R, _DI, _LO, _CP, _US, _VS, _AS = range(14)
N_WORK_ROWS = 14
# entries of the scalar work array S
_FC, _EIN, _EVIS, _EISO, _AGC, _KC = range(6)
N_SCALARS = 12  # second half keeps the saved copy


@njit(cache=True)
def _iso(code, p, count, s, sc, st, u, v, h):
    """Layer force [kN] and tangent [kN/m] by similitude: count s^2 F(u/s, v/s), count s k."""
    f, k, status = law_step(code, p, sc, u / s, v / s, h, st)
    return count * s * s * f, count * s * k, status


@njit(cache=True)
def _try_step(code, p, count, s, m, ks, cs, cg, h, ag1, gamma, beta, tol, max_iter, W, sc, st):
    """One Newmark step of size ``h`` from the committed rows to the trial rows of ``W``.

    Returns (status, iterations, isolator force, isolator tangent).
    """
    n = m.shape[0]
    c1 = gamma / (beta * h)
    c2 = 1.0 / (beta * h * h)
    u = W[_U]
    v = W[_V]
    a = W[_A]
    ut = W[_UT]
    vt = W[_VT]
    at = W[_AT]
    du = W[_DU]
    r = W[_R]
    di = W[_DI]
    lo = W[_LO]
    cp = W[_CP]
    for j in range(n):
        ut[j] = u[j]
        vt[j] = (1.0 - gamma / beta) * v[j] + h * (1.0 - gamma / (2.0 * beta)) * a[j]
        at[j] = (1.0 - 1.0 / (2.0 * beta)) * a[j] - v[j] / (beta * h)
    f, kt, status = _iso(code, p, count, s, sc, st, ut[0], vt[0], h)
    if status != 0:
        return status, 0, f, kt
    if not (math.isfinite(f) and math.isfinite(kt)):
        return -3, 0, f, kt
    for it in range(max_iter):
        # residual and effective tangent
        for j in range(n):
            r[j] = -m[j] * (ag1 + at[j]) - cg[j] * vt[j]
            di[j] = c2 * m[j] + c1 * cg[j]
        r[0] -= f
        di[0] += kt
        for i in range(1, n):  # story i joins DOF i-1 and DOF i
            ke = ks[i - 1] + c1 * cs[i - 1]
            fs = ks[i - 1] * (ut[i] - ut[i - 1]) + cs[i - 1] * (vt[i] - vt[i - 1])
            r[i] -= fs
            r[i - 1] += fs
            di[i] += ke
            di[i - 1] += ke
            lo[i] = -ke
        # Thomas algorithm (symmetric tridiagonal), solution in du
        b = di[0]
        du[0] = r[0] / b
        for i in range(1, n):
            cp[i - 1] = lo[i] / b
            b = di[i] - lo[i] * cp[i - 1]
            du[i] = (r[i] - lo[i] * du[i - 1]) / b
        for i in range(n - 2, -1, -1):
            du[i] -= cp[i] * du[i + 1]
        norm = 0.0
        for j in range(n):
            ut[j] += du[j]
            vt[j] += c1 * du[j]
            at[j] += c2 * du[j]
            norm += du[j] * du[j]
        f, kt, status = _iso(code, p, count, s, sc, st, ut[0], vt[0], h)
        if status != 0:
            return status, it + 1, f, kt
        if not (math.isfinite(f) and math.isfinite(kt) and math.isfinite(norm)):
            return -3, it + 1, f, kt
        if math.sqrt(norm) < tol:
            return 0, it + 1, f, kt
    return -4, max_iter, f, kt


@njit(cache=True)
def _commit(m, ks, cs, cg, ag1, f, kt, W, sc, st, S):
    """Accumulate the energy increments of the converged trial state, then commit it."""
    n = m.shape[0]
    u = W[_U]
    v = W[_V]
    a = W[_A]
    ut = W[_UT]
    vt = W[_VT]
    at = W[_AT]
    e_in = 0.0
    e_vis = 0.0
    agm = 0.5 * (S[_AGC] + ag1)
    for j in range(n):
        dj = ut[j] - u[j]
        e_in -= m[j] * agm * dj
        e_vis += 0.5 * cg[j] * (v[j] + vt[j]) * dj
    for i in range(1, n):
        dd = (ut[i] - ut[i - 1]) - (u[i] - u[i - 1])
        e_vis += 0.5 * cs[i - 1] * ((v[i] - v[i - 1]) + (vt[i] - vt[i - 1])) * dd
    S[_EIN] += e_in
    S[_EVIS] += e_vis
    S[_EISO] += 0.5 * (S[_FC] + f) * (ut[0] - u[0])
    S[_FC] = f
    S[_KC] = kt
    S[_AGC] = ag1
    for j in range(n):
        u[j] = ut[j]
        v[j] = vt[j]
        a[j] = at[j]
    for q in range(sc.shape[0]):
        sc[q] = st[q]


@njit(cache=True)
def _advance(code, p, count, s, m, ks, cs, cg, h, ag0, ag1, gamma, beta, tol, max_iter, max_levels,
             W, sc, st, sc_save, S):
    """Advance one output step of size ``h`` (ground acceleration ag0 -> ag1), subdividing on
    failure.  Returns (status, Newton iterations, subdivision level used)."""
    n = m.shape[0]
    ns = S.shape[0] // 2
    for j in range(n):
        W[_US, j] = W[_U, j]
        W[_VS, j] = W[_V, j]
        W[_AS, j] = W[_A, j]
    for q in range(sc.shape[0]):
        sc_save[q] = sc[q]
    for q in range(ns):
        S[ns + q] = S[q]
    iters = 0
    nsub = 1
    status = 0
    for level in range(max_levels + 1):
        status = 0
        for k in range(nsub):
            agk = ag1 if k == nsub - 1 else ag0 + (ag1 - ag0) * (k + 1) / nsub
            status, it, f, kt = _try_step(code, p, count, s, m, ks, cs, cg, h / nsub, agk, gamma, beta,
                                          tol, max_iter, W, sc, st)
            iters += it
            if status != 0:
                break
            _commit(m, ks, cs, cg, agk, f, kt, W, sc, st, S)
        if status == 0:
            return 0, iters, level
        # restore the state at the start of the step and retry with twice as many substeps
        for j in range(n):
            W[_U, j] = W[_US, j]
            W[_V, j] = W[_VS, j]
            W[_A, j] = W[_AS, j]
        for q in range(sc.shape[0]):
            sc[q] = sc_save[q]
            st[q] = sc_save[q]
        for q in range(ns):
            S[q] = S[ns + q]
        nsub *= 2
    return status, iters, max_levels


@njit(cache=True)
def _start(m, ag0, state0, W, sc, st, S):
    """At rest with the initial acceleration solved exactly: a_0 = -a_g(0) 1 (no force at rest)."""
    W[:, :] = 0.0
    S[:] = 0.0
    for j in range(m.shape[0]):
        W[_A, j] = -ag0
    for q in range(state0.shape[0]):
        sc[q] = state0[q]
        st[q] = state0[q]
    S[_AGC] = ag0


@njit(cache=True)
def _stored_energy(m, ks, W):
    """(kinetic, recoverable strain of the stories) of the committed state [kN m]."""
    ek = 0.0
    es = 0.0
    for j in range(m.shape[0]):
        ek += 0.5 * m[j] * W[_V, j] * W[_V, j]
    for i in range(1, m.shape[0]):
        d = W[_U, i] - W[_U, i - 1]
        es += 0.5 * ks[i - 1] * d * d
    return ek, es


@njit(cache=True)
def history(code, p, count, s, m, ks, cs, cg, state0, ag, dt, gamma, beta, tol, max_iter, max_levels,
            U, V, A, F, E, iters, levels):
    """Full response histories.

    Writes, for every output step k (time k dt): ``U``, ``V`` (ndof) relative displacement and
    velocity, ``A`` (ndof) absolute acceleration, ``F`` isolator force, ``E`` (5) energies
    [input, kinetic, viscous, isolator work, story strain], ``iters`` Newton iterations and
    ``levels`` subdivision level.  Returns (status, failing step index or -1).
    """
    n = m.shape[0]
    W = np.zeros((N_WORK_ROWS, n))
    sc = np.zeros(state0.shape[0])
    st = np.zeros(state0.shape[0])
    sc_save = np.zeros(state0.shape[0])
    S = np.zeros(N_SCALARS)
    _start(m, ag[0], state0, W, sc, st, S)
    for j in range(n):
        U[0, j] = 0.0
        V[0, j] = 0.0
        A[0, j] = 0.0
    F[0] = 0.0
    E[0, :] = 0.0
    iters[0] = 0
    levels[0] = 0
    for k in range(1, ag.shape[0]):
        status, it, lev = _advance(code, p, count, s, m, ks, cs, cg, dt, ag[k - 1], ag[k], gamma, beta,
                                   tol, max_iter, max_levels, W, sc, st, sc_save, S)
        iters[k] = it
        levels[k] = lev
        if status != 0:
            for j in range(n):
                U[k, j] = W[_U, j]
                V[k, j] = W[_V, j]
            return status, k
        for j in range(n):
            U[k, j] = W[_U, j]
            V[k, j] = W[_V, j]
            A[k, j] = W[_A, j] + ag[k]
        F[k] = S[_FC]
        ek, es = _stored_energy(m, ks, W)
        E[k, 0] = S[_EIN]
        E[k, 1] = ek
        E[k, 2] = S[_EVIS]
        E[k, 3] = S[_EISO]
        E[k, 4] = es
    return 0, -1


@njit(cache=True)
def _peaks_one(code, p, count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol, max_iter,
               max_levels, W, sc, st, sc_save, S, drift, acc):
    """One analysis, peaks only.  ``drift`` (n-1) and ``acc`` (n-1) receive the peak |drift ratio|
    per story and the peak |absolute acceleration| per floor.  Returns (status, peak |u_0|,
    residual |u_0|, peak base shear, isolator work, energy error, subdivided steps)."""
    n = m.shape[0]
    _start(m, ag[0], state0, W, sc, st, S)
    for i in range(n - 1):
        drift[i] = 0.0
        acc[i] = 0.0
    umax = 0.0
    vbmax = 0.0
    imb_max = 0.0
    ein_max = 0.0
    nsub = 0
    for k in range(1, ag.shape[0]):
        status, it, lev = _advance(code, p, count, s, m, ks, cs, cg, dt, ag[k - 1], ag[k], gamma, beta,
                                   tol, max_iter, max_levels, W, sc, st, sc_save, S)
        if status != 0:
            return status, umax, 0.0, vbmax, S[_EISO], 0.0, nsub
        if lev > 0:
            nsub += 1
        u0 = abs(W[_U, 0])
        if u0 > umax:
            umax = u0
        for i in range(1, n):
            dr = abs(W[_U, i] - W[_U, i - 1]) / hts[i - 1]
            if dr > drift[i - 1]:
                drift[i - 1] = dr
            aa = abs(W[_A, i] + ag[k])
            if aa > acc[i - 1]:
                acc[i - 1] = aa
        vb = abs(ks[0] * (W[_U, 1] - W[_U, 0]) + cs[0] * (W[_V, 1] - W[_V, 0]))
        if vb > vbmax:
            vbmax = vb
        ek, es = _stored_energy(m, ks, W)
        imb = abs(S[_EIN] - ek - S[_EVIS] - S[_EISO] - es)
        if imb > imb_max:
            imb_max = imb
        if abs(S[_EIN]) > ein_max:
            ein_max = abs(S[_EIN])
    err = imb_max / ein_max if ein_max > 0.0 else 0.0
    return 0, umax, abs(W[_U, 0]), vbmax, S[_EISO], err, nsub


@njit(cache=True, parallel=True)
def batch(code, P, count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol, max_iter, max_levels,
          n_blocks, status, u_peak, u_res, drift, acc, vb, e_iso, e_err, n_sub):
    """Run the parameter sets ``P`` (m_runs, n_params) in ``n_blocks`` parallel blocks.

    Each block allocates its work arrays once and runs its analyses one after another
    (one thread per analysis at a time).  Outputs are per run (first axis).
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
        lo = (runs * b) // n_blocks
        hi = (runs * (b + 1)) // n_blocks
        for r in range(lo, hi):
            out = _peaks_one(code, P[r], count, s, m, ks, cs, cg, hts, state0, ag, dt, gamma, beta, tol,
                             max_iter, max_levels, W, sc, st, sc_save, S, drift[r], acc[r])
            status[r] = out[0]
            u_peak[r] = out[1]
            u_res[r] = out[2]
            vb[r] = out[3]
            e_iso[r] = out[4]
            e_err[r] = out[5]
            n_sub[r] = out[6]


# =============================================================================================
# public API
# =============================================================================================
from dataclasses import dataclass  # noqa: E402

from rrfrei.laws import STATUS_MESSAGES  # noqa: E402
from structures import energy as _energy  # noqa: E402

_DEFAULT_MAX_ITER = 50
_DEFAULT_LEVELS = 6


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

    Raises
    ------
    ValueError : bad building, record (non-finite values), dt or options.
    ConvergenceError : a step failed at every subdivision; names the record, time and state.
    """
    g, b, t, it, lv = _options(gamma, beta, tol, max_iter, max_subdivisions)
    spec, iso, m, ks, cs, cg, hts = _model(building)
    p = iso.packed()
    name, ag, h = _ground(record, dt)
    n, ndof = ag.size, m.size
    U = np.zeros((n, ndof))
    V = np.zeros((n, ndof))
    A = np.zeros((n, ndof))
    F = np.zeros(n)
    E = np.zeros((n, len(_energy.TERMS)))
    iters = np.zeros(n, dtype=np.int64)
    levels = np.zeros(n, dtype=np.int64)
    status, k = history(spec.code, p, float(iso.count), float(iso.length_scale), m, ks, cs, cg,
                        np.array(spec.initial_state, dtype=float), ag, h, g, b, t, it, lv,
                        U, V, A, F, E, iters, levels)
    if status != 0:
        raise ConvergenceError(
            f"record {name!r}: the step to t = {k * h:.6g} s (step {k}) failed even in "
            f"{2 ** lv} substeps: {STATUS_MESSAGES.get(int(status), f'status {status}')}; state at "
            f"t = {(k - 1) * h:.6g} s: isolator displacement {U[k - 1, 0]:.6g} m, velocity "
            f"{V[k - 1, 0]:.6g} m/s, force {F[k - 1]:.6g} kN; law {spec.name!r} with parameters "
            f"{spec.as_dict(p)}, {iso.count} bearings, length_scale {iso.length_scale:g}"
        )
    energy = _energy.as_dict(E)
    floors = U[:, 1:]
    drift = np.diff(U, axis=1)
    vb = ks[0] * (U[:, 1] - U[:, 0]) + cs[0] * (V[:, 1] - V[:, 0])
    return Response(
        record=name,
        time=np.arange(n) * h,
        isolator_disp=U[:, 0].copy(),
        isolator_force=F,
        floor_disp=np.ascontiguousarray(floors),
        drift=drift,
        drift_ratio=drift / hts,
        floor_accel_abs=np.ascontiguousarray(A[:, 1:]),
        base_accel_abs=A[:, 0].copy(),
        base_shear=vb,
        energy=energy,
        energy_error=_energy.balance_error(energy),
        newton_iterations=iters,
        subdivided_steps=np.flatnonzero(levels > 0),
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
) -> dict[str, np.ndarray]:
    """Peak demands of ``building`` under ``record`` for many isolator parameter sets.

    Runs m analyses in parallel (Numba ``prange`` over blocks of runs; each block preallocates
    its work arrays).  Same integration as :func:`time_history`.

    Parameters
    ----------
    params : (m, n_params) array in the law's ``param_names`` order (law scale, before
        similitude); every row is validated by the law.
    n_blocks : number of parallel blocks (default: 4 per Numba thread, at most m).

    Returns
    -------
    dict of arrays over the m runs: ``iso_disp_peak`` [m], ``iso_disp_residual`` [m] (|u_0| at
    the end), ``iso_disp_max_abs`` [m] (= peak), ``drift_peak`` (m, stories) [-],
    ``floor_acc_peak`` (m, stories) absolute [m/s^2], ``base_shear_peak`` [kN], ``iso_energy``
    (isolator work at the end) [kN m], ``energy_error`` [-], ``subdivided_steps``, ``status``
    (0 = converged) and ``converged`` (bool).  Runs that failed hold NaN demands.
    """
    import numba

    g, b, t, it, lv = _options(gamma, beta, tol, max_iter, max_subdivisions)
    spec, iso, m, ks, cs, cg, hts = _model(building)
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
    u_peak = np.zeros(runs)
    u_res = np.zeros(runs)
    drift = np.zeros((runs, nst))
    acc = np.zeros((runs, nst))
    vb = np.zeros(runs)
    e_iso = np.zeros(runs)
    e_err = np.zeros(runs)
    n_sub = np.zeros(runs, dtype=np.int64)
    if runs:
        batch(spec.code, P, float(iso.count), float(iso.length_scale), m, ks, cs, cg, hts,
              np.array(spec.initial_state, dtype=float), ag, h, g, b, t, it, lv, nb,
              status, u_peak, u_res, drift, acc, vb, e_iso, e_err, n_sub)
    ok = status == 0
    out = {
        "iso_disp_peak": u_peak,
        "iso_disp_residual": u_res,
        "drift_peak": drift,
        "floor_acc_peak": acc,
        "base_shear_peak": vb,
        "iso_energy": e_iso,
        "energy_error": e_err,
    }
    for arr in out.values():
        arr[~ok] = np.nan
    out["iso_disp_max_abs"] = u_peak.copy()
    out["subdivided_steps"] = n_sub
    out["status"] = status
    out["converged"] = ok
    return out
