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
kernel :mod:`structures.dynamics.newmark` does (see there for the predictor and corrector formulas).

Condensation onto the two base DOFs
-----------------------------------
The unidirectional condensation applies to each chain: with K_L,d = K_d + g/(b h) C_d +
1/(b h^2) M, phi_d = -K_ss,d^-1 K_s0,d (phi_d,0 = 1) and d_0,d = K_00,d + K_0s,d phi_d
(:func:`structures.dynamics.newmark_chain.condense`), the effective system K_eff du = R with
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
:mod:`structures.dynamics.newmark`, so the x response is the unidirectional one bit for bit wherever the
plan law is its unidirectional law bit for bit along the axis (bouc_wen: to rounding).

A step whose Newton iteration fails (no convergence in ``max_iter``, a law status < 0 or a
non-finite force) is retried from the committed state in 2, 4, ... 2^max_levels equal substeps
with both ground accelerations interpolated linearly.

Energy per direction (relative formulation, trapezoidal increments; :mod:`structures.dynamics.energy`,
:mod:`structures.dynamics.plan_energy`): E_I,d = -sum (1/2)(a_g,d,n + a_g,d,n+1) 1^T M du_d, viscous
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
from numba import njit

from rrfrei.laws.specialise import unbound
from structures.dynamics import newmark_chain as core
from structures.dynamics.blocks import run_blocks
from structures.dynamics.newmark_records import Layer
from structures.dynamics.plan_newmark_records import PlanHistories, PlanSummary

SLOTS = ("plan_step",)
plan_step = unbound("plan_step")


