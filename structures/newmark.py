"""Newmark time stepping with Newton-Raphson on the isolator tangent (Numba kernel template).

The chain ``[base, floor 1, ..., floor n]`` (displacements relative to the ground) obeys

    M a + C v + K_s u + F_iso(u_0, v_0) e_0 = -M 1 a_g(t)

with story springs/dashpots between neighbouring DOFs and the isolator layer between the ground
and the base (DOF 0).  Each step follows OpenSees' ``Newmark`` (displacement form,
``SRC/analysis/integrator/Newmark.cpp`` l.157-255) with ``Newton`` and ``NormDispIncr``:

1. predictor u = u_n, v = (1 - g/b) v_n + h (1 - g/(2b)) a_n, a = (1 - 1/(2b)) a_n - v_n/(b h),
   then the isolator is updated at that trial state;
2. Newton: K_eff du = R = p_{n+1} - M a - C v - K_s u - F_iso e_0 with
   K_eff = K_L + k_t e_0 e_0^T,  K_L = K_s + g/(b h) C + 1/(b h^2) M;
3. u += du, v += g/(b h) du, a += du/(b h^2), isolator update; converged when ||du||_2 < tol;
4. commit (the law's trial state becomes its committed state).

Condensation onto the base
--------------------------
The isolator is the only nonlinear element, so the Newton iterates have a closed form in all but
one unknown.  Since R is affine in u apart from F_iso, the residual after a correction du
(solved with the tangent k_t) is

    R(u + du) = R(u) - K_L du - (F_new - F) e_0 = (k_t du_0 - (F_new - F)) e_0,

i.e. after the first correction of a step the residual lives on the base DOF alone.  Split
K_L into its base row/column and the superstructure block K_ss (tridiagonal); with
phi = -K_ss^-1 K_s0 (phi_0 = 1, the superstructure's response to a unit base correction) and
d_0 = K_00 + K_0s phi (the condensed base stiffness), ``K_eff du = R`` reads

    du_0 = (R_0 + phi_s . R_s) / (d_0 + k_t),    du_s = K_ss^-1 R_s + phi_s du_0,

and for a residual on the base alone du = phi du_0, ||du||_2 = |du_0| sqrt(phi^T phi).  So a step
costs one residual of the linear part at the predictor (R_s does not depend on the isolator),
a scalar Newton iteration on the base DOF (every isolator call, and every correction, is
O(1)), and one move of the superstructure by K_ss^-1 R_s + phi (sum of the du_0) at the commit.
These are OpenSees' iterates (same corrections, same norm) up to rounding; d_0, phi and
K_ss^-1 (dense: no serial substitution in the step) depend on the step size only and are
computed when it changes.  The norm of the first correction needs du_s only when |du_0| < tol
(otherwise it cannot converge).

A step whose Newton iteration fails (no convergence in ``max_iter``, a law status < 0 or a
non-finite force) is retried from the committed state in 2, 4, ... 2^max_levels equal substeps
with the ground acceleration interpolated linearly.

Energy (relative formulation, trapezoidal increments, exact for g = 1/2, b = 1/4 up to the
Newton tolerance): input E_I = -sum (1/2)(a_g,n + a_g,n+1) 1^T M du, viscous E_D = sum
(1/2)(C v_n + C v_n+1)^T du, isolator work E_H = sum (1/2)(F_n + F_n+1) du_0; the kinetic and
recoverable strain energies are evaluated from the state.

Template
--------
The isolator law is called through the slots ``law_step`` and ``law_step_robust`` (contract of
:mod:`rrfrei.laws.registry`: ``(p, sc, u, v, dt, st) -> (force, tangent, status)``), bound per
law by :func:`rrfrei.laws.specialise.instantiate`; call the kernels of an instance, never those
of this module.  ``law_step_robust`` is used at the last subdivision level when
``Solver.robust``; a positive status from it marks a step where it deviated from OpenSees.

Status codes: 0 converged; law codes (< 0, :data:`rrfrei.laws.STATUS_MESSAGES`); -3 non-finite
force or correction; -4 Newton did not converge even after subdivision.
"""

