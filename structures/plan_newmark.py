"""Newmark + Newton for a shear building in plan on a coupled isolator (Numba kernel template).

Two chains ``[base, floor 1, ..., floor n]``, one per horizontal direction d = x, y
(displacements relative to the ground), with the same lumped masses, each with its own story
springs and dashpots, share one nonlinear element: the isolator layer between the ground and the
base slab, whose force F = (F_x, F_y) depends on both base displacements u_b = (u_0x, u_0y) and
their history (a plan law, :mod:`rrfrei.laws.plan`):

    M a_d + C_d v_d + K_d u_d + F_d(u_b, v_b) e_0 = -M 1 a_g,d(t),     d = x, y.

No torsion: each floor is one lumped mass at the centre of rigidity (no eccentricity, no
rotational DOF), so the directions couple only through the isolator.  Each step follows
OpenSees' ``Newmark`` (displacement form, ``SRC/analysis/integrator/Newmark.cpp`` l.157-255)
with ``Newton`` and ``NormDispIncr`` on the 2 (n + 1) horizontal DOFs, as the unidirectional
kernel :mod:`structures.newmark` does (see there for the predictor and corrector formulas).

Condensation onto the two base DOFs
-----------------------------------
The unidirectional condensation applies to each chain: with K_L,d = K_d + g/(b h) C_d +
1/(b h^2) M, phi_d = -K_ss,d^-1 K_s0,d (phi_d,0 = 1) and d_0,d = K_00,d + K_0s,d phi_d
(:func:`structures.newmark._condense`), the effective system K_eff du = R with
K_eff = blockdiag(K_L,x, K_L,y) + [k_t on the base DOFs (0x, 0y)] (k_t the isolator's 2 x 2
tangent dF_i/du_j) reduces to the 2 x 2 base system

    (diag(d_0,x, d_0,y) + k_t) du_b = r_b,   r_b,d = R_0,d + phi_d,s . R_s,d,
    du_s,d = K_ss,d^-1 R_s,d + phi_d,s du_b,d,

solved by elimination without pivoting (the pivot d_0,x + k_t,xx > 0 carries the mass term
1/(b h^2) m_0): du_y = (r_y - l r_x) / (a_yy - l a_xy), du_x = (r_x - a_xy du_y) / a_xx with
l = a_yx / a_xx.  As in 1-D, after the first correction of a step the residual lives on the base
DOFs alone, r_b = k_t,prev du_b,prev - (F - F_prev), and ||du||_2^2 = sum_d du_b,d^2 phi_d^T phi_d.
With no excitation and no force in y (a record along x on a layer whose plan law gives F_y = 0
and k_yx = 0 there), every y quantity is an exact zero and each x operation is that of
:mod:`structures.newmark`, so the x response is the unidirectional one bit for bit wherever the
plan law is its unidirectional law bit for bit along the axis (bouc_wen: to rounding).

A step whose Newton iteration fails (no convergence in ``max_iter``, a law status < 0 or a
non-finite force) is retried from the committed state in 2, 4, ... 2^max_levels equal substeps
with both ground accelerations interpolated linearly.

Energy per direction (relative formulation, trapezoidal increments; :mod:`structures.energy`,
:mod:`structures.plan_energy`): E_I,d = -sum (1/2)(a_g,d,n + a_g,d,n+1) 1^T M du_d, viscous
E_D,d = sum (1/2)(C v_n + C v_n+1)^T du_d, isolator E_H,d = sum (1/2)(F_d,n + F_d,n+1) du_0,d
(E_H,x + E_H,y = int F . du_b, the line integral in plan); kinetic and strain energies from the
state.  Each direction balances on its own (its equations of motion dotted with du_d).

Template
--------
The plan law is called through the slot ``plan_step`` (contract of
:mod:`rrfrei.laws.plan.registry`: ``step(p, sc, u, v, dt, st, f, k) -> status``), bound per law
by :func:`rrfrei.laws.specialise.instantiate`; call the kernels of an instance, never those of
this module.  ``Solver.robust`` is not used (the plan laws have no robust local solve).

Status codes: 0 converged; law codes (< 0, :data:`rrfrei.laws.STATUS_MESSAGES`); -3 non-finite
force or correction; -4 Newton did not converge even after subdivision.
"""

