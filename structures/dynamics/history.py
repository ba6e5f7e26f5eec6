"""Nonlinear time histories of a shear building on isolators: the public API.

:func:`time_history` (one analysis, full histories as a :class:`Response`) and
:func:`time_history_batch` (peak demands of many isolator parameter sets, in parallel) validate
their inputs, build the named records of :mod:`structures.dynamics.newmark_records`, and run the Newmark
kernel (:mod:`structures.dynamics.newmark`) instantiated for the building's isolator law by
:func:`rrfrei.laws.specialise.instantiate`, so each law's step is compiled into its own copy of
the kernel (only the laws used are compiled).  Units: kN, m, s, tonnes.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from types import ModuleType

import numba
import numpy as np

from rrfrei.laws import STATUS_MESSAGES, LawSpec, specialise
from rrfrei.simulate import deviation_warning, robust_hint, robust_local_solve
from structures.building.shear_building import ShearBuilding
from structures.dynamics import energy as _energy
from structures.dynamics.newmark_records import Batch, Chain, Histories, Layer, Solver

_DEFAULT_MAX_ITER = 50
_DEFAULT_LEVELS = 6
TEMPLATE = "structures.dynamics.newmark"
"""The kernel template instantiated per law."""


class ConvergenceError(RuntimeError):
    """A time step failed even after subdivision (the message names record, time and state)."""


@dataclass(frozen=True, eq=False)
class Response:
    """Time history of a shear building (arrays over the output times).

    Attributes
    ----------
    record : name of the ground motion.
    time : (n,) [s].
    isolator_disp, isolator_force : (n,) layer displacement [m] and force [kN].
    floor_disp : (n, stories) floor displacement relative to the ground [m], roof last.
    drift, drift_ratio : (n, stories) story drift [m] (floor i minus floor i-1, the base slab
        below story 1) and drift / story height [-].
    floor_accel_abs : (n, stories) absolute floor acceleration [m/s^2], roof last.
    base_accel_abs : (n,) absolute acceleration of the base slab [m/s^2].
    base_shear : (n,) shear force in story 1 (spring + dashpot), i.e. above the isolators [kN].
    energy : dict of (n,) energy histories [kN m] (see :mod:`structures.dynamics.energy`).
    energy_error : max |imbalance| / max |input energy| [-].
    newton_iterations : (n,) Newton iterations per output step (summed over substeps).
    subdivided_steps : indices of the output steps that needed substeps.
    robust_steps : indices of the output steps where ``local_solver="robust"`` replaced
        OpenSees' failed local iteration (a deviation from OpenSees; empty by default).
    """

    record: str
    time: np.ndarray
    isolator_disp: np.ndarray
    isolator_force: np.ndarray
    floor_disp: np.ndarray
    drift: np.ndarray
    drift_ratio: np.ndarray
    floor_accel_abs: np.ndarray
    base_accel_abs: np.ndarray
    base_shear: np.ndarray
    energy: dict
    energy_error: float
    newton_iterations: np.ndarray
    subdivided_steps: np.ndarray
    robust_steps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def summary(self) -> dict[str, float]:
        """Peak demands (absolute values): isolator displacement [m] and force [kN], residual
        isolator displacement [m], peak drift ratio [-], peak roof and floor absolute
        accelerations [m/s^2], base shear [kN], isolator work [kN m], energy error, steps."""
        return {
            "isolator_disp_peak": float(np.max(np.abs(self.isolator_disp))),
            "isolator_disp_residual": float(abs(self.isolator_disp[-1])),
            "isolator_force_peak": float(np.max(np.abs(self.isolator_force))),
            "drift_ratio_peak": float(np.max(np.abs(self.drift_ratio))),
            "roof_accel_abs_peak": float(np.max(np.abs(self.floor_accel_abs[:, -1]))),
            "floor_accel_abs_peak": float(np.max(np.abs(self.floor_accel_abs))),
            "base_shear_peak": float(np.max(np.abs(self.base_shear))),
            "isolator_work": float(self.energy["isolator"][-1]),
            "energy_error": float(self.energy_error),
            "newton_iterations_mean": (
                float(np.mean(self.newton_iterations[1:])) if self.time.size > 1 else 0.0
            ),
            "subdivided_steps": int(self.subdivided_steps.size),
            "robust_steps": int(self.robust_steps.size),
        }


NEWMARK_OPTIONS = ("gamma", "beta", "tol", "max_iter", "max_subdivisions")
"""The keyword options of every time-history verb that set the Newmark step and its Newton
iteration (:func:`solver_settings`, which holds their defaults)."""


def solver_settings(robust: bool = False, *, gamma: float = 0.5, beta: float = 0.25, tol: float = 1e-12,
                    max_iter: int = _DEFAULT_MAX_ITER, max_subdivisions: int = _DEFAULT_LEVELS,
                    **unknown) -> Solver:
    """The validated settings of the Newmark step and its Newton iteration (:class:`Solver`), the
    one home of the options the time-history verbs take (:data:`NEWMARK_OPTIONS`).

    Parameters
    ----------
    robust : the law's robust local solve replaces a failed local iteration (at the last
        subdivision level only).
    gamma, beta : Newmark's parameters (0.5, 0.25: average acceleration).
    tol : Newton convergence on ||du||_2 [m] (OpenSees NormDispIncr).
    max_iter : Newton iterations per (sub)step before the step is subdivided.
    max_subdivisions : a failing step is retried in 2, 4, ... 2^max_subdivisions substeps.

    Raises
    ------
    ValueError : an option that is not one of :data:`NEWMARK_OPTIONS`, or a bad value (named).
    """
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(map(repr, unknown))}: the time-history options "
                         f"are dt, {', '.join(NEWMARK_OPTIONS)} and the verb's own")
    g = float(gamma)
    b = float(beta)
    if not (np.isfinite(g) and g > 0.0):
        raise ValueError(f"gamma = {gamma!r} is invalid: expected a finite number > 0 (0.5 is standard)")
    if not (np.isfinite(b) and b > 0.0):
        raise ValueError(f"beta = {beta!r} is invalid: expected a finite number > 0 (0.25 is standard)")
    t = float(tol)
    if not (np.isfinite(t) and t > 0.0):
        raise ValueError(f"tol = {tol!r} is invalid: expected a finite number > 0 [m]")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter = {max_iter!r} is invalid: expected an integer >= 1")
    if (isinstance(max_subdivisions, bool) or not isinstance(max_subdivisions, (int, np.integer))
            or not 0 <= max_subdivisions <= 20):
        raise ValueError(
            f"max_subdivisions = {max_subdivisions!r} is invalid: expected an integer in [0, 20]"
        )
    return Solver(g, b, t, int(max_iter), int(max_subdivisions), bool(robust))


def _ground(record, dt) -> tuple[str, np.ndarray, float]:
    """(name, ground acceleration [m/s^2] at the analysis step, step [s])."""
    name = str(getattr(record, "name", "record"))
    try:
        rdt = float(record.dt)
        acc = np.asarray(record.accel, dtype=float)
    except (AttributeError, TypeError, ValueError):
        raise ValueError(
            f"record must be a ground_motions.Record (dt [s], accel [m/s^2]), got {type(record).__name__}"
        ) from None
    if acc.ndim != 1 or acc.size < 2:
        raise ValueError(
            f"record {name!r}: accel must be a 1-D array of at least 2 values, got shape {acc.shape}"
        )
    return on_step("record", name, acc, rdt, dt)


def on_step(what: str, name: str, acc: np.ndarray, rdt: float, dt) -> tuple[str, np.ndarray, float]:
    """(name, ground acceleration ``acc`` (n,) or (n, 2) (x, y) [m/s^2] sampled every ``rdt``
    [s] on the analysis step ``dt`` [s] (None: ``rdt``; a smaller one interpolates linearly), the
    step).  ValueError naming the ``what`` (record, ground), ``name``, and the sample (and
    component) for a bad step or a non-finite value."""
    if not (np.isfinite(rdt) and rdt > 0.0):
        raise ValueError(f"{what} {name!r}: dt = {rdt!r} is invalid: expected a finite number > 0 s")
    bad = np.argwhere(~np.isfinite(acc))
    if bad.size:
        i = int(bad[0, 0])
        at = f"accel[{i}]" if acc.ndim == 1 else f"accel[{i}, {int(bad[0, 1])}]"
        comp = "" if acc.ndim == 1 else f"component {'xy'[int(bad[0, 1])]}, "
        raise ValueError(f"{what} {name!r}: {at} = {float(acc[tuple(bad[0])])!r} ({comp}t = {i * rdt:g} s) "
                         "is not finite")
    try:
        h = rdt if dt is None else float(dt)
    except (TypeError, ValueError):
        h = float("nan")
    if h == rdt:
        acc = np.ascontiguousarray(acc)
        # writable: Numba compiles a read-only array (a Record's) as a second signature of the
        # whole Newmark kernel (about 10 s of CPU per law and kernel)
        return name, acc if acc.flags.writeable else acc.copy(), rdt
    if not (np.isfinite(h) and 0.0 < h <= rdt):
        raise ValueError(
            f"dt = {dt!r} is invalid for {what} {name!r}: expected 0 < dt <= the record step {rdt:g} s "
            "(the record is interpolated linearly onto the finer step)"
        )
    duration = (acc.shape[0] - 1) * rdt
    n = int(np.floor(duration / h * (1.0 + 1e-12))) + 1
    t = np.arange(n) * h
    tr = np.arange(acc.shape[0]) * rdt
    if acc.ndim == 1:
        return name, np.interp(t, tr, acc), h
    return name, np.ascontiguousarray(np.column_stack([np.interp(t, tr, c) for c in acc.T])), h


def _model(building) -> tuple[LawSpec, Chain]:
    """The law of the building's isolator and the superstructure as the kernel's record."""
    if not isinstance(building, ShearBuilding):
        raise ValueError(f"building must be a ShearBuilding, got {type(building).__name__}")
    cs, cg = building.damping_coefficients()
    chain = Chain(
        mass=np.concatenate(([building.base_mass], building.story_masses)),
        story_stiffness=np.array(building.story_stiffness, dtype=float),
        story_damping=np.ascontiguousarray(cs, dtype=float),
        ground_damping=np.ascontiguousarray(cg, dtype=float),
        story_height=np.array(building.story_heights, dtype=float),
    )
    return building.isolator.spec, chain


def _layer(building, params: np.ndarray) -> Layer:
    iso = building.isolator
    return Layer(params, float(iso.count), float(iso.length_scale),
                 np.array(iso.spec.initial_state, dtype=float))


def kernel(spec: LawSpec) -> ModuleType:
    """The Newmark kernel (:mod:`structures.dynamics.newmark`) instantiated for the law ``spec``."""
    return specialise.instantiate(TEMPLATE, specialise.bindings(spec), spec.name)


def failure(what: str, name: str, k: int, h: float, solver: Solver, status: int) -> str:
    """The head of a :class:`ConvergenceError` message: which step of which ground motion failed
    and why (followed by the state at the step before, which the caller words)."""
    return (f"{what} {name!r}: the step to t = {k * h:.6g} s (step {k}) failed even in "
            f"{2 ** solver.max_levels} substeps: "
            f"{STATUS_MESSAGES.get(int(status), f'status {status}')}; state at t = {(k - 1) * h:.6g} s: ")


def response(name: str, time: np.ndarray, hist: Histories, energy: dict, energy_error: float,
             robust_steps: np.ndarray | None = None) -> Response:
    """The :class:`Response` of unidirectional histories (a plan direction's: ``hist.direction(d)``)."""
    extra = {} if robust_steps is None else {"robust_steps": robust_steps}
    return Response(
        record=name,
        time=time,
        isolator_disp=hist.disp[:, 0],
        isolator_force=hist.isolator_force,
        floor_disp=hist.disp[:, 1:],
        drift=hist.drift,
        drift_ratio=hist.drift_ratio,
        floor_accel_abs=hist.accel[:, 1:],
        base_accel_abs=hist.accel[:, 0],
        base_shear=hist.base_shear,
        energy=energy,
        energy_error=float(energy_error),
        newton_iterations=hist.iterations,
        subdivided_steps=np.flatnonzero(hist.levels > 0),
        **extra,
    )


def run_batch(batch, args: tuple, res, runs: int, n_blocks: int | None):
    """Run the kernel ``batch(*args, blocks, res)`` over ``runs`` parameter rows in ``n_blocks``
    parallel blocks (default: 4 per Numba thread, at most ``runs``); return ``res``."""
    if n_blocks is None:
        n_blocks = 4 * numba.get_num_threads()
    if runs:
        batch(*args, max(1, min(int(n_blocks), runs)), res)
    return res


def batch_demands(res, demands: dict[str, str], peak: tuple[str, str], counts: tuple[str, ...]) -> dict:
    """The per-run arrays of a batch's results ``res``: ``demands`` (key -> field) hold NaN for
    the runs that failed; ``peak`` (key, field) keeps every run's value (for a failed run the
    largest reached before it failed); then the ``counts``, ``status`` and ``converged``."""
    ok = res.status == 0
    out = {key: getattr(res, f).copy() for key, f in demands.items()}
    for arr in out.values():
        arr[~ok] = np.nan
    out[peak[0]] = getattr(res, peak[1])
    for c in counts:
        out[c] = getattr(res, c)
    out["status"] = res.status
    out["converged"] = ok
    return out


def time_history(
    building,
    record,
    *,
    dt: float | None = None,
    local_solver: str = "opensees",
    **newmark,
) -> Response:
    """Nonlinear time history of ``building`` under the ground acceleration ``record``.

    Newmark (``gamma``, ``beta``) with Newton-Raphson on the isolator tangent, started from rest
    (a_0 = -a_g(0) exactly); the steps are those of OpenSees' Newmark + Newton + NormDispIncr
    (see :mod:`structures.dynamics.newmark`), so with ``record.accel[0] == 0`` the result matches an
    openseespy model of the same building (``record.with_leading_zero()``).

    Parameters
    ----------
    building : :class:`structures.ShearBuilding` whose isolator has parameters.
    record : ``ground_motions.Record`` (``dt`` [s], ``accel`` [m/s^2]).
    dt : analysis step [s]; None uses the record's step, a smaller one interpolates the record
        linearly.
    **newmark : ``gamma``, ``beta`` (0.5, 0.25), ``tol`` (Newton convergence on ||du||_2 [m],
        OpenSees NormDispIncr; 1e-12), ``max_iter`` (Newton iterations per (sub)step before the
        step is subdivided; 50), ``max_subdivisions`` (a failing step is retried in 2, 4, ...
        2^max_subdivisions substeps; 6): :func:`solver_settings`.
    local_solver : ``"opensees"`` (default): the isolator law's own OpenSees local iteration.
        ``"robust"`` (Bouc-Wen; see :func:`rrfrei.simulate_force`): at the last subdivision level
        only, i.e. where the default would raise, a failed (or falsely converged) OpenSees local
        iteration is replaced by the bracketed safeguarded Newton solve of the same equation.
        The response is the default one wherever the default completes; the output steps where
        the robust solve
        acted are ``Response.robust_steps`` and are named by a
        :class:`rrfrei.simulate.LocalSolverDeviation` warning.

    Raises
    ------
    ValueError : bad building, record (non-finite values), dt or options.
    ConvergenceError : a step failed at every subdivision; names the record, time and state.
    """
    spec, chain = _model(building)
    solver = solver_settings(robust_local_solve(spec, local_solver), **newmark)
    iso = building.isolator
    p = iso.packed()
    name, ag, h = _ground(record, dt)
    n, ndof = ag.size, chain.mass.size
    hist = Histories.allocate(n, ndof)
    run = kernel(spec).integrate(chain, _layer(building, p), ag, h, solver, hist)
    if run.status != 0:
        k = run.failed_step
        raise ConvergenceError(
            failure("record", name, k, h, solver, run.status)
            + f"isolator displacement {hist.disp[k - 1, 0]:.6g} m, force "
            f"{hist.isolator_force[k - 1]:.6g} kN, base shear {hist.base_shear[k - 1]:.6g} kN; law "
            f"{spec.name!r} with parameters {spec.as_dict(p)}, {iso.count} bearings, length_scale "
            f"{iso.length_scale:g}" + robust_hint(spec, run.status, solver.robust)
        )
    robust_steps = np.flatnonzero(hist.robust)
    if robust_steps.size:
        warnings.warn(deviation_warning(spec.name, robust_steps, "time step"), stacklevel=2)
    return response(name, np.arange(n) * h, hist, _energy.as_dict(hist.energy), run.energy_error,
                    robust_steps)


def time_history_batch(
    building,
    record,
    params,
    *,
    dt: float | None = None,
    n_blocks: int | None = None,
    local_solver: str = "opensees",
    **newmark,
) -> dict[str, np.ndarray]:
    """Peak demands of ``building`` under ``record`` for many isolator parameter sets.

    Runs m analyses in parallel (blocks of runs on Numba's number of threads,
    :mod:`structures.dynamics.blocks`).  Same integration as
    :func:`time_history`.

    Parameters
    ----------
    params : (m, n_params) array in the law's ``param_names`` order (law scale, before
        similitude); every row is validated by the law.
    n_blocks : number of parallel blocks (default: 4 per Numba thread, at most m).
    local_solver : as in :func:`time_history`; ``robust_steps`` counts, per run, the output steps
        where the robust solve acted (no warning is issued here).

    Returns
    -------
    dict of arrays over the m runs: ``iso_disp_peak`` [m], ``iso_disp_residual`` [m] (|u_0| at
    the end), ``iso_disp_max_abs`` [m] (= peak; for a failed run the largest reached before it
    failed), ``drift_peak`` (m, stories) [-], ``floor_acc_peak`` (m, stories) absolute
    [m/s^2], ``base_shear_peak`` [kN], ``iso_energy``
    (isolator work at the end) [kN m], ``energy_error`` [-], ``subdivided_steps``,
    ``robust_steps``, ``status``
    (0 = converged) and ``converged`` (bool).  Runs that failed hold NaN demands.
    """
    spec, chain = _model(building)
    solver = solver_settings(robust_local_solve(spec, local_solver), **newmark)
    name, ag, h = _ground(record, dt)
    P = param_rows(spec, params)
    res = run_batch(kernel(spec).batch, (chain, _layer(building, first_row(P)), P, ag, h, solver),
                    Batch.allocate(P.shape[0], chain.mass.size - 1), P.shape[0], n_blocks)
    return batch_demands(res, {"iso_disp_peak": "iso_disp_peak", "iso_disp_residual": "iso_disp_residual",
                               "drift_peak": "drift_peak", "floor_acc_peak": "accel_peak",
                               "base_shear_peak": "base_shear_peak", "iso_energy": "iso_work",
                               "energy_error": "energy_error"},
                         ("iso_disp_max_abs", "iso_disp_peak"), ("subdivided_steps", "robust_steps"))


def first_row(P: np.ndarray) -> np.ndarray:
    """The first parameter row of ``P`` (zeros when it has none): a batch's layer, whose
    parameters the batch kernel replaces by each row."""
    return P[0] if P.shape[0] else np.zeros(P.shape[1])


def param_rows(spec: LawSpec, params) -> np.ndarray:
    """``params`` as a contiguous (m, p) float array of parameter sets of law ``spec`` (one set
    may be given as a 1-D array), each row validated by ``spec.pack``; ValueError naming the
    expected shape or the row and the parameter."""
    P = np.asarray(params, dtype=float)
    if P.ndim == 1:
        P = P[None, :]
    if P.ndim != 2 or P.shape[1] != len(spec.param_names):
        raise ValueError(
            f"params must be an (m, {len(spec.param_names)}) array for law {spec.name!r} "
            f"({', '.join(spec.param_names)}), got shape {P.shape}"
        )
    for r in range(P.shape[0]):
        try:
            spec.pack(P[r])
        except ValueError as exc:
            raise ValueError(f"params row {r}: {exc}") from None
    return np.ascontiguousarray(P)
