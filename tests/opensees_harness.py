"""Reusable displacement-control openseespy driver for the four OpenSees bearing laws.

Follows ``docs/reference/opensees_elements.md`` section 6 exactly: a zero-length element
between a fixed node and a node whose global X DOF is imposed by ``sp(j, 1, 1.0)`` in a Plain
pattern on a Path series (``-dt 1``, one padding value appended because PathSeries returns 0 at
its last sample), the vertical DOF free on an elastic axial material/stiffness, every other DOF
fixed; Transformation constraints, Plain numberer, BandGeneral, NormDispIncr 1e-12, Newton,
LoadControl 1.0, so analysis step k lands exactly on pseudo-time k and imposes ``disp[k-1]``.

* 2-D (plasticity, bouc_wen): ``-orient 0 1 0 -1 0 0`` makes the basic shear deformation
  ``-u_X``; we impose ``u_X = -disp`` so the basic deformation is ``disp`` and return the basic
  force ``-F_X`` (node j global X force): no reliance on the laws' odd symmetry.
* 3-D (elastomeric_x, hdr): orientation ``0 0 1 1 0 0`` makes the basic shear ``+u_X``; the
  force is ``+F_X``.  ElastomericX receives all 29 arguments, HDR all 32.

The element and its argument list are the law's (``LawSpec.opensees``), as in the exported
command (:func:`rrfrei.calibration.results.opensees_command`).

Use :func:`element_force` (one ``analyze(1)`` per sample, reads ``eleResponse``) in tests and
:func:`element_force_recorder` (one ``analyze(n)`` call, element recorder to a file: openseespy's
fastest path) in benchmarks.  Law parameters are the rrfrei ones (kN, m).

The building blocks are shared by every openseespy peer of the tests (the plan driver
:mod:`tests.opensees_plan`, the building models :mod:`tests.opensees_dynamic` and
:mod:`tests.opensees_plan_building`, the exported-command check): :func:`element_args` (the
law's element from its spec), :func:`bearing_model` (nodes, supports, masses, axial
materials), :func:`impose`, :func:`static_analysis` / :func:`transient_analysis`,
:func:`analyze_each` (step by step, local failures caught on opserr), :func:`recorded_forces`
and :func:`check_against_opensees` (the differential contract).
"""

from __future__ import annotations

import io
import os
import re
import sys
import tempfile

import numpy as np

from rrfrei.laws import get, opensees_laws

AXIAL_K = 1.0e6  # kN/m, elastic axial (and rotational) stiffness of the 2-D bearings
ORIENT = {2: [0, 1, 0, -1, 0, 0], 3: [0, 0, 1, 1, 0, 0]}  # see the module docstring

TWO_D = tuple(n for n in opensees_laws() if 2 in get(n).opensees.dims)
THREE_D = tuple(n for n in opensees_laws() if 2 not in get(n).opensees.dims)


def opensees_ndm(law: str) -> int:
    """Model dimension the harnesses build ``law``'s element in: 2 where OpenSees has the
    element in 2-D (``LawSpec.opensees.dims``), else 3."""
    spec = get(law)
    if spec.opensees is None:
        raise ValueError(f"no OpenSees element for law {law!r}")
    return 2 if 2 in spec.opensees.dims else 3


def element_args(law: str, p: dict, ndm: int) -> list:
    """``ops.element`` arguments of the law's OpenSees element as element 1 between nodes 1
    and 2 in a ``ndm``-D model with orientation :data:`ORIENT` (the law's spec,
    :meth:`rrfrei.laws.LawSpec.opensees_args`; in 3-D material tags 1-4 for ``-P -T -My -Mz``,
    in 2-D 1-2 for ``-P -Mz``, for the elements that take them)."""
    spec = get(law)
    return [spec.opensees_element, 1, 1, 2, *spec.opensees_args(p, ndm=ndm, orient=ORIENT[ndm])]


def _element_args(law: str, p: dict) -> list:
    """:func:`element_args` in the dimension the harness uses (:func:`opensees_ndm`)."""
    return element_args(law, p, opensees_ndm(law))


