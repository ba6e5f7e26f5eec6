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

from functools import partial

import numpy as np

from rrfrei.laws import plan
from tests import opensees_harness as harness
from tests.opensees_harness import (
    RTOL,  # noqa: F401  (the plan tests' tolerance, the harness's)
    _CaptureStderr,  # noqa: F401  (re-exported for the plan tests)
    analyze_each,
    bearing_model,
    impose,
    recorded_forces,
    rrfrei_force_and_failure,  # noqa: F401  (re-exported for the plan tests)
    static_analysis,
)

ORIENT = harness.ORIENT[3]
PLAN_LAWS = tuple(n for n in plan.names() if plan.get(n).opensees_element)


def _plan_element_args(law: str, p: dict) -> list:
    """``ops.element`` arguments of the plan law's 3-D OpenSees element (the law's spec,
    :meth:`rrfrei.laws.plan.PlanLawSpec.opensees_args`; material tags 1-4)."""
    spec = plan.get(law)
    if not spec.opensees_element:
        raise ValueError(f"no OpenSees 3-D element for law {law!r}")
    return [spec.opensees_element, 1, 1, 2, *spec.opensees_args(p, orient=ORIENT)]


def _build(ops, law: str, params: dict, disp: np.ndarray) -> None:
    bearing_model(ops, 3, (1, 2, 3))
    ops.element(*_plan_element_args(law, params))
    for a in (0, 1):
        impose(ops, a + 1, disp[:, a])
    static_analysis(ops)


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
    a failed local Newton solve (its WARNING on opserr), or -1
    (:func:`tests.opensees_harness.analyze_each`)."""
    disp = np.asarray(disp, dtype=float)
    if disp.ndim != 2 or disp.shape[1] != 2:
        raise ValueError(f"disp must be (n, 2), got {disp.shape}")
    _build(ops, law, params, disp)
    out = np.full(disp.shape, np.nan)

    def read(k):
        r = ops.eleResponse(1, "force")
        out[k, 0] = r[6]
        out[k, 1] = r[7]

    n_ok, first_fail = analyze_each(ops, disp.shape[0], read)
    return out, n_ok, first_fail


def element_force_recorder(ops, law: str, params: dict, disp, path: str | None = None) -> np.ndarray:
    """Same forces as :func:`element_force` from one ``analyze(n)`` call with an element
    recorder (openseespy's fastest path; benchmarks).  Raises RuntimeError if the analysis fails.
    """
    disp = np.asarray(disp, dtype=float)
    _build(ops, law, params, disp)
    return recorded_forces(ops, law, disp.shape[0], path)[:, 6:8]


check_against_opensees = partial(harness.check_against_opensees, peer=element_force_and_failure)
"""The plan form of :func:`tests.opensees_harness.check_against_opensees`: the same contract on
an (n, 2) path, forces compared on both components."""
