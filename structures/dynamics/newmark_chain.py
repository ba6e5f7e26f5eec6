"""One direction of the Newmark step on a shear chain condensed onto its base: the shared core.

Both time-history kernels, the unidirectional :mod:`structures.dynamics.newmark` (one chain) and the plan
:mod:`structures.dynamics.plan_newmark` (one chain per horizontal direction, coupled only through the
isolator), move each chain with the functions of this module; they differ only in the Newton
iteration on the base DOF(s), where the isolator law is called (a scalar iteration in 1-D, a
2 x 2 system in plan).  So every equation below is written once and each direction of the plan
building is, operation for operation, the unidirectional building.

The chain ``[base, floor 1, ..., floor n]`` (displacements relative to the ground) obeys

    M a + C v + K_s u + F_iso e_0 = -M 1 a_g(t)

and the step is OpenSees' ``Newmark`` (displacement form, ``SRC/analysis/integrator/Newmark.cpp``
l.157-255) with ``Newton`` and ``NormDispIncr``; with K_L = K_s + g/(b h) C + 1/(b h^2) M split
into the base row/column and the superstructure block K_ss (tridiagonal),
phi = -K_ss^-1 K_s0 (phi_0 = 1) and d_0 = K_00 + K_0s phi (derivation in
:mod:`structures.dynamics.newmark`):

* :func:`condense`: d_0, phi, phi^T phi and K_ss^-1 (depend on the step size only);
* :func:`linear_residual`: the predictor u = u_n, v = cv v_n + cva a_n, a = ca a_n + cav v_n,
  the residual R of the linear part there (R_0 without the isolator force) and its condensation
  r_0 = R_0 + phi . R_s;
* :func:`add_superstructure_norm`: ||du_s||^2 of the first correction, du_s = K_ss^-1 R_s +
  phi_s du_0 (needed only when the base correction alone is below the tolerance);
* :func:`commit`: the superstructure moved by its predictor plus K_ss^-1 R_s + phi (sum of the
  base corrections), with the input and viscous energy increments (trapezoidal,
  :mod:`structures.dynamics.energy`);
* :func:`output_step`: kinetic and strain energy, story-1 shear, peak drifts and floor
  accelerations, and the history rows of an output step.

All are pure functions of arrays and scalars (state in, state out through the arrays given);
units kN, m, s, tonnes.  All but :func:`condense` (called once per step size) are inlined into
the kernels (``inline="always"``, at Numba IR level): a call per step, with the views of the
plan kernel's per-direction rows, would otherwise cost reference counting and calls that the
written-out loops did not (measured: the plan kernel 1.7x slower).  The rows of a kernel's
work array are named here (:data:`N_WORK`).
"""

import math

from numba import njit

N_WORK = 11
"""Rows of a kernel's work array (each ndof long, per direction)."""
(U, V, A,  # committed displacement, velocity, acceleration
 U_SAVED, V_SAVED, A_SAVED,  # the committed state before a subdivided step
 R,  # residual of the linear part at the predictor
 LOWER, RATIO, INV_PIVOT,  # scratch of the elimination in condense
 SHAPE) = range(N_WORK)  # phi, the superstructure's correction per unit base correction

N_SCALARS = 5
"""Committed scalars of a direction, rows of a kernel's (2 N_SCALARS, [directions]) array (the
second half: their saved copy): isolator force [kN], input, viscous and isolator energy
[kN m], ground acceleration [m/s^2]."""
F_C, E_INPUT, E_VISCOUS, E_ISOLATOR, AG_C = range(N_SCALARS)

NON_FINITE = -3
"""Status of a step with a non-finite isolator force, tangent or correction."""
NOT_CONVERGED = -4
"""Status of a step whose Newton iteration did not converge even after subdivision."""


@njit(cache=True, inline="always")
def work_rows(work):
    """Views of the rows of a work array (N_WORK, [directions,] ndof) used by the step:
    (u, v, a, r, lower, ratio, inv_pivot, shape)."""
    return (work[U], work[V], work[A], work[R], work[LOWER], work[RATIO], work[INV_PIVOT],
            work[SHAPE])