def bearing_model(ops, ndm: int, free: tuple[int, ...], masses=(0.0,)) -> None:
    """Wipe and build the nodes of a bearing model: a basic ``ndm``-D model (``-ndf`` 3 or 6),
    node 1 at the origin and fixed, nodes 2, 3, ... at the origin, one per entry of ``masses``
    [t], each free in the global DOFs ``free`` (1-based) and fixed in the others, with its mass
    in every free DOF (none where it is 0: the static models); elastic materials of stiffness
    :data:`AXIAL_K` with tags 1-2 (2-D) or 1-4 (3-D) for the element directions the shear law
    does not model (``-P -Mz``, ``-P -T -My -Mz``)."""
    ndf = 3 if ndm == 2 else 6
    origin = [0.0] * ndm
    ops.wipe()
    ops.model("basic", "-ndm", ndm, "-ndf", ndf)
    ops.node(1, *origin)
    ops.fix(1, *([1] * ndf))
    for j, mass in enumerate(masses):
        ops.node(j + 2, *origin)
        ops.fix(j + 2, *(0 if dof in free else 1 for dof in range(1, ndf + 1)))
        if mass:
            ops.mass(j + 2, *(mass if dof in free else 0.0 for dof in range(1, ndf + 1)))
    for tag in range(1, (2 if ndm == 2 else 4) + 1):
        ops.uniaxialMaterial("Elastic", tag, AXIAL_K)


def impose(ops, dof: int, disp) -> None:
    """Impose ``disp`` [m] on node 2's global ``dof`` (tag ``dof`` for its Path series and Plain
    pattern): ``-dt 1`` and one padding value (PathSeries returns 0 at its last sample), so
    analysis step k imposes ``disp[k-1]``."""
    disp = np.asarray(disp, dtype=float)
    ops.timeSeries("Path", dof, "-dt", 1.0, "-values", 0.0, *disp.tolist(), float(disp[-1]))
    ops.pattern("Plain", dof, dof)
    ops.sp(2, dof, 1.0)


def _analysis(ops, constraints: str, test: tuple, integrator: tuple, kind: str) -> None:
    ops.constraints(constraints)
    ops.numberer("Plain")
    ops.system("BandGeneral")
    ops.test(*test)
    ops.algorithm("Newton")
    ops.integrator(*integrator)
    ops.analysis(kind)


def static_analysis(ops) -> None:
    """Displacement control: Transformation constraints, Plain numberer, BandGeneral,
    NormDispIncr 1e-12 (100 iterations), Newton, LoadControl 1.0 (step k at pseudo-time k)."""
    _analysis(ops, "Transformation", ("NormDispIncr", 1e-12, 100), ("LoadControl", 1.0), "Static")


def transient_analysis(ops, *, tol: float, max_iter: int, gamma: float, beta: float) -> None:
    """Time history: Plain constraints and numberer, BandGeneral, NormDispIncr ``tol``
    (``max_iter`` iterations), Newton, Newmark(``gamma``, ``beta``)."""
    _analysis(ops, "Plain", ("NormDispIncr", tol, max_iter), ("Newmark", gamma, beta), "Transient")


FREE = {2: (1, 2), 3: (1, 3)}
"""Free DOFs of node 2 in the one-axis models: global X (imposed) and the vertical."""


def _build(ops, law: str, params: dict, disp: np.ndarray) -> tuple[int, float]:
    """Build the model; return (index of the node-j X component in eleResponse force, sign)."""
    ndm = opensees_ndm(law)
    bearing_model(ops, ndm, FREE[ndm])
    ops.element(*element_args(law, params, ndm))
    sign = -1.0 if ndm == 2 else 1.0
    impose(ops, 1, sign * np.asarray(disp, dtype=float))
    static_analysis(ops)
    return (3 if ndm == 2 else 6), sign


class _CaptureStderr:
    """Capture OpenSees' opserr: openseespy writes it through ``sys.stderr`` (a Python object,
    replaced by pytest's capture), other builds to file descriptor 2; both are redirected."""

    def __enter__(self):
        self.tmp = tempfile.TemporaryFile(mode="w+b")
        self.saved_fd = os.dup(2)
        os.dup2(self.tmp.fileno(), 2)
        self.buf = io.StringIO()
        self.saved_sys = sys.stderr
        sys.stderr = self.buf
        return self

    def text(self) -> str:
        self.tmp.seek(0)
        return self.buf.getvalue() + self.tmp.read().decode(errors="replace")

    def __exit__(self, *exc):
        sys.stderr = self.saved_sys
        os.dup2(self.saved_fd, 2)
        os.close(self.saved_fd)
        self.tmp.close()