import math

import numpy as np
from numba import njit, prange

from rrfrei.laws.specialise import unbound
from structures.newmark import _condense
from structures.newmark_records import Layer
from structures.plan_newmark_records import PlanHistories, PlanSummary

SLOTS = ("plan_step",)
plan_step = unbound("plan_step")

# rows of the per-analysis work array (each (2, ndof): direction, DOF)
N_WORK = 11
(U, V, A,  # committed displacement, velocity, acceleration
 U_SAVED, V_SAVED, A_SAVED,  # the committed state before a subdivided step
 R,  # residual of the linear part at the predictor
 LOWER, RATIO, INV_PIVOT,  # scratch of the elimination in _condense
 SHAPE) = range(N_WORK)  # phi, the superstructure's correction per unit base correction


@njit(cache=True)
def integrate(chain_x, chain_y, layer, ag, dt, solver, hist):
    """One analysis from rest under the ground accelerations ``ag`` [m/s^2] every ``dt`` [s].

    Parameters
    ----------
    chain_x, chain_y : :class:`structures.newmark_records.Chain` of each direction (the same
        ``mass`` and ``story_height``; stiffness and damping may differ).
    layer : :class:`structures.newmark_records.Layer` (the coupled isolators; force
        count s^2 F_law(u / s, v / s), tangent count s k_law).
    ag : (nt, 2) ground acceleration (x, y) at the output steps [m/s^2].
    dt : output step [s].
    solver : :class:`structures.newmark_records.Solver` (``robust`` unused).
    hist : :class:`structures.plan_newmark_records.PlanHistories` with nt steps (written), or
        zero steps (peaks only).

    Returns
    -------
    :class:`structures.plan_newmark_records.PlanSummary` (peaks, status, failing step).
    """
    m = chain_x.mass
    n = m.shape[0]
    ks = np.empty((2, n - 1))
    cs = np.empty((2, n - 1))
    cg = np.empty((2, n))
    for j in range(n):
        cg[0, j] = chain_x.ground_damping[j]
        cg[1, j] = chain_y.ground_damping[j]
    for j in range(n - 1):
        ks[0, j] = chain_x.story_stiffness[j]
        ks[1, j] = chain_y.story_stiffness[j]
        cs[0, j] = chain_x.story_damping[j]
        cs[1, j] = chain_y.story_damping[j]
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
    iterations_h, levels_h = hist.iterations, hist.levels
    nt = ag.shape[0]
    store = disp_h.shape[1] > 0
    work = np.zeros((N_WORK, 2, n))
    u, v, a = work[U], work[V], work[A]
    u_saved, v_saved, a_saved = work[U_SAVED], work[V_SAVED], work[A_SAVED]
    r = work[R]
    lower, ratio, inv_pivot, shape = work[LOWER], work[RATIO], work[INV_PIVOT], work[SHAPE]
    flex = np.zeros((2, n, n))  # K_ss^-1 per direction [m/kN] (see _condense)
    nstate = layer.state0.shape[0]
    sc = layer.state0.copy()  # the law's committed state
    st = layer.state0.copy()  # its trial state
    sc_saved = layer.state0.copy()  # its committed state before a subdivided step
    inv_height = 1.0 / chain_x.story_height  # [1/m]
    drift_max = np.zeros((2, n - 1))  # peak |story drift| [m]
    accel_max = np.zeros((2, n - 1))  # peak |absolute floor acceleration| [m/s^2]
    # per-direction scalars, committed and saved: isolator force [kN], energies [kN m],
    # ground acceleration [m/s^2]
    scal = np.zeros((10, 2))
    f_c, e_input, e_viscous, e_isolator, ag_c = scal[0], scal[1], scal[2], scal[3], scal[4]
    f_c_sv, e_input_sv, e_viscous_sv, e_isolator_sv, ag_c_sv = scal[5], scal[6], scal[7], scal[8], scal[9]
    # Newton on the base: trial state and scratch (index: direction)
    nb = np.zeros((12, 2))
    ub, vb, ab, f, f_prev, du, moved, r0, agk, ulaw, vlaw, flaw = (
        nb[0], nb[1], nb[2], nb[3], nb[4], nb[5], nb[6], nb[7], nb[8], nb[9], nb[10], nb[11])
    kt = np.zeros((2, 2))  # isolator tangent [kN/m] at the trial state
    kt_prev = np.zeros((2, 2))  # and before the last correction
    klaw = np.zeros((2, 2))
    d0 = np.zeros(2)  # condensed base pivots [kN/m]
    phi2 = np.ones(2)  # phi^T phi per direction
    # ---- at rest, initial acceleration solved exactly: a_0 = -a_g(0) 1 (no force at rest)
    for d in range(2):
        ag_c[d] = ag[0, d]
        for j in range(n):
            a[d, j] = -ag[0, d]
    if store:
        for d in range(2):
            for j in range(n):
                disp_h[d, 0, j] = 0.0
                accel_h[d, 0, j] = 0.0
            for j in range(n - 1):
                drift_h[d, 0, j] = 0.0
                drift_ratio_h[d, 0, j] = 0.0
            force_h[d, 0] = 0.0
            shear_h[d, 0] = 0.0
            for q in range(energy_h.shape[1]):
                energy_h[d, q, 0] = 0.0
        iterations_h[0] = 0
        levels_h[0] = 0
    u0_peak = np.zeros(2)
    plan_peak = 0.0
    shear_peak = np.zeros(2)
    imbalance_max = 0.0
    input_max = 0.0
    n_subdivided = 0
    h_condensed = -1.0
    for k in range(1, nt):
        n_it = 0
        status = 0
        level = 0
        for level in range(max_levels + 1):
            if level == 1:  # the failed first try committed nothing: save the state at step k-1
                for d in range(2):
                    for j in range(n):
                        u_saved[d, j] = u[d, j]
                        v_saved[d, j] = v[d, j]
                        a_saved[d, j] = a[d, j]
                for q in range(nstate):
                    sc_saved[q] = sc[q]
                for d in range(2):
                    f_c_sv[d] = f_c[d]
                    ag_c_sv[d] = ag_c[d]
                    e_input_sv[d] = e_input[d]
                    e_viscous_sv[d] = e_viscous[d]
                    e_isolator_sv[d] = e_isolator[d]
            elif level > 1:  # restore it
                for d in range(2):
                    for j in range(n):
                        u[d, j] = u_saved[d, j]
                        v[d, j] = v_saved[d, j]
                        a[d, j] = a_saved[d, j]
                for q in range(nstate):
                    sc[q] = sc_saved[q]
                for d in range(2):
                    f_c[d] = f_c_sv[d]
                    ag_c[d] = ag_c_sv[d]
                    e_input[d] = e_input_sv[d]
                    e_viscous[d] = e_viscous_sv[d]
                    e_isolator[d] = e_isolator_sv[d]
            if level > 0:
                for q in range(nstate):
                    st[q] = sc[q]
            nsub = 1 << level
            h = dt / nsub
            c1 = gamma / (beta * h)  # dv/du of a correction
            c2 = 1.0 / (beta * h * h)  # da/du of a correction
            cv = 1.0 - gamma / beta  # predictor: v = cv v_n + cva a_n, a = ca a_n + cav v_n
            cva = h * (1.0 - gamma / (2.0 * beta))
            ca = 1.0 - 1.0 / (2.0 * beta)
            cav = -1.0 / (beta * h)
            if h != h_condensed:
                d0[0], phi2[0] = _condense(chain_x, c1, c2, lower[0], ratio[0], inv_pivot[0], shape[0],
                                           flex[0])
                d0[1], phi2[1] = _condense(chain_y, c1, c2, lower[1], ratio[1], inv_pivot[1], shape[1],
                                           flex[1])
                h_condensed = h
            status = 0
            for sub in range(nsub):
                for d in range(2):
                    ag0 = ag[k - 1, d]
                    ag1 = ag[k, d]
                    agk[d] = ag1 if sub == nsub - 1 else ag0 + (ag1 - ag0) * (sub + 1) / nsub
                # -- predictor, the residual of the linear part at it (R_0 without the isolator
                # force), and its condensation on the base r0 = R_0 + phi . R_s, per direction
                for d in range(2):
                    ag_d = agk[d]
                    v_below = cv * v[d, 0] + cva * a[d, 0]
                    r_below = -m[0] * (ag_d + ca * a[d, 0] + cav * v[d, 0]) - cg[d, 0] * v_below
                    rr = 0.0
                    for j in range(1, n):  # story j joins DOF j-1 and DOF j
                        vj = cv * v[d, j] + cva * a[d, j]
                        fs = ks[d, j - 1] * (u[d, j] - u[d, j - 1]) + cs[d, j - 1] * (vj - v_below)
                        r[d, j - 1] = r_below + fs
                        rr += shape[d, j - 1] * r[d, j - 1]
                        r_below = -m[j] * (ag_d + ca * a[d, j] + cav * v[d, j]) - cg[d, j] * vj - fs
                        v_below = vj
                    r[d, n - 1] = r_below
                    rr += shape[d, n - 1] * r_below
                    r0[d] = rr
                    # -- trial state of the base DOF
                    ub[d] = u[d, 0]
                    vb[d] = cv * v[d, 0] + cva * a[d, 0]
                    ab[d] = ca * a[d, 0] + cav * v[d, 0]
                    f[d] = 0.0
                    f_prev[d] = 0.0
                    du[d] = 0.0
                    moved[d] = 0.0
                    for e in range(2):
                        kt[d, e] = 0.0
                        kt_prev[d, e] = 0.0
                norm2 = 0.0  # squared 2-norm of the last correction [m^2]
                converged = False
                for it in range(max_iter + 1):
                    if it > 0:
                        if it == 1:  # the condensed residual of the predictor, r0 - F
                            rx = r0[0] - f[0]
                            ry = r0[1] - f[1]
                        else:  # the residual is on the base alone: k_t,prev du - (F - F_prev)
                            rx = (kt_prev[0, 0] * du[0] + kt_prev[0, 1] * du[1]) - (f[0] - f_prev[0])
                            ry = (kt_prev[1, 0] * du[0] + kt_prev[1, 1] * du[1]) - (f[1] - f_prev[1])
                        axx = d0[0] + kt[0, 0]
                        axy = kt[0, 1]
                        lyx = kt[1, 0] / axx
                        du[1] = (ry - lyx * rx) / ((d0[1] + kt[1, 1]) - lyx * axy)
                        du[0] = (rx - axy * du[1]) / axx
                        if it == 1:
                            norm2 = du[0] * du[0] + du[1] * du[1]
                            if norm2 < tol * tol:  # else not converged whatever the superstructure
                                for d in range(2):  # its correction K_ss^-1 R_s + phi du_0
                                    for j in range(1, n):
                                        dd = shape[d, j] * du[d]
                                        for i in range(1, n):
                                            dd += flex[d, j, i] * r[d, i]
                                        norm2 += dd * dd
                        else:
                            norm2 = du[0] * du[0] * phi2[0] + du[1] * du[1] * phi2[1]
                        for d in range(2):
                            ub[d] += du[d]
                            vb[d] += c1 * du[d]
                            ab[d] += c2 * du[d]
                            moved[d] += du[d]
                    # -- the isolator at the trial state (the only call of the law)
                    for d in range(2):
                        f_prev[d] = f[d]
                        for e in range(2):
                            kt_prev[d, e] = kt[d, e]
                        ulaw[d] = ub[d] * inv_scale
                        vlaw[d] = vb[d] * inv_scale
                    status = plan_step(params, sc, ulaw, vlaw, h, st, flaw, klaw)
                    for d in range(2):
                        f[d] = force_scale * flaw[d]
                        for e in range(2):
                            kt[d, e] = tangent_scale * klaw[d, e]
                    n_it += 1 if it > 0 else 0
                    if status != 0:
                        break
                    if not (math.isfinite(f[0]) and math.isfinite(f[1]) and math.isfinite(kt[0, 0])
                            and math.isfinite(kt[0, 1]) and math.isfinite(kt[1, 0])
                            and math.isfinite(kt[1, 1]) and math.isfinite(norm2)):
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
                for d in range(2):
                    agm = 0.5 * (ag_c[d] + agk[d])
                    du_j = ub[d] - u[d, 0]
                    de_input = -m[0] * agm * du_j
                    de_viscous = 0.5 * cg[d, 0] * (v[d, 0] + vb[d]) * du_j
                    e_isolator[d] += 0.5 * (f_c[d] + f[d]) * du_j
                    u_below, v_below = u[d, 0], v[d, 0]  # DOF j-1 before the step
                    u_below_t, v_below_t = ub[d], vb[d]  # and after
                    u[d, 0] = ub[d]
                    v[d, 0] = vb[d]
                    a[d, 0] = ab[d]
                    for j in range(1, n):
                        dd = shape[d, j] * moved[d]
                        for i in range(1, n):
                            dd += flex[d, j, i] * r[d, i]
                        uj = u[d, j] + dd
                        vj = cv * v[d, j] + cva * a[d, j] + c1 * dd
                        aj = ca * a[d, j] + cav * v[d, j] + c2 * dd
                        du_j = uj - u[d, j]
                        de_input -= m[j] * agm * du_j
                        de_viscous += 0.5 * cg[d, j] * (v[d, j] + vj) * du_j
                        ddr = (uj - u_below_t) - (u[d, j] - u_below)
                        de_viscous += 0.5 * cs[d, j - 1] * ((v[d, j] - v_below) + (vj - v_below_t)) * ddr
                        u_below, v_below = u[d, j], v[d, j]
                        u_below_t, v_below_t = uj, vj
                        u[d, j] = uj
                        v[d, j] = vj
                        a[d, j] = aj
                    e_input[d] += de_input
                    e_viscous[d] += de_viscous
                    f_c[d] = f[d]
                    ag_c[d] = agk[d]
                for q in range(nstate):
                    sc[q] = st[q]
            if status == 0:
                break
        if store:
            iterations_h[k] = n_it
            levels_h[k] = level
        if status != 0:
            if store:
                for d in range(2):
                    for j in range(n):
                        disp_h[d, k, j] = u[d, j]
            return PlanSummary(status, k, plan_peak, u0_peak, 0.0, np.zeros(2), 0.0, 0.0, n_subdivided,
                               drift_max * inv_height, accel_max)
        if level > 0:
            n_subdivided += 1
        # -- output step k: stored energies, peaks, histories
        imbalance = 0.0
        e_in_total = 0.0
        for d in range(2):
            ag1 = ag[k, d]
            e_kinetic = 0.5 * m[0] * v[d, 0] * v[d, 0]
            e_strain = 0.0
            if store:
                disp_h[d, k, 0] = u[d, 0]
                accel_h[d, k, 0] = a[d, 0] + ag1
            for j in range(1, n):
                e_kinetic += 0.5 * m[j] * v[d, j] * v[d, j]
                dr = u[d, j] - u[d, j - 1]
                e_strain += 0.5 * ks[d, j - 1] * dr * dr
                if abs(dr) > drift_max[d, j - 1]:
                    drift_max[d, j - 1] = abs(dr)
                aa = abs(a[d, j] + ag1)
                if aa > accel_max[d, j - 1]:
                    accel_max[d, j - 1] = aa
                if store:
                    disp_h[d, k, j] = u[d, j]
                    accel_h[d, k, j] = a[d, j] + ag1
                    drift_h[d, k, j - 1] = dr
                    drift_ratio_h[d, k, j - 1] = dr * inv_height[j - 1]
            if abs(u[d, 0]) > u0_peak[d]:
                u0_peak[d] = abs(u[d, 0])
            shear = ks[d, 0] * (u[d, 1] - u[d, 0]) + cs[d, 0] * (v[d, 1] - v[d, 0])
            if abs(shear) > shear_peak[d]:
                shear_peak[d] = abs(shear)
            imbalance += e_input[d] - e_kinetic - e_viscous[d] - e_isolator[d] - e_strain
            e_in_total += e_input[d]
            if store:
                force_h[d, k] = f_c[d]
                shear_h[d, k] = shear
                energy_h[d, 0, k] = e_input[d]
                energy_h[d, 1, k] = e_kinetic
                energy_h[d, 2, k] = e_viscous[d]
                energy_h[d, 3, k] = e_isolator[d]
                energy_h[d, 4, k] = e_strain
        plan = math.sqrt(u[0, 0] * u[0, 0] + u[1, 0] * u[1, 0])
        if plan > plan_peak:
            plan_peak = plan
        if abs(imbalance) > imbalance_max:
            imbalance_max = abs(imbalance)
        if abs(e_in_total) > input_max:
            input_max = abs(e_in_total)
    energy_error = imbalance_max / input_max if input_max > 0.0 else 0.0
    plan_residual = math.sqrt(u[0, 0] * u[0, 0] + u[1, 0] * u[1, 0])
    return PlanSummary(0, -1, plan_peak, u0_peak, plan_residual, shear_peak,
                       e_isolator[0] + e_isolator[1], energy_error, n_subdivided, drift_max * inv_height,
                       accel_max)


