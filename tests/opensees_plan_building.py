"""openseespy 3-D model of a plan building (the peer of ``structures.plan_time_history``).

The 3-D counterpart of :mod:`tests.opensees_dynamic` (same analysis settings):

* ``-ndm 3 -ndf 6``, all nodes at the origin: node 1 the fixed ground, node 2 the base slab,
  nodes 3.. the floors, each with global X and Y free and the vertical and the three rotations
  fixed (a lumped mass per floor, no torsion); nodal masses in X and Y;
* the isolator layer as one 3-D bearing element between nodes 1 and 2 with the orientation of
  :mod:`tests.opensees_plan` (``-orient 0 0 1 1 0 0``: local x vertical, local y = global X,
  local z = global Y), its parameters mapped to the prototype by similitude
  (:func:`tests.opensees_dynamic.prototype_params`), the element and its arguments the law's
  own (``LawSpec.opensees``, read by :func:`tests.opensees_harness.element_args`; vertical DOF
  fixed); the ``linear`` law as a zeroLength element with an elastic material in X and one in
  Y (``count length_scale k`` each);
* story springs and dashpots as zeroLength elements with ``uniaxialMaterial Elastic k eta=c`` in
  dirs 1 and 2 (the x stories from ``building``, the y stories from ``building_y``); Rayleigh's
  mass term as zeroLength dashpots to the ground;
* two ``UniformExcitation`` patterns, in X and in Y, each on its own Path series with the record
  step and one padding value; Newmark(1/2, 1/4), Newton, NormDispIncr, Plain
  constraints/numberer, BandGeneral;
* ``nodeAccel`` is relative: the ground acceleration is added for the absolute one.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
from opensees_dynamic import prototype_params

from rrfrei.laws import opensees_laws
from tests.opensees_harness import _CaptureStderr, bearing_model, element_args, transient_analysis

LAWS = ("linear", *opensees_laws())


def _isolator(ops, law: str, p: dict) -> None:
    """The isolator layer between nodes 1 and 2: the law's 3-D OpenSees element from its spec
    (``LawSpec.opensees``, :func:`tests.opensees_harness.element_args`; material tags 1-4 of
    :func:`tests.opensees_harness.bearing_model` for the elements that take them), or for
    ``linear`` a zeroLength element with one elastic material in X and Y."""
    if law == "linear":
        if p.get("c", 0.0) != 0.0:
            raise ValueError("the linear isolator's dashpot c is not mapped (its tangent differs)")
        ops.uniaxialMaterial("Elastic", 5, p["k"])
        ops.element("zeroLength", 1, 1, 2, "-mat", 5, 5, "-dir", 1, 2)
        return
    ops.element(*element_args(law, p, 3))


def _prototype(law: str, p: dict, count: int, s: float) -> dict:
    if law == "linear":
        return {"k": p["k"] * count * s, "c": p.get("c", 0.0) * count * s}
    return prototype_params(law, p, count, s)


def build(ops, building, ag: np.ndarray, dt: float, *, building_y=None, tol: float = 1e-12,
          max_iter: int = 50, gamma: float = 0.5, beta: float = 0.25) -> int:
    """Build the model and the transient analysis under ``ag`` (n, 2) [m/s^2]; return the roof
    node tag."""
    by = building if building_y is None else building_y
    iso = building.isolator
    law = iso.law
    p = _prototype(law, dict(iso.params), iso.count, iso.length_scale)
    n = building.n_stories
    masses = [building.base_mass, *building.story_masses]
    damping = [b.damping_coefficients() for b in (building, by)]
    stiffness = [building.story_stiffness, by.story_stiffness]
    bearing_model(ops, 3, (1, 2), masses)  # X and Y free, mass in both
    _isolator(ops, law, p)
    for i in range(n):  # story i+1 joins node i+2 (below) and node i+3
        tags = []
        for d in (0, 1):
            tag = 10 + 2 * i + d
            ops.uniaxialMaterial("Elastic", tag, float(stiffness[d][i]), float(damping[d][0][i]))
            tags.append(tag)
        ops.element("zeroLength", 10 + i, i + 2, i + 3, "-mat", *tags, "-dir", 1, 2)
    for j in range(n + 1):
        cg = (float(damping[0][1][j]), float(damping[1][1][j]))
        if cg[0] > 0.0 or cg[1] > 0.0:
            ops.uniaxialMaterial("Elastic", 100 + 2 * j, 0.0, cg[0])
            ops.uniaxialMaterial("Elastic", 101 + 2 * j, 0.0, cg[1])
            ops.element("zeroLength", 100 + j, 1, j + 2, "-mat", 100 + 2 * j, 101 + 2 * j, "-dir", 1, 2)
    ag = np.asarray(ag, dtype=float)
    for d in (0, 1):
        ops.timeSeries("Path", d + 1, "-dt", dt, "-values", *ag[:, d].tolist(), float(ag[-1, d]))
        ops.pattern("UniformExcitation", d + 1, d + 1, "-accel", d + 1)
    transient_analysis(ops, tol=tol, max_iter=max_iter, gamma=gamma, beta=beta)
    return n + 2


def plan_building(ops, building, ag, dt: float, **kw) -> dict:
    """Step by step (``analyze(1, dt)``): isolator displacement (n, 2) [m], floor displacements
    (2, n, stories) [m] and absolute accelerations (2, n, stories) [m/s^2], roof last, and
    ``n_ok``: the number of valid rows (n, or the step at which ``analyze`` failed: OpenSees does
    not subdivide; later rows NaN)."""
    ag = np.asarray(ag, dtype=float)
    if ag.ndim != 2 or ag.shape[1] != 2:
        raise ValueError(f"ag must be (n, 2), got {ag.shape}")
    if np.any(ag[0] != 0.0):
        raise ValueError("OpenSees starts with a_0 = 0: give a ground motion whose first row is 0")
    roof = build(ops, building, ag, dt, **kw)
    n = ag.shape[0]
    floors = range(3, roof + 1)
    u_iso = np.zeros((n, 2))
    disp = np.zeros((2, n, roof - 2))
    acc = np.zeros((2, n, roof - 2))
    n_ok = n
    for k in range(1, n):
        with _CaptureStderr():
            status = ops.analyze(1, dt)
        if status != 0:
            n_ok = k
            u_iso[k:] = np.nan
            disp[:, k:] = np.nan
            acc[:, k:] = np.nan
            break
        for d in (0, 1):
            u_iso[k, d] = ops.nodeDisp(2, d + 1)
            for c, node in enumerate(floors):
                disp[d, k, c] = ops.nodeDisp(node, d + 1)
                acc[d, k, c] = ops.nodeAccel(node, d + 1) + ag[k, d]
    ops.wipe()
    return {"isolator_disp": u_iso, "floor_disp": disp, "floor_accel_abs": acc, "n_ok": n_ok}


def plan_building_one_call(ops, building, ag, dt: float, **kw) -> np.ndarray:
    """The whole record in one ``analyze(n-1, dt)`` call, the base and roof X and Y
    displacements recorded to a file (openseespy's fastest path, for benchmarks).  Returns
    (n-1, 4): base X, base Y, roof X, roof Y."""
    ag = np.asarray(ag, dtype=float)
    roof = build(ops, building, ag, dt, **kw)
    fd, path = tempfile.mkstemp(suffix=".out")
    os.close(fd)
    try:
        ops.recorder("Node", "-file", path, "-precision", 17, "-node", 2, roof, "-dof", 1, 2, "disp")
        if ops.analyze(ag.shape[0] - 1, dt) != 0:
            raise RuntimeError("OpenSees failed")
        ops.wipe()  # flushes and closes the recorder
        data = np.loadtxt(path, ndmin=2)
    finally:
        os.unlink(path)
    return data