import math

import numpy as np
from numba import njit, prange

from rrfrei.laws.specialise import unbound
from structures.newmark_records import N_ENERGY, Histories, Layer, Summary

SLOTS = ("law_step", "law_step_robust")
law_step = unbound("law_step")
law_step_robust = unbound("law_step_robust")

# rows of the per-analysis work array (each of length ndof)
N_WORK = 11
(U, V, A,  # committed displacement, velocity, acceleration
 U_SAVED, V_SAVED, A_SAVED,  # the committed state before a subdivided step
 R,  # residual of the linear part at the predictor
 LOWER, RATIO, INV_PIVOT,  # scratch of the elimination in _condense
 SHAPE) = range(N_WORK)  # phi, the superstructure's correction per unit base correction


@njit(cache=True)
def _condense(chain, c1, c2, lower, ratio, inv_pivot, shape, flex):
    """Condense K_L = K_s + c1 C + c2 M onto the base DOF.

    Eliminates K_L from the roof down (scratch: for DOF j >= 1 the coupling ``lower[j]`` of DOFs
    j-1 and j, the factors ``ratio[j] = lower[j] / d'_j`` and ``inv_pivot[j] = 1 / d'_j``), and
    writes ``shape`` = phi, the superstructure's correction per unit base correction (phi_0 = 1,
    phi_j = -ratio[j] phi_{j-1}, i.e. -K_ss^-1 K_s0), and ``flex`` = K_ss^-1, the flexibility of
    the superstructure with the base held still (row and column 0 zero).  The condensed base
    residual of a residual R is then R_0 + phi . R_s and the superstructure's correction for a
    base correction du_0 is K_ss^-1 R_s + phi du_0.

    Returns
    -------
    (d_0, phi^T phi) : the condensed base pivot [kN/m] (without the isolator tangent) and the
    squared norm of phi.
    """
    m = chain.mass
    ks = chain.story_stiffness
    cs = chain.story_damping
    cg = chain.ground_damping
    n = m.shape[0]
    d0 = 0.0
    for j in range(n - 1, -1, -1):
        dj = c2 * m[j] + c1 * cg[j]
        if j < n - 1:
            dj += ks[j] + c1 * cs[j]  # story j+1 above DOF j
        if j > 0:
            lj = -(ks[j - 1] + c1 * cs[j - 1])  # story j below DOF j
            dj -= lj
            lower[j] = lj
        if j < n - 1:
            dj -= lower[j + 1] * ratio[j + 1]
        if j > 0:
            inv_pivot[j] = 1.0 / dj
            ratio[j] = lower[j] / dj
        else:
            d0 = dj
    shape[0] = 1.0
    norm2 = 1.0
    for j in range(1, n):
        shape[j] = -ratio[j] * shape[j - 1]
        norm2 += shape[j] * shape[j]
    for k in range(n):  # column k of K_ss^-1: eliminate e_k from the roof down, back-substitute
        flex[0, k] = 0.0
        flex[k, 0] = 0.0
    for k in range(1, n):
        below = 0.0
        for j in range(n - 1, 0, -1):
            below = (1.0 if j == k else 0.0) - (ratio[j + 1] * below if j < n - 1 else 0.0)
            flex[j, k] = below  # r'_j
        x = 0.0
        for j in range(1, n):
            x = (flex[j, k] - lower[j] * x) * inv_pivot[j]
            flex[j, k] = x
    return d0, norm2