def first_spurious_sample(law: str, p: dict, disp, f_os) -> int | None:
    """First sample at which OpenSees' Bouc-Wen state lies beyond the bound |z| <= z_max =
    (beta + gamma)^(-1/eta), or None (every other law: None).

    ``disp`` [m] and ``f_os`` [kN] are (n,) along one axis or (n, 2) in plan (|z| the Euclidean
    norm).  From |z_C| <= z_max the step equation has its physical root inside the bound
    (``rrfrei.laws.bouc_wen`` module docstring; in plan |z| saturates at the same bound); with
    gamma > beta and |du| >> u_y it also has spurious roots outside it, and which one the local
    Newton lands on, and whether it converges from there, is decided by the last bit of its
    iterates (ours differ from OpenSees' by rounding: powers Taylor-updated, a 2x2 solve by
    Cramer's rule in plan).  The differential tests therefore require agreement up to that
    sample, not from it on.  z is read off OpenSees' force: z = (F - k2 u - k3 sgn(u) |u|^mu) / qd.
    """
    if law != "bouc_wen":
        return None
    disp = np.asarray(disp, dtype=float)
    k2 = p["alpha1"] * p["k_init"]
    k3 = p["alpha2"] * p["k_init"]
    z = (np.asarray(f_os) - k2 * disp - k3 * np.sign(disp) * np.abs(disp) ** p["mu"]) / p["qd"]
    size = np.abs(z) if z.ndim == 1 else np.hypot(z[:, 0], z[:, 1])
    z_max = (p["beta"] + p["gamma"]) ** (-1.0 / p["eta"])
    beyond = np.flatnonzero(size > z_max * (1.0 + 1e-6) + 1e-9)  # NaN is not beyond
    return int(beyond[0]) if beyond.size else None


def z_floor(law: str, p: dict) -> float:
    """Force [kN] below which two correct Bouc-Wen ports may differ: OpenSees defines z only to
    its local Newton tolerance (|dz| < 1e-12, ``-iter`` default), so forces of qd z agree to
    qd 1e-12 and no better when every force is itself that small (a history of 1e-10 m steps
    with eta < 1: 3.7e-18 kN apart on 1e-9 kN forces, seen by hypothesis).  0 for the others."""
    return p["qd"] * 1e-12 if law == "bouc_wen" else 0.0


def spurious_cut(law: str, p: dict, disp, f_os, fail_os: int, ours) -> int | None:
    """The sample at which a differential test stops comparing, or None (compare all).

    The first sample where OpenSees' state lies beyond the bound (:func:`first_spurious_sample`),
    or, earlier, the sample where OpenSees' local Newton failed if ours lands beyond the bound
    there: the same spurious-root lottery seen from the other side (OpenSees' first update()
    call reached such a root, its second did not settle).  ``ours(disp) -> (force or None,
    failing sample or -1)``.  A state of ours beyond the bound where OpenSees converged inside it
    is no cut: it fails the comparison.
    """
    j = first_spurious_sample(law, p, disp, f_os)
    if law == "bouc_wen" and fail_os >= 0 and (j is None or fail_os < j):
        head = np.asarray(disp)[: fail_os + 1]
        f, _ = ours(head)
        if f is not None and first_spurious_sample(law, p, head, f) == fail_os:
            j = fail_os
    return j


def analyze_each(ops, n: int, read) -> tuple[int, int]:
    """Run ``n`` analysis steps one ``analyze(1)`` at a time, calling ``read(k)`` after each
    converged step k, then wipe.

    Returns ``(n_ok, first_local_failure)``: ``n_ok`` steps converged globally (``n_ok < n``
    when ``analyze`` failed at step ``n_ok``; no later step runs), and ``first_local_failure``
    is the first step at which the element's ``update()`` reported a failed local Newton solve
    (its WARNING on opserr), or -1.  openseespy 3.7.1.2 does not stop the analysis on such a
    failure: the next ``update()`` call of the same step continues the local Newton from the
    stuck trial z.
    """
    first_fail = -1
    n_ok = n
    with _CaptureStderr() as cap:
        seen = 0
        for k in range(n):
            status = ops.analyze(1)
            text = cap.text()
            if first_fail < 0 and len(text) > seen and "update()" in text[seen:]:
                first_fail = k
            seen = len(text)
            if status != 0:
                n_ok = k
                break
            read(k)
        ops.wipe()
    return n_ok, first_fail


def recorded_forces(ops, law: str, n: int, path: str | None = None) -> np.ndarray:
    """Element 1's ``force`` response over ``n`` steps from one ``analyze(n)`` call with an
    element recorder to ``path`` (a temporary file when None; openseespy's fastest path):
    the recorder's last ``n`` rows.  Raises RuntimeError if the analysis fails."""
    own = path is None
    if own:
        fd, path = tempfile.mkstemp(suffix=".out")
        os.close(fd)
    try:
        ops.recorder("Element", "-file", path, "-precision", 17, "-ele", 1, "force")
        status = ops.analyze(n)
        ops.wipe()  # flushes and closes the recorder
        if status != 0:
            raise RuntimeError(f"OpenSees analysis of {law} failed (status {status})")
        return np.loadtxt(path, ndmin=2)[-n:]
    finally:
        if own:
            os.unlink(path)


