"""Two-component displacement-control openseespy driver for the 3-D bearing elements.

The plan counterpart of :mod:`tests.opensees_harness` (same analysis settings: Path series
with ``-dt 1`` and one padding value, Plain patterns, Transformation constraints, Plain
numberer, BandGeneral, NormDispIncr 1e-12, Newton, LoadControl 1.0, so analysis step k imposes
sample k-1).  A zero-length 3-D element between a fixed node and a node whose global X and Y
DOFs are imposed by ``sp(2, 1, 1.0)`` and ``sp(2, 2, 1.0)`` on two Path series; the vertical DOF
(global Z, the element's local x) is free on an elastic axial material (ElastomericX and HDR:
their own axial model), the rotations fixed.  The orientation ``-orient 0 0 1 1 0 0`` makes the
element's local y the global X and its local z the global Y, so the basic shear deformations are
``(u_X, u_Y)`` and the returned forces are node j's global ``(F_X, F_Y)`` (``eleResponse``
components 6 and 7).  Law parameters are the rrfrei ones (kN, m).
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from rrfrei.laws import plan
from tests.opensees_harness import AXIAL_K, _CaptureStderr, spurious_cut, z_floor

ORIENT = [0, 0, 1, 1, 0, 0]
PLAN_LAWS = tuple(n for n in plan.names() if plan.get(n).opensees_element)


def _plan_element_args(law: str, p: dict) -> list:
    """``ops.element`` arguments of the plan law's 3-D OpenSees element (the law's spec,
    :meth:`rrfrei.laws.plan.PlanLawSpec.opensees_args`; material tags 1-4)."""
    spec = plan.get(law)
    if not spec.opensees_element:
        raise ValueError(f"no OpenSees 3-D element for law {law!r}")
    return [spec.opensees_element, 1, 1, 2, *spec.opensees_args(p, orient=ORIENT)]


def _build(ops, law: str, params: dict, disp: np.ndarray) -> None:
    ops.wipe()
    ops.model("basic", "-ndm", 3, "-ndf", 6)
    ops.node(1, 0.0, 0.0, 0.0)
    ops.node(2, 0.0, 0.0, 0.0)
    ops.fix(1, 1, 1, 1, 1, 1, 1)
    ops.fix(2, 0, 0, 0, 1, 1, 1)
    for tag in (1, 2, 3, 4):
        ops.uniaxialMaterial("Elastic", tag, AXIAL_K)
    ops.element(*_plan_element_args(law, params))
    for a in (0, 1):
        col = np.asarray(disp[:, a], dtype=float)
        values = [0.0, *col.tolist(), float(col[-1])]
        ops.timeSeries("Path", a + 1, "-dt", 1.0, "-values", *values)
        ops.pattern("Plain", a + 1, a + 1)
        ops.sp(2, a + 1, 1.0)
    ops.constraints("Transformation")
    ops.numberer("Plain")
    ops.system("BandGeneral")
    ops.test("NormDispIncr", 1e-12, 100)
    ops.algorithm("Newton")
    ops.integrator("LoadControl", 1.0)
    ops.analysis("Static")


def element_force(ops, law: str, params: dict, disp) -> tuple[np.ndarray, int]:
    """Shear forces (F_X, F_Y) [kN] of the OpenSees 3-D element along the (n, 2) path ``disp``
    [m].

    Returns ``(force, n_ok)``: ``force`` is (n, 2); ``n_ok < n`` when ``analyze`` failed at
    sample ``n_ok`` (later rows NaN).
    """
    force, n_ok, _ = element_force_and_failure(ops, law, params, disp)
    return force, n_ok


def element_force_and_failure(ops, law: str, params: dict, disp) -> tuple[np.ndarray, int, int]:
    """:func:`element_force` plus the first sample at which the element's ``update()`` reported
    a failed local Newton solve (its WARNING on opserr), or -1.

    openseespy 3.7.1.2 does not stop the analysis on such a failure (the next ``update()`` of
    the same step continues the local Newton from the stuck trial z), so the forces after it
    are not comparable; the failure sample is (as in :func:`tests.opensees_harness.element_force`).
    """
    disp = np.asarray(disp, dtype=float)
    if disp.ndim != 2 or disp.shape[1] != 2:
        raise ValueError(f"disp must be (n, 2), got {disp.shape}")
    _build(ops, law, params, disp)
    out = np.full(disp.shape, np.nan)
    n_ok = disp.shape[0]
    first_fail = -1
    with _CaptureStderr() as cap:
        seen = 0
        for k in range(disp.shape[0]):
            status = ops.analyze(1)
            text = cap.text()
            if first_fail < 0 and len(text) > seen and "update()" in text[seen:]:
                first_fail = k
            seen = len(text)
            if status != 0:
                n_ok = k
                break
            r = ops.eleResponse(1, "force")
            out[k, 0] = r[6]
            out[k, 1] = r[7]
        ops.wipe()
    return out, n_ok, first_fail


def element_force_recorder(ops, law: str, params: dict, disp, path: str | None = None) -> np.ndarray:
    """Same forces as :func:`element_force` from one ``analyze(n)`` call with an element
    recorder (openseespy's fastest path; benchmarks).  Raises RuntimeError if the analysis fails.
    """
    disp = np.asarray(disp, dtype=float)
    _build(ops, law, params, disp)
    own = path is None
    if own:
        fd, path = tempfile.mkstemp(suffix=".out")
        os.close(fd)
    try:
        ops.recorder("Element", "-file", path, "-precision", 17, "-ele", 1, "force")
        status = ops.analyze(disp.shape[0])
        ops.wipe()  # flushes and closes the recorder
        if status != 0:
            raise RuntimeError(f"OpenSees analysis of {law} failed (status {status})")
        data = np.loadtxt(path, ndmin=2)
    finally:
        if own:
            os.unlink(path)
    return data[-disp.shape[0]:, 6:8]


RTOL = 1e-9
"""Largest force difference against the OpenSees element, relative to the history's peak |F|."""


def rrfrei_force_and_failure(law: str, params: dict, disp) -> tuple[np.ndarray | None, int]:
    """(forces (n, 2) or None, failing sample or -1) of ``rrfrei.simulate_force`` on the path."""
    import re

    import rrfrei

    try:
        return rrfrei.simulate_force(law, params, disp), -1
    except ValueError as exc:
        m = re.search(r"failed at sample (\d+)", str(exc))
        assert m, str(exc)
        return None, int(m.group(1))


def check_against_opensees(ops, law: str, params: dict, disp, rtol: float = RTOL) -> None:
    """The law fails at the sample where the OpenSees element's local solve first fails, or
    neither fails and the forces agree to ``rtol`` of the peak |F|, up to the first sample at
    which OpenSees' Bouc-Wen state lands on a spurious root (:func:`spurious_cut`)."""
    f_os, n_ok, fail_os = element_force_and_failure(ops, law, params, disp)
    j = spurious_cut(law, params, disp, f_os, fail_os,
                     lambda d: rrfrei_force_and_failure(law, params, d))
    if j is not None:  # compare the samples before it
        if j == 0:
            return
        disp = disp[:j]
        f_os, n_ok, fail_os = element_force_and_failure(ops, law, params, disp)
    f, fail = rrfrei_force_and_failure(law, params, disp)
    assert fail == fail_os, f"local failure at sample {fail} here, {fail_os} in OpenSees"
    if fail < 0:
        assert n_ok == disp.shape[0]
        scale = np.max(np.abs(f_os))
        if scale == 0.0:
            assert np.all(f == 0.0)
        else:
            err = np.max(np.abs(f - f_os))
            assert err <= rtol * scale + z_floor(law, params), \
                f"max error {err:.3e} kN, peak force {scale:.3e} kN"