@njit(cache=True, parallel=True)
def batch(chain_x, chain_y, layer, params, ag, dt, solver, n_blocks, out):
    """:func:`integrate` for every parameter row of ``params`` (runs, n_params), peaks only.

    The runs are split into ``n_blocks`` contiguous blocks run in parallel (Numba ``prange``),
    one analysis per thread at a time; ``layer`` gives the bearings (its ``params`` unused).
    Writes run r's :class:`structures.plan_newmark_records.PlanSummary` into row r of the fields
    of ``out`` (:class:`structures.plan_newmark_records.PlanBatch`).
    """
    runs = params.shape[0]
    n = chain_x.mass.shape[0]
    none = PlanHistories(np.empty((2, 0, n)), np.empty((2, 0, n)), np.empty((2, 0, n - 1)),
                         np.empty((2, 0, n - 1)), np.empty((2, 0)), np.empty((2, 0)),
                         np.empty((2, 5, 0)), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64))
    # (the result arrays are taken out of ``out`` first: Numba loses writes made through a named
    # tuple's field inside ``prange``)
    status, plan_peak, iso_peak, plan_residual = (out.status, out.iso_plan_disp_peak, out.iso_disp_peak,
                                                  out.iso_plan_disp_residual)
    shear_peak, iso_work, energy_error = out.base_shear_peak, out.iso_work, out.energy_error
    subdivided, drift_peak, accel_peak = out.subdivided_steps, out.drift_peak, out.accel_peak
    for b in prange(n_blocks):
        lo = (runs * b) // n_blocks
        hi = (runs * (b + 1)) // n_blocks
        for run in range(lo, hi):
            one = Layer(params[run], layer.count, layer.scale, layer.state0)
            s = integrate(chain_x, chain_y, one, ag, dt, solver, none)
            status[run] = s.status
            plan_peak[run] = s.iso_plan_disp_peak
            plan_residual[run] = s.iso_plan_disp_residual
            iso_work[run] = s.iso_work
            energy_error[run] = s.energy_error
            subdivided[run] = s.subdivided_steps
            for d in range(2):
                iso_peak[run, d] = s.iso_disp_peak[d]
                shear_peak[run, d] = s.base_shear_peak[d]
                for i in range(n - 1):
                    drift_peak[run, d, i] = s.drift_peak[d, i]
                    accel_peak[run, d, i] = s.accel_peak[d, i]