def element_force(ops, law: str, params: dict, disp) -> tuple[np.ndarray, int, int]:
    """Basic shear force [kN] of the OpenSees element along ``disp`` [m].

    Returns ``(force, n_ok, first_local_failure)`` (:func:`analyze_each`; forces after a
    global failure are NaN).
    """
    disp = np.asarray(disp, dtype=float)
    idx, sign = _build(ops, law, params, disp)
    out = np.full(disp.size, np.nan)

    def read(k):
        out[k] = sign * ops.eleResponse(1, "force")[idx]

    n_ok, first_fail = analyze_each(ops, disp.size, read)
    return out, n_ok, first_fail


def element_force_recorder(ops, law: str, params: dict, disp, path: str | None = None) -> np.ndarray:
    """Same as :func:`element_force` with one ``analyze(n)`` call and an element recorder.

    Raises RuntimeError if the analysis fails.
    """
    disp = np.asarray(disp, dtype=float)
    idx, sign = _build(ops, law, params, disp)
    return sign * recorded_forces(ops, law, disp.size, path)[:, idx]


def command_force(ops, law: str, command: str, disp) -> np.ndarray:
    """Basic shear force [kN] of the element that the exported openseespy ``command`` builds
    (``rrfrei.calibration.results.opensees_command``: the user's copy-paste, run as is, its
    trailing comment dropped), driven along global X by ``disp`` [m] on the one-axis model;
    asserts that every step converges."""
    disp = np.asarray(disp, dtype=float)
    ndm = opensees_ndm(law)
    bearing_model(ops, ndm, FREE[ndm])
    eval(command.split("#")[0], {"ops": ops})
    impose(ops, 1, disp)
    static_analysis(ops)
    out = np.full(disp.size, np.nan)

    def read(k):
        out[k] = ops.eleResponse(1, "basicForce")[1]  # basic shear force

    n_ok, _ = analyze_each(ops, disp.size, read)
    assert n_ok == disp.size, f"openseespy analysis of the exported {law} failed at sample {n_ok}"
    return out


RTOL = 1e-9
"""Largest force difference against the OpenSees element, relative to the history's peak |F|."""


def rrfrei_force_and_failure(law: str, params: dict, disp) -> tuple[np.ndarray | None, int]:
    """(forces or None, failing sample or -1) of ``rrfrei.simulate_force`` on the path (one
    axis (n,) or plan (n, 2))."""
    import rrfrei

    try:
        return rrfrei.simulate_force(law, params, disp), -1
    except ValueError as exc:
        m = re.search(r"failed at sample (\d+)", str(exc))
        assert m, str(exc)
        return None, int(m.group(1))


def check_against_opensees(ops, law: str, params: dict, disp, rtol: float = RTOL, *,
                           peer=element_force) -> None:
    """The law fails at the sample where the OpenSees element's local solve first fails, or
    neither fails and the forces agree to ``rtol`` of the peak |F|, up to the first sample at
    which OpenSees' Bouc-Wen state lands on a spurious root (:func:`spurious_cut`).

    ``peer(ops, law, params, disp) -> (force, n_ok, first_local_failure)`` drives the element:
    :func:`element_force` along one axis, ``tests.opensees_plan.element_force_and_failure``
    in plan."""
    disp = np.asarray(disp, dtype=float)
    f_os, n_ok, fail_os = peer(ops, law, params, disp)
    j = spurious_cut(law, params, disp, f_os, fail_os,
                     lambda d: rrfrei_force_and_failure(law, params, d))
    if j is not None:  # compare the samples before it
        if j == 0:
            return
        disp = disp[:j]
        f_os, n_ok, fail_os = peer(ops, law, params, disp)
    f, fail = rrfrei_force_and_failure(law, params, disp)
    assert fail == fail_os, f"local failure at sample {fail} here, {fail_os} in OpenSees"
    if fail < 0:
        assert n_ok == len(disp)
        scale = np.max(np.abs(f_os))
        if scale == 0.0:
            assert np.all(f == 0.0)
        else:
            err = np.max(np.abs(f - f_os))
            assert err <= rtol * scale + z_floor(law, params), \
                f"max error {err:.3e} kN, peak force {scale:.3e} kN"
