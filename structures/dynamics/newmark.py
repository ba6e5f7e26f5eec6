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

Shared core
-----------
The chain's part of the step (condensation, predictor residual, commit with energy, output step,
convergence rule) is :mod:`structures.dynamics.newmark_chain`, which the plan kernel
(:mod:`structures.dynamics.plan_newmark`) calls per direction; this module holds what is its own: the
scalar Newton iteration on the base DOF and the calls of the law.

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
from numba import njit

from rrfrei.laws.specialise import unbound
from structures.dynamics import newmark_chain as core
from structures.dynamics.blocks import run_blocks
from structures.dynamics.newmark_records import Histories, Layer, Summary

SLOTS = ("law_step", "law_step_robust")
law_step = unbound("law_step")
law_step_robust = unbound("law_step_robust")


@njit(cache=True, nogil=True)
def integrate(chain, layer, ag, dt, solver, hist):
    """One analysis from rest under the ground acceleration ``ag`` [m/s^2] every ``dt`` [s].

    The chain moves by the shared core :mod:`structures.dynamics.newmark_chain`; the Newton iteration on
    the base DOF, where the isolator law is called, is written out here.

    Parameters
    ----------
    chain : :class:`structures.dynamics.newmark_records.Chain` (the superstructure).
    layer : :class:`structures.dynamics.newmark_records.Layer` (the isolators).
    ag : (nt,) ground acceleration at the output steps [m/s^2].
    dt : output step [s].
    solver : :class:`structures.dynamics.newmark_records.Solver`.
    hist : :class:`structures.dynamics.newmark_records.Histories` with nt rows (written), or zero rows
        (peaks only).

    Returns
    -------
    :class:`structures.dynamics.newmark_records.Summary` (peaks, status, failing step).
    """
    # (arrays are taken out of the records once: reading one inside the loops would cost a
    # reference count increment and decrement each time)
    m = chain.mass
    ks = chain.story_stiffness
    cs = chain.story_damping
    cg = chain.ground_damping
    params = layer.params
    inv_scale, force_scale, tangent_scale = core.layer_scales(layer)
    tol = solver.tol
    disp_h, accel_h, drift_h, drift_ratio_h = hist.disp, hist.accel, hist.drift, hist.drift_ratio
    force_h, shear_h, energy_h = hist.isolator_force, hist.base_shear, hist.energy
    iterations_h, levels_h, robust_h = hist.iterations, hist.levels, hist.robust
    n = m.shape[0]
    nt = ag.shape[0]
    store = disp_h.shape[0] > 0
    work = np.zeros((core.N_WORK, n))
    u, v, a, r, lower, ratio, inv_pivot, shape = core.work_rows(work)
    flex = np.zeros((n, n))  # K_ss^-1 [m/kN] (see newmark_chain.condense)
    law = np.empty((2, layer.state0.shape[0]))  # the law's committed state, and before a subdivided step
    law[0] = layer.state0
    sc = law[0]
    st = layer.state0.copy()  # its trial state
    inv_height = 1.0 / chain.story_height  # [1/m]
    drift_max = np.zeros(n - 1)  # peak |story drift| [m]
    accel_max = np.zeros(n - 1)  # peak |absolute floor acceleration| [m/s^2]
    # ---- at rest, initial acceleration solved exactly: a_0 = -a_g(0) 1 (no force at rest)
    for j in range(n):
        a[j] = -ag[0]
    core.clear_first_step(disp_h, accel_h, drift_h, drift_ratio_h, force_h, shear_h, energy_h)
    if store:
        iterations_h[0] = 0
        levels_h[0] = 0
        robust_h[0] = False
    # committed scalars (and their saved copy), see newmark_chain.N_SCALARS
    scal = np.zeros(2 * core.N_SCALARS)
    scal[core.AG_C] = ag[0]
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
        for level in range(solver.max_levels + 1):
            core.start_try(level, work, law, scal, st)
            robust = solver.robust and level == solver.max_levels
            nsub = 1 << level
            h = dt / nsub
            c1, c2, cv, cva, ca, cav = core.coefficients(solver, h)
            if h != h_condensed:
                d0, phi2 = core.condense(chain, c1, c2, lower, ratio, inv_pivot, shape, flex)
                h_condensed = h
            status = 0
            for sub in range(nsub):
                agk = ag1 if sub == nsub - 1 else ag0 + (ag1 - ag0) * (sub + 1) / nsub
                r0 = core.linear_residual(m, ks, cs, cg, u, v, a, agk, cv, cva, ca, cav, shape, r)
                # -- Newton on the base: trial state of DOF 0
                u0 = u[0]
                v0 = cv * v[0] + cva * a[0]
                a0 = ca * a[0] + cav * v[0]
                f = kt = 0.0  # isolator force [kN] and tangent [kN/m] at the trial state
                f_prev = kt_prev = 0.0  # and before the last correction
                du0 = 0.0  # base correction of the last iteration [m]
                moved = 0.0  # sum of the base corrections [m]
                norm2 = 0.0  # squared 2-norm of the last correction [m^2]
                for it in range(solver.max_iter + 1):
                    if it > 0:
                        if it == 1:  # the condensed residual of the predictor, r0 - F
                            du0 = (r0 - f) / (d0 + kt)
                            norm2 = du0 * du0
                            if norm2 < tol * tol:  # else not converged whatever the superstructure
                                norm2 = core.add_superstructure_norm(norm2, shape, flex, r, du0)
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
                    finite = math.isfinite(f) and math.isfinite(kt) and math.isfinite(norm2)
                    status, stop = core.newton_verdict(status, finite, it, norm2, tol)
                    if stop:
                        break
                if status != 0:
                    break
                # -- commit, with the energy increments (trapezoidal)
                scal[core.E_ISOLATOR] += 0.5 * (scal[core.F_C] + f) * (u0 - u[0])
                de_input, de_viscous = core.commit(m, cs, cg, u, v, a, u0, v0, a0, moved, shape, flex, r,
                                                   0.5 * (scal[core.AG_C] + agk), c1, c2, cv, cva, ca, cav)
                scal[core.E_INPUT] += de_input
                scal[core.E_VISCOUS] += de_viscous
                scal[core.F_C] = f
                scal[core.AG_C] = agk
                core.copy(st, sc)
            if status == 0:
                break
        if store:
            iterations_h[k] = n_it
            levels_h[k] = level
            robust_h[k] = deviated
        if status != 0:
            if store:
                disp_h[k, :] = u
            return Summary(status, k, u0_peak, 0.0, 0.0, 0.0, 0.0, n_subdivided, n_robust,
                           drift_max * inv_height, accel_max)
        if level > 0:
            n_subdivided += 1
        if deviated:
            n_robust += 1
        # -- output step k: stored energies, peaks, histories
        e_kinetic, e_strain, shear = core.output_step(m, ks, cs, u, v, a, ag1, inv_height, drift_max,
                                                      accel_max, k, disp_h, accel_h, drift_h, drift_ratio_h)
        e_input = scal[core.E_INPUT]
        if abs(u[0]) > u0_peak:
            u0_peak = abs(u[0])
        if abs(shear) > shear_peak:
            shear_peak = abs(shear)
        imbalance = abs(e_input - e_kinetic - scal[core.E_VISCOUS] - scal[core.E_ISOLATOR] - e_strain)
        if imbalance > imbalance_max:
            imbalance_max = imbalance
        if abs(e_input) > input_max:
            input_max = abs(e_input)
        if store:
            force_h[k] = scal[core.F_C]
            shear_h[k] = shear
            energy_h[0, k] = e_input
            energy_h[1, k] = e_kinetic
            energy_h[2, k] = scal[core.E_VISCOUS]
            energy_h[3, k] = scal[core.E_ISOLATOR]
            energy_h[4, k] = e_strain
    energy_error = imbalance_max / input_max if input_max > 0.0 else 0.0
    return Summary(0, -1, u0_peak, abs(u[0]), shear_peak, scal[core.E_ISOLATOR], energy_error, n_subdivided,
                   n_robust, drift_max * inv_height, accel_max)


def batch(chain, layer, params, ag, dt, solver, n_blocks, out):
    """:func:`integrate` for every parameter row of ``params`` (runs, n_params), peaks only.

    The runs are split into ``n_blocks`` contiguous blocks run in parallel on
    ``numba.get_num_threads()`` threads (:func:`structures.dynamics.blocks.run_blocks`: each run
    calls the compiled :func:`integrate`, which releases the GIL, so a batch compiles nothing of
    its own), one analysis per thread at a time; ``layer`` gives the bearings (its ``params``
    unused).  Writes run r's :class:`structures.dynamics.newmark_records.Summary` into row r of
    the fields of ``out`` (:class:`structures.dynamics.newmark_records.Batch`).
    """
    none = Histories.allocate(0, chain.mass.shape[0])  # peaks only (the same type as full histories)
    fields = [getattr(out, f) for f in Summary._fields]

    def one(run):
        s = integrate(chain, Layer(params[run], layer.count, layer.scale, layer.state0), ag, dt, solver, none)
        for field, value in zip(fields, s):
            field[run] = value

    run_blocks(one, params.shape[0], n_blocks)
