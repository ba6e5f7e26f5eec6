"""openseespy model of a :class:`structures.ShearBuilding` (the peer of ``structures.time_history``).

Follows ``docs/reference/opensees_elements.md`` section 6 ("Dynamics"):

* 2-D (``-ndm 2 -ndf 3``) for plasticity and bouc_wen, 3-D (``-ndm 3 -ndf 6``) with only X free
  for elastomeric_x and hdr; all nodes at the origin, node 1 the fixed ground, node 2 the base
  slab, nodes 3.. the floors; nodal masses in X only;
* the isolator layer as one bearing element between nodes 1 and 2 (2-D ``-orient 0 1 0 -1 0 0``,
  3-D orientation ``0 0 1 1 0 0``), its parameters mapped to the prototype by similitude (below);
* story springs and dashpots as zeroLength elements in dir 1 on ``uniaxialMaterial Elastic k
  eta=c``; Rayleigh's mass term (``damping="rayleigh"``) as zeroLength dashpots to the ground
  (``Elastic 0 eta=c``);
* ``UniformExcitation`` in X on a Path series with the record step and one padding value
  (PathSeries returns 0 at its last sample), Newmark(1/2, 1/4), Newton, NormDispIncr, Plain
  constraints/numberer, BandGeneral;
* ``nodeAccel`` is relative: the ground acceleration is added for the absolute one.

Similitude (equal stress, scale s, ``count`` bearings): the prototype layer force is
count s^2 F_law(u/s), which each OpenSees law represents exactly with mapped parameters
(:func:`prototype_params`), so the peer never sees ``count`` or ``length_scale``.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from rrfrei.laws import opensees_laws
from tests.opensees_harness import bearing_model, element_args, opensees_ndm, transient_analysis

TWO_D = tuple(n for n in opensees_laws() if opensees_ndm(n) == 2)
THREE_D = tuple(n for n in opensees_laws() if opensees_ndm(n) == 3)


def prototype_params(law: str, p: dict, count: int, s: float) -> dict:
    """Parameters of ONE OpenSees bearing equal to ``count`` bearings of ``law`` scaled by ``s``.

    With F(u) = count s^2 F_law(u/s):
    * plasticity / bouc_wen: k_init x c s, qd x c s^2, alpha2 x s^(1-mu) (k3 |u/s|^mu), the rest
      unchanged (u_y = qd/k0 scales by s);
    * elastomeric_x: fy x c s^2, gr x c, diameters/thicknesses x s (ke = gr A / Tr x c s),
      cd x c s, alpha and n unchanged;
    * hdr: a1 x c s, a2 x c/s, a3 x c/s^3, b1 x c s^2, b2 x c, b3 / s, c1, c2, c4 / s^3, c3 same.
    """
    c = float(count)
    q = dict(p)
    if law in TWO_D:
        q["k_init"] = p["k_init"] * c * s
        q["qd"] = p["qd"] * c * s * s
        q["alpha2"] = p["alpha2"] * s ** (1.0 - p["mu"])
    elif law == "elastomeric_x":
        q["fy"] = p["fy"] * c * s * s
        q["gr"] = p["gr"] * c
        for k in ("d1", "d2", "tr", "tc"):
            q[k] = p[k] * s
        q["cd"] = p["cd"] * c * s
    elif law == "hdr":
        q.update(a1=p["a1"] * c * s, a2=p["a2"] * c / s, a3=p["a3"] * c / s**3, b1=p["b1"] * c * s * s,
                 b2=p["b2"] * c, b3=p["b3"] / s, c1=p["c1"] / s**3, c2=p["c2"] / s**3, c4=p["c4"] / s**3)
    else:
        raise ValueError(f"no OpenSees element for law {law!r}")
    return q


def build(ops, building, ag: np.ndarray, dt: float, *, tol: float = 1e-12, max_iter: int = 50,
          gamma: float = 0.5, beta: float = 0.25) -> int:
    """Build the model and the transient analysis; return the roof node tag."""
    iso = building.isolator
    law = iso.law
    p = prototype_params(law, dict(iso.params), iso.count, iso.length_scale)
    n = building.n_stories
    masses = [building.base_mass, *building.story_masses]
    cs, cg = building.damping_coefficients()
    ndm = opensees_ndm(law)
    bearing_model(ops, ndm, (1,), masses)  # X free, mass in X
    ops.element(*element_args(law, p, ndm))  # the law's element and arguments (LawSpec.opensees)
    for i in range(n):  # story i+1 joins node i+2 (below) and node i+3
        ops.uniaxialMaterial("Elastic", 10 + i, building.story_stiffness[i], float(cs[i]))
        ops.element("zeroLength", 10 + i, i + 2, i + 3, "-mat", 10 + i, "-dir", 1)
    for j in range(n + 1):
        if cg[j] > 0.0:
            ops.uniaxialMaterial("Elastic", 100 + j, 0.0, float(cg[j]))
            ops.element("zeroLength", 100 + j, 1, j + 2, "-mat", 100 + j, "-dir", 1)
    ops.timeSeries("Path", 1, "-dt", dt, "-values", *np.asarray(ag, dtype=float).tolist(), float(ag[-1]))
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    transient_analysis(ops, tol=tol, max_iter=max_iter, gamma=gamma, beta=beta)
    return n + 2


def shear_building(ops, building, ag, dt: float, **kw) -> dict[str, np.ndarray]:
    """Step by step (``analyze(1, dt)``): isolator displacement [m], all floor displacements
    [m] (n, stories) and absolute accelerations [m/s^2] (n, stories), roof last."""
    ag = np.asarray(ag, dtype=float)
    if ag[0] != 0.0:
        raise ValueError("OpenSees starts with a_0 = 0: give a record whose first value is 0")
    roof = build(ops, building, ag, dt, **kw)
    n = ag.size
    floors = range(3, roof + 1)
    u_iso = np.zeros(n)
    disp = np.zeros((n, roof - 2))
    acc = np.zeros((n, roof - 2))
    for k in range(1, n):
        if ops.analyze(1, dt) != 0:
            raise RuntimeError(f"OpenSees failed at step {k} (t = {k * dt:g} s)")
        u_iso[k] = ops.nodeDisp(2, 1)
        for c, node in enumerate(floors):
            disp[k, c] = ops.nodeDisp(node, 1)
            acc[k, c] = ops.nodeAccel(node, 1) + ag[k]
    ops.wipe()
    return {"isolator_disp": u_iso, "floor_disp": disp, "floor_accel_abs": acc}


def shear_building_one_call(ops, building, ag, dt: float, **kw) -> np.ndarray:
    """The whole record in one ``analyze(n-1, dt)`` call, the base and roof X displacement
    recorded to a file (openseespy's fastest path, for benchmarks).  Returns (n-1, 2)."""
    ag = np.asarray(ag, dtype=float)
    roof = build(ops, building, ag, dt, **kw)
    fd, path = tempfile.mkstemp(suffix=".out")
    os.close(fd)
    try:
        ops.recorder("Node", "-file", path, "-precision", 17, "-node", 2, roof, "-dof", 1, "disp")
        if ops.analyze(ag.size - 1, dt) != 0:
            raise RuntimeError("OpenSees failed")
        ops.wipe()  # flushes and closes the recorder
        return np.loadtxt(path, ndmin=2)
    finally:
        os.unlink(path)


#: Example law parameters at the scale of the RR-FREI 1:3 specimen (80 mm diameter, 15 x 2 mm of
#: rubber; kN, m, s), used with the example buildings' count and length_scale.
SPECIMEN_PARAMS = {
    "plasticity": dict(k_init=260.0, qd=1.4, alpha1=0.33, alpha2=0.0, mu=2.0),
    "bouc_wen": dict(k_init=260.0, qd=1.4, alpha1=0.33, alpha2=0.0, mu=2.0, eta=1.0, beta=0.5, gamma=0.5),
    "elastomeric_x": dict(fy=1.4, alpha=0.33, gr=513.0, d1=0.0, d2=0.08, tr=0.002, n=15.0, tc=0.0, cd=1.0),
    "hdr": dict(a1=150.0, a2=1.6e4, a3=2.3e6, b1=1.2, b2=550.0, b3=200.0, c1=30.0, c2=30.0, c3=0.8,
                c4=0.5),
}
