"""Public entry point for driving a law along a displacement history."""

from __future__ import annotations

import warnings
from collections.abc import Mapping

import numpy as np

from rrfrei._inputs import as_history
from rrfrei.errors import NumericalFailure
from rrfrei.laws import STATUS_MESSAGES, LawSpec, get, names
from rrfrei.laws.specialise import history

LOCAL_SOLVERS = ("opensees", "robust")
"""Values of the ``local_solver`` option of :func:`simulate_force` and
:func:`structures.time_history`."""

class LocalSolverDeviation(UserWarning):
    """The robust local solve replaced OpenSees' failed (or falsely converged) local iteration
    at some steps.

    Attributes
    ----------
    law : law name.
    samples : (k,) int array, the sample (output step) indices where it acted.
    """

    def __init__(self, message: str, law: str, samples: np.ndarray):
        super().__init__(message)
        self.law = law
        self.samples = samples


def robust_local_solve(spec: LawSpec, local_solver) -> bool:
    """True when ``local_solver`` asks for the law's robust local solve, after validating it.

    ``"opensees"`` (OpenSees' own local iteration, the default) is valid for every law;
    ``"robust"`` for a law with a robust local solve in its registry entry
    (``LawSpec.step_robust``: ``bouc_wen``'s bracketed safeguarded Newton where OpenSees'
    iteration fails, see :mod:`rrfrei.laws.bouc_wen`; ``elastomeric_x`` and every augmented law
    use it) and for the closed-form laws (``local_iteration=False``: ``linear``, ``plasticity``,
    ``hdr``), where it changes nothing.  Raises ``ValueError`` otherwise.
    """
    if not isinstance(local_solver, str) or local_solver not in LOCAL_SOLVERS:
        raise ValueError(
            f"local_solver = {local_solver!r} is invalid: expected one of {LOCAL_SOLVERS}"
        )
    if local_solver == "opensees":
        return False
    if spec.step_robust is not None:
        return True
    if not spec.local_iteration:
        return False
    robust = [n for n in names() if get(n).step_robust is not None]
    closed = [n for n in names() if not get(n).local_iteration]
    raise ValueError(
        f"local_solver = 'robust' is not available for law {spec.name!r}: it is implemented for "
        f"{_quoted(robust)} (and is a no-op for the closed-form laws {_quoted(closed)}); use "
        "local_solver='opensees'"
    )


def _quoted(items: list[str]) -> str:
    return " and ".join(", ".join(repr(x) for x in items).rsplit(", ", 1)) if items else "(none)"


def deviation_warning(law: str, samples: np.ndarray, where: str = "sample") -> LocalSolverDeviation:
    """The :class:`LocalSolverDeviation` naming how many and which steps deviated."""
    first = ", ".join(str(int(i)) for i in samples[:5]) + (", ..." if samples.size > 5 else "")
    return LocalSolverDeviation(
        f"law {law!r}: OpenSees' local Newton iteration failed (or stopped away from a root) at "
        f"{samples.size} {where}(s) ({where} {first}); the robust bracketed solve "
        "(local_solver='robust') was used there, a deviation from OpenSees",
        law,
        samples,
    )


ROBUST_HINT = (
    "; local_solver='robust' solves the same backward-Euler equation by bracketed safeguarded "
    "Newton where OpenSees' iteration fails (reported as a deviation from OpenSees)"
)


def robust_hint(spec: LawSpec, status: int, robust: bool) -> str:
    """:data:`ROBUST_HINT` for a failure message when the robust solve could have helped (a
    local-iteration failure, status -1 or -2, of a law with a robust local solve, e.g.
    ``bouc_wen``, with the default solver), else ""."""
    return (ROBUST_HINT if status in (-1, -2) and spec.step_robust is not None and not robust
            else "")