@njit(cache=True, inline="always")
def save_state(work, saved, scalars):
    """Save the committed state before a subdivided step: u, v, a into their saved rows, the
    law's committed state into ``saved[1]`` and the committed scalars (first half of the rows of
    ``scalars``) into the second half."""
    work[U_SAVED:A_SAVED + 1] = work[U:A + 1]
    saved[1, :] = saved[0]
    half = scalars.shape[0] // 2
    scalars[half:] = scalars[:half]


@njit(cache=True, inline="always")
def restore_state(work, saved, scalars):
    """Undo a failed try of a subdivided step: the inverse of :func:`save_state`."""
    work[U:A + 1] = work[U_SAVED:A_SAVED + 1]
    saved[0, :] = saved[1]
    half = scalars.shape[0] // 2
    scalars[:half] = scalars[half:]


@njit(cache=True, inline="always")
def start_try(level, work, law, scalars, trial):
    """Before try ``level`` of a step (0: one step; l: 2^l substeps): at level 1 save the
    committed state of step k-1 (the failed first try committed nothing), at higher levels
    restore it; from level 1 on, reset the law's trial state ``trial`` to its committed state
    ``law[0]`` (see :func:`save_state` for the layout)."""
    if level == 1:
        save_state(work, law, scalars)
    elif level > 1:
        restore_state(work, law, scalars)
    if level > 0:
        copy(law[0], trial)


@njit(cache=True, inline="always")
def newton_verdict(status, finite, it, norm2, tol):
    """(status, stop) after the isolator call of Newton iteration ``it`` (0: at the predictor):
    stop on a law status != 0, on a non-finite force, tangent or correction (``finite`` False:
    :data:`NON_FINITE`), or when the last correction's 2-norm sqrt(``norm2``) [m] is below ``tol``
    (OpenSees' NormDispIncr: status 0); else go on, :data:`NOT_CONVERGED` unless a later
    iteration converges."""
    if status != 0:
        return status, True
    if not finite:
        return NON_FINITE, True
    if it > 0 and math.sqrt(norm2) < tol:
        return 0, True
    return NOT_CONVERGED, False


@njit(cache=True, inline="always")
def copy(src, dst):
    """dst[:] = src for short 1-D arrays (a law's state), as a loop."""
    for q in range(src.shape[0]):
        dst[q] = src[q]


@njit(cache=True, inline="always")
def coefficients(solver, h):
    """Newmark's coefficients for the step ``h`` [s]: (c1, c2) = (dv/du, da/du) of a
    correction, g/(b h) and 1/(b h^2), and the predictor's v = cv v_n + cva a_n,
    a = ca a_n + cav v_n: (c1, c2, cv, cva, ca, cav)."""
    gamma = solver.gamma
    beta = solver.beta
    return (gamma / (beta * h), 1.0 / (beta * h * h), 1.0 - gamma / beta,
            h * (1.0 - gamma / (2.0 * beta)), 1.0 - 1.0 / (2.0 * beta), -1.0 / (beta * h))


@njit(cache=True, inline="always")
def layer_scales(layer):
    """(1 / s, count s^2, count s) of an isolator layer: the law sees u / s and v / s and its
    force and tangent scale to the layer's by the other two (similitude, equal stress)."""
    return 1.0 / layer.scale, layer.count * layer.scale * layer.scale, layer.count * layer.scale


@njit(cache=True)
def condense(chain, c1, c2, lower, ratio, inv_pivot, shape, flex):
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


@njit(cache=True, inline="always")
def linear_residual(m, ks, cs, cg, u, v, a, ag, cv, cva, ca, cav, shape, r):
    """The residual of the linear part at the predictor, written to ``r`` [kN], and its
    condensation on the base r_0 = R_0 + phi . R_s [kN] (returned).

    ``u, v, a`` are the committed state [m, m/s, m/s^2], ``ag`` the ground acceleration at the
    end of the (sub)step [m/s^2] and (cv, cva, ca, cav) the predictor's coefficients.  Story j
    joins DOF j-1 and DOF j; the predicted superstructure state is recomputed at the commit.
    """
    n = m.shape[0]
    v_below = cv * v[0] + cva * a[0]
    r_below = -m[0] * (ag + ca * a[0] + cav * v[0]) - cg[0] * v_below
    r0 = 0.0
    for j in range(1, n):
        vj = cv * v[j] + cva * a[j]
        fs = ks[j - 1] * (u[j] - u[j - 1]) + cs[j - 1] * (vj - v_below)
        r[j - 1] = r_below + fs
        r0 += shape[j - 1] * r[j - 1]
        r_below = -m[j] * (ag + ca * a[j] + cav * v[j]) - cg[j] * vj - fs
        v_below = vj
    r[n - 1] = r_below
    r0 += shape[n - 1] * r_below
    return r0


