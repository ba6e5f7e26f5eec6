"""Integer dispatch over the base law kernels (ids from each module's ``KERNEL_ID``).

Numba cannot cache functions that take other jitted functions as arguments, so one
``base_step`` holds the branches; it is internal.  Public code selects a law by name through the
registry, which supplies the integer code.
"""

from numba import njit

from rrfrei.laws import bouc_wen, elastomeric_x, hdr, linear, plasticity


@njit(cache=True)
def base_step(lid, p, sc, u, v, dt, st):
    """Step of base law ``lid`` (see :mod:`rrfrei.laws.registry` for the contract)."""
    if lid == 2:
        return bouc_wen.step(p, sc, u, v, dt, st)
    if lid == 1:
        return plasticity.step(p, sc, u, v, dt, st)
    if lid == 3:
        return elastomeric_x.step(p, sc, u, v, dt, st)
    if lid == 4:
        return hdr.step(p, sc, u, v, dt, st)
    if lid == 0:
        return linear.step(p, sc, u, v, dt, st)
    return 0.0, 0.0, -3


@njit(cache=True)
def base_drive(lid, p, sc, st, disp, time, use_time, substeps, force, tangent):
    """Whole-history driver of base law ``lid``: one branch per history instead of per step.

    Each law module's ``drive`` inlines its own ``step`` in the time loop, which is about twice
    as fast as dispatching every step (see ``benchmarks/bench_laws.py``).
    """
    if lid == 2:
        return bouc_wen.drive(p, sc, st, disp, time, use_time, substeps, force, tangent)
    if lid == 1:
        return plasticity.drive(p, sc, st, disp, time, use_time, substeps, force, tangent)
    if lid == 3:
        return elastomeric_x.drive(p, sc, st, disp, time, use_time, substeps, force, tangent)
    if lid == 4:
        return hdr.drive(p, sc, st, disp, time, use_time, substeps, force, tangent)
    if lid == 0:
        return linear.drive(p, sc, st, disp, time, use_time, substeps, force, tangent)
    return -3, 0