@njit(cache=True, nogil=True)
def integrate(chain_x, chain_y, layer, ag, dt, solver, hist):
    """One analysis from rest under the ground accelerations ``ag`` [m/s^2] every ``dt`` [s].

    Each direction's chain moves by the shared core :mod:`structures.dynamics.newmark_chain`, exactly as
    the unidirectional kernel moves its one chain; the 2 x 2 Newton iteration on the base DOFs,
    where the plan law is called, is written out here.

    Parameters
    ----------
    chain_x, chain_y : :class:`structures.dynamics.newmark_records.Chain` of each direction (the same
        ``mass`` and ``story_height``; stiffness and damping may differ).
    layer : :class:`structures.dynamics.newmark_records.Layer` (the coupled isolators; force
        count s^2 F_law(u / s, v / s), tangent count s k_law).
    ag : (nt, 2) ground acceleration (x, y) at the output steps [m/s^2].
    dt : output step [s].
    solver : :class:`structures.dynamics.newmark_records.Solver` (``robust`` unused).
    hist : :class:`structures.dynamics.plan_newmark_records.PlanHistories` with nt steps (written), or
        zero steps (peaks only).

    Returns
    -------
    :class:`structures.dynamics.plan_newmark_records.PlanSummary` (peaks, status, failing step).
    """
    m = chain_x.mass
    n = m.shape[0]
    ks = np.empty((2, n - 1))
    cs = np.empty((2, n - 1))
    cg = np.empty((2, n))
    for d, chain in enumerate((chain_x, chain_y)):
        ks[d] = chain.story_stiffness
        cs[d] = chain.story_damping
        cg[d] = chain.ground_damping
    params = layer.params
    inv_scale, force_scale, tangent_scale = core.layer_scales(layer)
    tol = solver.tol
    disp_h, accel_h, drift_h, drift_ratio_h = hist.disp, hist.accel, hist.drift, hist.drift_ratio
    force_h, shear_h, energy_h = hist.isolator_force, hist.base_shear, hist.energy
    nt = ag.shape[0]
    store = disp_h.shape[1] > 0
    work = np.zeros((core.N_WORK, 2, n))  # (row, direction, DOF)
    u, v, a, r, lower, ratio, inv_pivot, shape = core.work_rows(work)
    flex = np.zeros((2, n, n))  # K_ss^-1 per direction [m/kN] (see newmark_chain.condense)
    law = np.empty((2, layer.state0.shape[0]))  # the law's committed state, and before a subdivided step
    law[0] = layer.state0
    sc = law[0]
    st = layer.state0.copy()  # its trial state
    inv_height = 1.0 / chain_x.story_height  # [1/m]
    drift_max = np.zeros((2, n - 1))  # peak |story drift| [m]
    accel_max = np.zeros((2, n - 1))  # peak |absolute floor acceleration| [m/s^2]
    # committed scalars per direction (and their saved copy), see newmark_chain.N_SCALARS
    scal = np.zeros((2 * core.N_SCALARS, 2))
    f_c, e_input, e_viscous, e_isolator, ag_c = (scal[core.F_C], scal[core.E_INPUT], scal[core.E_VISCOUS],
                                                 scal[core.E_ISOLATOR], scal[core.AG_C])
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
        core.clear_first_step(disp_h[d], accel_h[d], drift_h[d], drift_ratio_h[d], force_h[d], shear_h[d],
                              energy_h[d])
    if store:
        hist.iterations[0] = 0
        hist.levels[0] = 0
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
        for level in range(solver.max_levels + 1):
            core.start_try(level, work, law, scal, st)
            nsub = 1 << level
            h = dt / nsub
            c1, c2, cv, cva, ca, cav = core.coefficients(solver, h)
            if h != h_condensed:
                for d, chain in enumerate((chain_x, chain_y)):
                    d0[d], phi2[d] = core.condense(chain, c1, c2, lower[d], ratio[d], inv_pivot[d], shape[d],
                                                   flex[d])
                h_condensed = h
            status = 0
            for sub in range(nsub):
                for d in range(2):
                    ag0 = ag[k - 1, d]
                    ag1 = ag[k, d]
                    agk[d] = ag1 if sub == nsub - 1 else ag0 + (ag1 - ag0) * (sub + 1) / nsub
                    r0[d] = core.linear_residual(m, ks[d], cs[d], cg[d], u[d], v[d], a[d], agk[d], cv, cva,
                                                 ca, cav, shape[d], r[d])
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
                for it in range(solver.max_iter + 1):
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
                                for d in range(2):
                                    norm2 = core.add_superstructure_norm(norm2, shape[d], flex[d], r[d],
                                                                         du[d])
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
                    finite = math.isfinite(norm2)
                    for d in range(2):
                        f[d] = force_scale * flaw[d]
                        finite = finite and math.isfinite(f[d])
                        for e in range(2):
                            kt[d, e] = tangent_scale * klaw[d, e]
                            finite = finite and math.isfinite(kt[d, e])
                    n_it += 1 if it > 0 else 0
                    status, stop = core.newton_verdict(status, finite, it, norm2, tol)
                    if stop:
                        break
                if status != 0:
                    break
                # -- commit each direction, with its energy increments (trapezoidal)
                for d in range(2):
                    e_isolator[d] += 0.5 * (f_c[d] + f[d]) * (ub[d] - u[d, 0])
                    de_input, de_viscous = core.commit(m, cs[d], cg[d], u[d], v[d], a[d], ub[d], vb[d], ab[d],
                                                       moved[d], shape[d], flex[d], r[d],
                                                       0.5 * (ag_c[d] + agk[d]), c1, c2, cv, cva, ca, cav)
                    e_input[d] += de_input
                    e_viscous[d] += de_viscous
                    f_c[d] = f[d]
                    ag_c[d] = agk[d]
                core.copy(st, sc)
            if status == 0:
                break
        if store:
            hist.iterations[k] = n_it
            hist.levels[k] = level
        if status != 0:
            if store:
                disp_h[:, k, :] = u
            return PlanSummary(status, k, plan_peak, u0_peak, 0.0, np.zeros(2), 0.0, 0.0, n_subdivided,
                               drift_max * inv_height, accel_max)
        if level > 0:
            n_subdivided += 1
        # -- output step k: stored energies, peaks, histories
        imbalance = 0.0
        e_in_total = 0.0
        for d in range(2):
            e_kinetic, e_strain, shear = core.output_step(m, ks[d], cs[d], u[d], v[d], a[d], ag[k, d],
                                                          inv_height, drift_max[d], accel_max[d], k,
                                                          disp_h[d], accel_h[d], drift_h[d], drift_ratio_h[d])
            u0_peak[d] = max(u0_peak[d], abs(u[d, 0]))
            shear_peak[d] = max(shear_peak[d], abs(shear))
            imbalance += e_input[d] - e_kinetic - e_viscous[d] - e_isolator[d] - e_strain
            e_in_total += e_input[d]
            if store:
                force_h[d, k] = f_c[d]
                shear_h[d, k] = shear
                for q, term in enumerate((e_input[d], e_kinetic, e_viscous[d], e_isolator[d], e_strain)):
                    energy_h[d, q, k] = term
        plan = math.sqrt(u[0, 0] * u[0, 0] + u[1, 0] * u[1, 0])
        plan_peak = max(plan_peak, plan)
        imbalance_max = max(imbalance_max, abs(imbalance))
        input_max = max(input_max, abs(e_in_total))
    energy_error = imbalance_max / input_max if input_max > 0.0 else 0.0
    plan_residual = math.sqrt(u[0, 0] * u[0, 0] + u[1, 0] * u[1, 0])
    return PlanSummary(0, -1, plan_peak, u0_peak, plan_residual, shear_peak,
                       e_isolator[0] + e_isolator[1], energy_error, n_subdivided, drift_max * inv_height,
                       accel_max)


def batch(chain_x, chain_y, layer, params, ag, dt, solver, n_blocks, out):
    """:func:`integrate` for every parameter row of ``params`` (runs, n_params), peaks only.

    The runs are split into ``n_blocks`` contiguous blocks run in parallel on
    ``numba.get_num_threads()`` threads (:func:`structures.dynamics.blocks.run_blocks`, as
    :func:`structures.dynamics.newmark.batch`: the compiled :func:`integrate` per run, no
    compilation of its own), one analysis per thread at a time; ``layer`` gives the bearings (its
    ``params`` unused).  Writes run r's :class:`structures.dynamics.plan_newmark_records.PlanSummary`
    into row r of the fields of ``out`` (:class:`structures.dynamics.plan_newmark_records.PlanBatch`).
    """
    none = PlanHistories.allocate(0, chain_x.mass.shape[0])  # peaks only (the type of full histories)
    fields = [getattr(out, f) for f in PlanSummary._fields]

    def one(run):
        s = integrate(chain_x, chain_y, Layer(params[run], layer.count, layer.scale, layer.state0), ag, dt,
                      solver, none)
        for field, value in zip(fields, s):
            field[run] = value

    run_blocks(one, params.shape[0], n_blocks)