@njit(cache=True)
def integrate(chain, layer, ag, dt, solver, hist):
    """One analysis from rest under the ground acceleration ``ag`` [m/s^2] every ``dt`` [s].

    Parameters
    ----------
    chain : :class:`structures.newmark_records.Chain` (the superstructure).
    layer : :class:`structures.newmark_records.Layer` (the isolators).
    ag : (nt,) ground acceleration at the output steps [m/s^2].
    dt : output step [s].
    solver : :class:`structures.newmark_records.Solver`.
    hist : :class:`structures.newmark_records.Histories` with nt rows (written), or zero rows
        (peaks only).

    Returns
    -------
    :class:`structures.newmark_records.Summary` (peaks, status, failing step).
    """
    # (arrays are taken out of the records once: reading one inside the loops would cost a
    # reference count increment and decrement each time)
    m = chain.mass
    ks = chain.story_stiffness
    cs = chain.story_damping
    cg = chain.ground_damping
    params = layer.params
    inv_scale = 1.0 / layer.scale  # the law sees u / s, v / s and gives count s^2 F, count s k
    force_scale = layer.count * layer.scale * layer.scale
    tangent_scale = layer.count * layer.scale
    gamma = solver.gamma
    beta = solver.beta
    max_iter = solver.max_iter
    max_levels = solver.max_levels
    tol = solver.tol
    disp_h, accel_h, drift_h, drift_ratio_h = hist.disp, hist.accel, hist.drift, hist.drift_ratio
    force_h, shear_h, energy_h = hist.isolator_force, hist.base_shear, hist.energy
    iterations_h, levels_h, robust_h = hist.iterations, hist.levels, hist.robust
    n = m.shape[0]
    nt = ag.shape[0]
    store = disp_h.shape[0] > 0
    work = np.zeros((N_WORK, n))
    u, v, a = work[U], work[V], work[A]
    u_saved, v_saved, a_saved = work[U_SAVED], work[V_SAVED], work[A_SAVED]
    r = work[R]
    lower, ratio, inv_pivot, shape = work[LOWER], work[RATIO], work[INV_PIVOT], work[SHAPE]
    flex = np.zeros((n, n))  # K_ss^-1 [m/kN] (see _condense)
    nstate = layer.state0.shape[0]
    sc = layer.state0.copy()  # the law's committed state
    st = layer.state0.copy()  # its trial state
    sc_saved = layer.state0.copy()  # its committed state before a subdivided step
    inv_height = 1.0 / chain.story_height  # [1/m]
    drift_max = np.zeros(n - 1)  # peak |story drift| [m]
    accel_max = np.zeros(n - 1)  # peak |absolute floor acceleration| [m/s^2]
    # ---- at rest, initial acceleration solved exactly: a_0 = -a_g(0) 1 (no force at rest)
    for j in range(n):
        a[j] = -ag[0]
    if store:
        for j in range(n):
            disp_h[0, j] = 0.0
            accel_h[0, j] = 0.0
        for j in range(n - 1):
            drift_h[0, j] = 0.0
            drift_ratio_h[0, j] = 0.0
        force_h[0] = 0.0
        shear_h[0] = 0.0
        for q in range(energy_h.shape[0]):
            energy_h[q, 0] = 0.0
        iterations_h[0] = 0
        levels_h[0] = 0
        robust_h[0] = False
    # committed scalars: isolator force [kN], energies [kN m], ground acceleration [m/s^2]
    f_c = 0.0
    e_input = 0.0
    e_viscous = 0.0
    e_isolator = 0.0
    ag_c = ag[0]
    f_c_saved, ag_c_saved = f_c, ag_c
    e_input_saved, e_viscous_saved, e_isolator_saved = e_input, e_viscous, e_isolator
    u0_peak = 0.0
    shear_peak = 0.0
    imbalance_max = 0.0
    input_max = 0.0
    n_subdivided = 0
    n_robust = 0
    h_condensed = -1.0
    d0 = 0.0
    phi2 = 1.0
    for k in range(1, nt):
        ag0 = ag[k - 1]
        ag1 = ag[k]
        n_it = 0
        status = 0
        level = 0
        deviated = False
        for level in range(max_levels + 1):
            if level == 1:  # the failed first try committed nothing: save the state at step k-1
                for j in range(n):
                    u_saved[j] = u[j]
                    v_saved[j] = v[j]
                    a_saved[j] = a[j]
                for q in range(nstate):
                    sc_saved[q] = sc[q]
                f_c_saved, ag_c_saved = f_c, ag_c
                e_input_saved, e_viscous_saved, e_isolator_saved = e_input, e_viscous, e_isolator
            elif level > 1:  # restore it
                for j in range(n):
                    u[j] = u_saved[j]
                    v[j] = v_saved[j]
                    a[j] = a_saved[j]
                for q in range(nstate):
                    sc[q] = sc_saved[q]
                f_c, ag_c = f_c_saved, ag_c_saved
                e_input, e_viscous, e_isolator = e_input_saved, e_viscous_saved, e_isolator_saved
            if level > 0:
                for q in range(nstate):
                    st[q] = sc[q]
            robust = solver.robust and level == max_levels
            nsub = 1 << level
            h = dt / nsub
            c1 = gamma / (beta * h)  # dv/du of a correction
            c2 = 1.0 / (beta * h * h)  # da/du of a correction
            cv = 1.0 - gamma / beta  # predictor: v = cv v_n + cva a_n, a = ca a_n + cav v_n
            cva = h * (1.0 - gamma / (2.0 * beta))
            ca = 1.0 - 1.0 / (2.0 * beta)
            cav = -1.0 / (beta * h)
            if h != h_condensed:
                d0, phi2 = _condense(chain, c1, c2, lower, ratio, inv_pivot, shape, flex)
                h_condensed = h
            status = 0
            for sub in range(nsub):
                agk = ag1 if sub == nsub - 1 else ag0 + (ag1 - ag0) * (sub + 1) / nsub
                # -- predictor, the residual of the linear part at it (R_0 without the isolator
                # force), and its condensation on the base r0 = R_0 + phi . R_s.  Predicted
                # superstructure values are recomputed from (u, v, a) at the commit.
                v_below = cv * v[0] + cva * a[0]
                r_below = -m[0] * (agk + ca * a[0] + cav * v[0]) - cg[0] * v_below
                r0 = 0.0
                for j in range(1, n):  # story j joins DOF j-1 and DOF j
                    vj = cv * v[j] + cva * a[j]
                    fs = ks[j - 1] * (u[j] - u[j - 1]) + cs[j - 1] * (vj - v_below)
                    r[j - 1] = r_below + fs
                    r0 += shape[j - 1] * r[j - 1]
                    r_below = -m[j] * (agk + ca * a[j] + cav * v[j]) - cg[j] * vj - fs
                    v_below = vj
                r[n - 1] = r_below
                r0 += shape[n - 1] * r_below
                # -- Newton on the base: trial state of DOF 0
                u0 = u[0]
                v0 = cv * v[0] + cva * a[0]
                a0 = ca * a[0] + cav * v[0]
                f = kt = 0.0  # isolator force [kN] and tangent [kN/m] at the trial state
                f_prev = kt_prev = 0.0  # and before the last correction
                du0 = 0.0  # base correction of the last iteration [m]
                moved = 0.0  # sum of the base corrections [m]
                norm2 = 0.0  # squared 2-norm of the last correction [m^2]
                converged = False
                for it in range(max_iter + 1):
                    if it > 0:
                        if it == 1:  # the condensed residual of the predictor, r0 - F
                            du0 = (r0 - f) / (d0 + kt)
                            norm2 = du0 * du0
                            if norm2 < tol * tol:  # else not converged whatever the superstructure
                                for j in range(1, n):  # its correction K_ss^-1 R_s + phi du_0
                                    d = shape[j] * du0
                                    for i in range(1, n):
                                        d += flex[j, i] * r[i]
                                    norm2 += d * d
                        else:  # the residual is on the base alone: r_0 = k_t du_0 - (F - F_prev)
                            du0 = (kt_prev * du0 - (f - f_prev)) / (d0 + kt)
                            norm2 = du0 * du0 * phi2
                        u0 += du0
                        v0 += c1 * du0
                        a0 += c2 * du0
                        moved += du0
                    # -- the isolator at the trial state (the only call of the law); written
                    # out here, not in a helper, which would cost reference counting per call
                    f_prev = f
                    kt_prev = kt
                    if robust:
                        fl, kl, status = law_step_robust(params, sc, u0 * inv_scale, v0 * inv_scale, h, st)
                        if status > 0:  # the robust solve acted: a deviation from OpenSees
                            status = 0
                            deviated = True
                    else:
                        fl, kl, status = law_step(params, sc, u0 * inv_scale, v0 * inv_scale, h, st)
                    f = force_scale * fl
                    kt = tangent_scale * kl
                    n_it += 1 if it > 0 else 0
                    if status != 0:
                        break
                    if not (math.isfinite(f) and math.isfinite(kt) and math.isfinite(norm2)):
                        status = -3
                        break
                    if it > 0 and math.sqrt(norm2) < tol:
                        converged = True
                        break
                if status == 0 and not converged:
                    status = -4
                if status != 0:
                    break
                # -- commit, with the energy increments (trapezoidal): the superstructure moves
                # by its predictor plus K_ss^-1 R_s + phi (sum of the base corrections)
                agm = 0.5 * (ag_c + agk)
                du_j = u0 - u[0]
                de_input = -m[0] * agm * du_j
                de_viscous = 0.5 * cg[0] * (v[0] + v0) * du_j
                e_isolator += 0.5 * (f_c + f) * du_j
                u_below, v_below = u[0], v[0]  # DOF j-1 before the step
                u_below_t, v_below_t = u0, v0  # and after
                u[0] = u0
                v[0] = v0
                a[0] = a0
                for j in range(1, n):
                    d = shape[j] * moved
                    for i in range(1, n):
                        d += flex[j, i] * r[i]
                    uj = u[j] + d
                    vj = cv * v[j] + cva * a[j] + c1 * d
                    aj = ca * a[j] + cav * v[j] + c2 * d
                    du_j = uj - u[j]
                    de_input -= m[j] * agm * du_j
                    de_viscous += 0.5 * cg[j] * (v[j] + vj) * du_j
                    dd = (uj - u_below_t) - (u[j] - u_below)
                    de_viscous += 0.5 * cs[j - 1] * ((v[j] - v_below) + (vj - v_below_t)) * dd
                    u_below, v_below = u[j], v[j]
                    u_below_t, v_below_t = uj, vj
                    u[j] = uj
                    v[j] = vj
                    a[j] = aj
                e_input += de_input
                e_viscous += de_viscous
                f_c = f
                ag_c = agk
                for q in range(nstate):
                    sc[q] = st[q]
            if status == 0:
                break
        if store:
            iterations_h[k] = n_it
            levels_h[k] = level
            robust_h[k] = deviated
        if status != 0:
            if store:
                for j in range(n):
                    disp_h[k, j] = u[j]
            return Summary(status, k, u0_peak, 0.0, 0.0, 0.0, 0.0, n_subdivided, n_robust,
                           drift_max * inv_height, accel_max)
        if level > 0:
            n_subdivided += 1
        if deviated:
            n_robust += 1
        # -- output step k: stored energies, peaks, histories
        e_kinetic = 0.5 * m[0] * v[0] * v[0]
        e_strain = 0.0
        if store:
            disp_h[k, 0] = u[0]
            accel_h[k, 0] = a[0] + ag1
        for j in range(1, n):
            e_kinetic += 0.5 * m[j] * v[j] * v[j]
            d = u[j] - u[j - 1]
            e_strain += 0.5 * ks[j - 1] * d * d
            if abs(d) > drift_max[j - 1]:
                drift_max[j - 1] = abs(d)
            aa = abs(a[j] + ag1)
            if aa > accel_max[j - 1]:
                accel_max[j - 1] = aa
            if store:
                disp_h[k, j] = u[j]
                accel_h[k, j] = a[j] + ag1
                drift_h[k, j - 1] = d
                drift_ratio_h[k, j - 1] = d * inv_height[j - 1]
        if abs(u[0]) > u0_peak:
            u0_peak = abs(u[0])
        shear = ks[0] * (u[1] - u[0]) + cs[0] * (v[1] - v[0])
        if abs(shear) > shear_peak:
            shear_peak = abs(shear)
        imbalance = abs(e_input - e_kinetic - e_viscous - e_isolator - e_strain)
        if imbalance > imbalance_max:
            imbalance_max = imbalance
        if abs(e_input) > input_max:
            input_max = abs(e_input)
        if store:
            force_h[k] = f_c
            shear_h[k] = shear
            energy_h[0, k] = e_input
            energy_h[1, k] = e_kinetic
            energy_h[2, k] = e_viscous
            energy_h[3, k] = e_isolator
            energy_h[4, k] = e_strain
    energy_error = imbalance_max / input_max if input_max > 0.0 else 0.0
    return Summary(0, -1, u0_peak, abs(u[0]), shear_peak, e_isolator, energy_error, n_subdivided,
                   n_robust, drift_max * inv_height, accel_max)