@njit(cache=True, inline="always")
def add_superstructure_norm(norm2, shape, flex, r, du0):
    """``norm2`` [m^2] plus the squared corrections of the superstructure's DOFs,
    du_s = K_ss^-1 R_s + phi_s du_0, for the base correction ``du0`` [m] of the first iteration."""
    n = shape.shape[0]
    for j in range(1, n):
        d = shape[j] * du0
        for i in range(1, n):
            d += flex[j, i] * r[i]
        norm2 += d * d
    return norm2


@njit(cache=True, inline="always")
def commit(m, cs, cg, u, v, a, ub, vb, ab, moved, shape, flex, r, agm, c1, c2, cv, cva, ca, cav):
    """Commit the (sub)step: the base to its converged trial state (``ub, vb, ab``), every
    floor by its predictor plus K_ss^-1 R_s + phi ``moved`` (the sum of the base corrections
    [m]); ``u, v, a`` updated in place.

    Returns the input and viscous energy increments [kN m] (trapezoidal, ``agm`` the mean ground
    acceleration over the step [m/s^2]): dE_I = -agm 1^T M du, dE_D = (1/2)(C v_n + C v_n+1)^T du.
    """
    n = m.shape[0]
    du_j = ub - u[0]
    de_input = -m[0] * agm * du_j
    de_viscous = 0.5 * cg[0] * (v[0] + vb) * du_j
    u_below, v_below = u[0], v[0]  # DOF j-1 before the step
    u_below_t, v_below_t = ub, vb  # and after
    u[0] = ub
    v[0] = vb
    a[0] = ab
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
    return de_input, de_viscous


@njit(cache=True, inline="always")
def output_step(m, ks, cs, u, v, a, ag, inv_height, drift_max, accel_max, k, disp_h, accel_h, drift_h,
                drift_ratio_h):
    """Output step ``k``: peak |drift| [m] and |absolute floor acceleration| [m/s^2] updated in
    ``drift_max`` / ``accel_max``, and (when the histories have rows) the rows ``k`` of
    displacement, absolute acceleration (``ag`` the ground's [m/s^2]), drift and drift ratio.

    Returns (kinetic energy, story strain energy [kN m], story-1 shear [kN]).
    """
    n = m.shape[0]
    store = disp_h.shape[0] > 0
    e_kinetic = 0.5 * m[0] * v[0] * v[0]
    e_strain = 0.0
    if store:
        disp_h[k, 0] = u[0]
        accel_h[k, 0] = a[0] + ag
    for j in range(1, n):
        e_kinetic += 0.5 * m[j] * v[j] * v[j]
        d = u[j] - u[j - 1]
        e_strain += 0.5 * ks[j - 1] * d * d
        if abs(d) > drift_max[j - 1]:
            drift_max[j - 1] = abs(d)
        aa = abs(a[j] + ag)
        if aa > accel_max[j - 1]:
            accel_max[j - 1] = aa
        if store:
            disp_h[k, j] = u[j]
            accel_h[k, j] = a[j] + ag
            drift_h[k, j - 1] = d
            drift_ratio_h[k, j - 1] = d * inv_height[j - 1]
    shear = ks[0] * (u[1] - u[0]) + cs[0] * (v[1] - v[0])
    return e_kinetic, e_strain, shear


@njit(cache=True, inline="always")
def clear_first_step(disp_h, accel_h, drift_h, drift_ratio_h, force_h, shear_h, energy_h):
    """Zero the histories' first output step (at rest; no-op for histories without rows)."""
    if disp_h.shape[0] == 0:
        return
    disp_h[0, :] = 0.0
    accel_h[0, :] = 0.0
    drift_h[0, :] = 0.0
    drift_ratio_h[0, :] = 0.0
    force_h[0] = 0.0
    shear_h[0] = 0.0
    energy_h[:, 0] = 0.0