def simulate_force(
    law: str | LawSpec,
    params: Mapping[str, float] | np.ndarray,
    disp,
    *,
    time=None,
    substeps: int = 1,
    return_tangent: bool = False,
    local_solver: str = "opensees",
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Shear force [kN] of ``law`` along the displacement history ``disp`` [m].

    Parameters
    ----------
    law : name of a registered law (``rrfrei.laws.names()``), possibly augmented
        (``"bouc_wen+rate"``), or its :class:`LawSpec`.
    params : parameter values by name (kN, m, s), or an array in ``spec.param_names`` order.
    disp : displacement history [m]; the law starts virgin at zero displacement.
    time : sample times [s], strictly increasing; needed only by velocity-dependent terms.
        Without it the history is quasi-static (velocity 0, dt = 1 as in OpenSees statics).
        An (n, 2) array is a two-component path in plan [m]: the law's coupled
        bidirectional form (:mod:`rrfrei.laws.plan`, OpenSees' 3-D bearing shear behaviour)
        returns (n, 2) forces [kN] and, with ``return_tangent``, (n, 2, 2) tangents [kN/m].
    substeps : 1 reproduces OpenSees (one implicit update per increment, so the result depends on
        the sampling); n > 1 splits every increment into n equal parts for a step-size-converged
        answer.
    return_tangent : also return the tangent stiffness history [kN/m].
    local_solver : ``"opensees"`` (default) runs OpenSees' local Newton iteration and fails where
        it fails; ``"robust"`` (every law with a local iteration and every augmented law; a
        no-op for the explicit laws ``linear``, ``plasticity`` and ``hdr``)
        keeps that iteration wherever it converges to a root (identical forces) and, where it
        fails or stops away from a root, solves the same step equation by bracketed safeguarded
        Newton
        (:func:`rrfrei.laws.bouc_wen.solve_bracketed`).  Those samples are a deviation from
        OpenSees and are reported by a :class:`LocalSolverDeviation` warning (``.samples``).

    Raises
    ------
    ValueError
        unknown law, bad parameters, non-finite or non-1-D displacement, or bad time.
    NumericalFailure
        (a ``ValueError`` subclass) the law's local solve failed; the message names the sample
        index, the state and the parameters (and, for ``bouc_wen``, suggests
        ``local_solver="robust"``).

    Warns
    -----
    LocalSolverDeviation
        ``local_solver="robust"`` acted at some samples (count and first indices named).
    """
    if np.ndim(disp) == 2:
        return _simulate_plan(law, params, disp, time=time, substeps=substeps,
                              return_tangent=return_tangent, local_solver=local_solver)
    spec = get(law)
    p = spec.pack(params)
    robust = robust_local_solve(spec, local_solver)
    u = as_history(disp, "disp")
    _check_substeps(substeps)
    t, use_time = _time_of(time, u.size)
    force = np.empty_like(u)
    tangent = np.empty_like(u)
    sc = np.array(spec.initial_state, dtype=float)
    st = sc.copy()
    deviated = None
    drive = history(spec, robust)  # the law's own history driver: only this law is compiled
    if robust:
        deviated = np.zeros(u.size, dtype=np.int64)
        status, idx = drive(p, sc, st, u, t, use_time, int(substeps), force, tangent, deviated)
    else:
        status, idx = drive(p, sc, st, u, t, use_time, int(substeps), force, tangent)
    if status != 0:
        raise NumericalFailure(
            f"law {spec.name!r} failed at sample {idx} (disp = {u[idx]:.6g} m): "
            f"{STATUS_MESSAGES.get(int(status), f'status {status}')}; committed state "
            f"{np.array2string(sc, precision=6)}, failed trial state "
            f"{np.array2string(st, precision=6)}; parameters {spec.as_dict(p)}"
            + robust_hint(spec, status, robust)
        )
    if deviated is not None and deviated.any():
        warnings.warn(deviation_warning(spec.name, np.flatnonzero(deviated)), stacklevel=2)
    return (force, tangent) if return_tangent else force


def _check_substeps(substeps) -> None:
    if not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")


def _time_of(time, n: int) -> tuple[np.ndarray, bool]:
    """(time array, use_time) after validating ``time`` against ``n`` samples."""
    if time is None:
        return np.zeros(n), False
    t = as_history(time, "time")
    if t.size != n:
        raise ValueError(f"time has {t.size} values but disp has {n}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0])
        raise ValueError(
            f"time must be strictly increasing; time[{i + 1}] = {t[i + 1]} <= time[{i}] = {t[i]}"
        )
    return t, True


def as_plan_history(values, name: str = "disp", finite: bool = True) -> np.ndarray:
    """A finite (n, 2) float64 array (n >= 1), or ValueError naming ``name``, the sample and the
    value (``finite=False``: finiteness not checked, for a caller whose compiled driver checks
    it)."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (n, 2) array of numbers, got {type(values).__name__}") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 1:
        raise ValueError(f"{name} must be an (n, 2) array (x, y per sample) [m], got shape {arr.shape}")
    if finite and not np.isfinite(arr).all():  # (argwhere only then: far slower than the test)
        i, a = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} is not finite at sample {i}, component {'xy'[a]} (value {arr[i, a]})")
    return np.ascontiguousarray(arr)


def _simulate_plan(law, params, disp, *, time, substeps, return_tangent, local_solver):
    """:func:`simulate_force` on an (n, 2) path: the law's coupled bidirectional form."""
    from rrfrei.laws import plan

    pspec = plan.get(law)
    spec = pspec.law
    p = spec.pack(params)
    if robust_local_solve(spec, local_solver) and spec.local_iteration:
        raise ValueError(
            f"local_solver = 'robust' is not available for the bidirectional form of law "
            f"{spec.name!r}; use local_solver='opensees'"
        )
    u = as_plan_history(disp, "disp", finite=False)  # the driver checks (plan.NONFINITE_DISP)
    _check_substeps(substeps)
    # without time, a 1-element stand-in: the plan drivers read time only with use_time (an
    # (n,) array of zeros is a measurable part of a short history's cost)
    t, use_time = _time_of(time, u.shape[0]) if time is not None else (np.zeros(1), False)
    force = np.empty_like(u)
    tangent = np.empty((u.shape[0], 2, 2))
    sc = np.array(pspec.initial_state, dtype=float)
    st = sc.copy()
    status, idx = plan.driver(pspec)(p, sc, st, u, t, use_time, int(substeps), force, tangent)
    if status == plan.registry.NONFINITE_DISP:
        as_plan_history(u, "disp")  # raises the ValueError naming the sample and component
    if status != 0:
        raise NumericalFailure(
            f"bidirectional law {spec.name!r} failed at sample {idx} (disp = "
            f"({u[idx, 0]:.6g}, {u[idx, 1]:.6g}) m): "
            f"{STATUS_MESSAGES.get(int(status), f'status {status}')}; committed state "
            f"{np.array2string(sc, precision=6)}, failed trial state "
            f"{np.array2string(st, precision=6)}; parameters {spec.as_dict(p)}"
        )
    return (force, tangent) if return_tangent else force
