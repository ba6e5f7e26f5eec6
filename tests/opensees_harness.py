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
"""

from __future__ import annotations

import io
import os
import sys
import tempfile

import numpy as np

from rrfrei.laws import get, opensees_laws

AXIAL_K = 1.0e6  # kN/m, elastic axial (and rotational) stiffness of the 2-D bearings
ORIENT = {2: [0, 1, 0, -1, 0, 0], 3: [0, 0, 1, 1, 0, 0]}  # see the module docstring

TWO_D = tuple(n for n in opensees_laws() if 2 in get(n).opensees.dims)
THREE_D = tuple(n for n in opensees_laws() if 2 not in get(n).opensees.dims)


def _element_args(law: str, p: dict) -> list:
    """``ops.element`` arguments of the law's OpenSees element (the law's spec,
    :meth:`rrfrei.laws.LawSpec.opensees_args`): 2-D where OpenSees has it, else 3-D."""
    spec = get(law)
    if spec.opensees is None:
        raise ValueError(f"no OpenSees element for law {law!r}")
    ndm = 2 if law in TWO_D else 3
    return [spec.opensees_element, 1, 1, 2, *spec.opensees_args(p, ndm=ndm, orient=ORIENT[ndm])]


def _build(ops, law: str, params: dict, disp: np.ndarray) -> tuple[int, float]:
    """Build the model; return (index of the node-j X component in eleResponse force, sign)."""
    ops.wipe()
    if law in TWO_D:
        ops.model("basic", "-ndm", 2, "-ndf", 3)
        ops.node(1, 0.0, 0.0)
        ops.node(2, 0.0, 0.0)
        ops.fix(1, 1, 1, 1)
        ops.fix(2, 0, 0, 1)
        ops.uniaxialMaterial("Elastic", 1, AXIAL_K)
        ops.uniaxialMaterial("Elastic", 2, AXIAL_K)
        idx, sign = 3, -1.0
    elif law in THREE_D:
        ops.model("basic", "-ndm", 3, "-ndf", 6)
        ops.node(1, 0.0, 0.0, 0.0)
        ops.node(2, 0.0, 0.0, 0.0)
        ops.fix(1, 1, 1, 1, 1, 1, 1)
        ops.fix(2, 0, 1, 0, 1, 1, 1)
        idx, sign = 6, 1.0
    else:
        raise ValueError(f"no OpenSees element for law {law!r}")
    ops.element(*_element_args(law, params))
    values = [0.0, *(sign * np.asarray(disp, dtype=float)).tolist(), sign * float(disp[-1])]
    ops.timeSeries("Path", 1, "-dt", 1.0, "-values", *values)
    ops.pattern("Plain", 1, 1)
    ops.sp(2, 1, 1.0)
    ops.constraints("Transformation")
    ops.numberer("Plain")
    ops.system("BandGeneral")
    ops.test("NormDispIncr", 1e-12, 100)
    ops.algorithm("Newton")
    ops.integrator("LoadControl", 1.0)
    ops.analysis("Static")
    return idx, sign


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


def element_force(ops, law: str, params: dict, disp) -> tuple[np.ndarray, int, int]:
    """Basic shear force [kN] of the OpenSees element along ``disp`` [m].

    Returns ``(force, n_ok, first_local_failure)``: ``n_ok`` samples converged globally
    (``n_ok < len(disp)`` when ``analyze`` failed at sample ``n_ok``; later forces are NaN), and
    ``first_local_failure`` is the first sample at which the element's ``update()`` reported a
    failed local Newton solve (its WARNING on opserr), or -1.  openseespy 3.7.1.2 does not stop
    the analysis on such a failure: the next ``update()`` call of the same step continues the
    local Newton from the stuck trial z.
    """
    disp = np.asarray(disp, dtype=float)
    idx, sign = _build(ops, law, params, disp)
    out = np.full(disp.size, np.nan)
    first_fail = -1
    n_ok = disp.size
    with _CaptureStderr() as cap:
        seen = 0
        for k in range(disp.size):
            status = ops.analyze(1)
            text = cap.text()
            if first_fail < 0 and len(text) > seen and "update()" in text[seen:]:
                first_fail = k
            seen = len(text)
            if status != 0:
                n_ok = k
                break
            out[k] = sign * ops.eleResponse(1, "force")[idx]
        ops.wipe()
    return out, n_ok, first_fail


def element_force_recorder(ops, law: str, params: dict, disp, path: str | None = None) -> np.ndarray:
    """Same as :func:`element_force` with one ``analyze(n)`` call and an element recorder.

    Raises RuntimeError if the analysis fails.
    """
    disp = np.asarray(disp, dtype=float)
    idx, sign = _build(ops, law, params, disp)
    own = path is None
    if own:
        fd, path = tempfile.mkstemp(suffix=".out")
        os.close(fd)
    try:
        ops.recorder("Element", "-file", path, "-precision", 17, "-ele", 1, "force")
        status = ops.analyze(disp.size)
        ops.wipe()  # flushes and closes the recorder
        if status != 0:
            raise RuntimeError(f"OpenSees analysis of {law} failed (status {status})")
        data = np.loadtxt(path, ndmin=2)
    finally:
        if own:
            os.unlink(path)
    return sign * data[-disp.size:, idx]