@njit(cache=True, parallel=True)
def batch(chain, layer, params, ag, dt, solver, n_blocks, out):
    """:func:`integrate` for every parameter row of ``params`` (runs, n_params), peaks only.

    The runs are split into ``n_blocks`` contiguous blocks run in parallel (Numba ``prange``),
    one analysis per thread at a time; ``layer`` gives the bearings (its ``params`` unused).
    Writes run r's :class:`structures.newmark_records.Summary` into row r of the fields of
    ``out`` (:class:`structures.newmark_records.Batch`).
    """
    runs = params.shape[0]
    n = chain.mass.shape[0]
    none = Histories(np.empty((0, n)), np.empty((0, n)), np.empty((0, n - 1)), np.empty((0, n - 1)),
                     np.empty(0), np.empty(0), np.empty((N_ENERGY, 0)), np.empty(0, dtype=np.int64),
                     np.empty(0, dtype=np.int64), np.empty(0, dtype=np.bool_))
    # (the result arrays are taken out of ``out`` first: Numba (0.68) loses writes made through a
    # named tuple's field inside ``prange``)
    status, iso_disp_peak, iso_disp_residual = out.status, out.iso_disp_peak, out.iso_disp_residual
    base_shear_peak, iso_work, energy_error = out.base_shear_peak, out.iso_work, out.energy_error
    subdivided, robust, drift_peak, accel_peak = (out.subdivided_steps, out.robust_steps, out.drift_peak,
                                                  out.accel_peak)
    for b in prange(n_blocks):
        lo = (runs * b) // n_blocks
        hi = (runs * (b + 1)) // n_blocks
        for run in range(lo, hi):
            one = Layer(params[run], layer.count, layer.scale, layer.state0)
            s = integrate(chain, one, ag, dt, solver, none)
            status[run] = s.status
            iso_disp_peak[run] = s.iso_disp_peak
            iso_disp_residual[run] = s.iso_disp_residual
            base_shear_peak[run] = s.base_shear_peak
            iso_work[run] = s.iso_work
            energy_error[run] = s.energy_error
            subdivided[run] = s.subdivided_steps
            robust[run] = s.robust_steps
            for i in range(n - 1):
                drift_peak[run, i] = s.drift_peak[i]
                accel_peak[run, i] = s.accel_peak[i]
