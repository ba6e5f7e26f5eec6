"""Time histories of a shear building in plan on coupled bidirectional isolators: the public API.

:func:`plan_time_history` (one analysis under a pair of horizontal ground components, full
histories as a :class:`PlanResponse`) and :func:`plan_time_history_batch` (peak demands of many
isolator parameter sets, in parallel) validate their inputs, build the named records of
:mod:`structures.dynamics.newmark_records` (one ``Chain`` per direction) and run the kernel
:mod:`structures.dynamics.plan_newmark` instantiated for the plan law (:mod:`rrfrei.laws.plan`) by
:func:`rrfrei.laws.specialise.instantiate`.

The model: the shear building of :class:`structures.ShearBuilding` in two orthogonal horizontal
directions x and y, with the same floor masses in both and the story stiffness and damping of
``building`` (x) and of ``building_y`` (y; default: the same as x), standing on one isolator
layer whose coupled plan law makes the x and y responses interact (an isolator pushed diagonally
yields on a circle, not on a square).  **No torsion**: each floor is one lumped mass at the
centre of rigidity, with no eccentricity and no rotational degree of freedom, so the isolator's
displacement is the same under every bearing (:data:`TORSION`).  No P-Delta, no vertical motion.
Units: kN, m, s, tonnes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from rrfrei.laws import plan as plan_laws
from rrfrei.laws import specialise
from structures.building.shear_building import ShearBuilding
from structures.dynamics import energy as _energy
from structures.dynamics import plan_energy as _plan_energy
from structures.dynamics.history import (
    ConvergenceError,
    Response,
    _model,
    batch_demands,
    failure,
    first_row,
    on_step,
    param_rows,
    response,
    run_batch,
    solver_settings,
)
from structures.dynamics.newmark_records import Chain, Layer
from structures.dynamics.plan_newmark_records import PlanBatch, PlanHistories

TEMPLATE = "structures.dynamics.plan_newmark"
"""The kernel template instantiated per plan law."""

TORSION = (
    "not modelled: one lumped mass per floor at the centre of rigidity (no eccentricity, no "
    "rotational degree of freedom), so every bearing has the isolator displacement; the total "
    "maximum displacement with accidental torsion (ASCE 7-22 section 17.5.3.3) is not computed here"
)
"""What the plan building leaves out about torsion (also :attr:`PlanResponse.torsion`)."""

DIRECTIONS = ("x", "y")


@dataclass(frozen=True, eq=False)
class PlanResponse:
    """Time history of a shear building in plan on coupled isolators (arrays over the output
    times).

    Attributes
    ----------
    record : name of the ground motion (pair).
    time : (n,) [s].
    x, y : :class:`structures.Response` of each direction: isolator displacement [m] and force
        [kN] components, floor displacements [m] and absolute accelerations [m/s^2], drifts [m]
        and drift ratios [-], base shear (story 1) [kN], the direction's energy terms [kN m]
        (each direction balances on its own, :mod:`structures.dynamics.plan_energy`).
    isolator_plan_disp : (n,) isolator displacement in plan, sqrt(u_x^2 + u_y^2) [m] (the
        vector sum; the same under every bearing, no torsion).
    isolator_plan_disp_max : its maximum over time [m].
    isolator_plan_force : (n,) magnitude of the isolator layer force in plan [kN].
    energy : dict of (n,) energy histories [kN m] of the whole building (x plus y; ``isolator``
        is the line integral int F . du in plan).
    energy_error : max |imbalance| / max |input energy| of ``energy`` [-].
    newton_iterations : (n,) Newton iterations per output step (summed over substeps).
    subdivided_steps : indices of the output steps that needed substeps.
    torsion : :data:`TORSION` (torsion is not modelled).
    """

    record: str
    time: np.ndarray
    x: Response
    y: Response
    isolator_plan_disp: np.ndarray
    isolator_plan_disp_max: float
    isolator_plan_force: np.ndarray
    energy: dict
    energy_error: float
    newton_iterations: np.ndarray
    subdivided_steps: np.ndarray
    torsion: str = TORSION

    @property
    def isolator_disp(self) -> np.ndarray:
        """(n, 2) isolator displacement (x, y) [m]."""
        return np.column_stack((self.x.isolator_disp, self.y.isolator_disp))

    @property
    def isolator_force(self) -> np.ndarray:
        """(n, 2) isolator layer force (x, y) [kN]."""
        return np.column_stack((self.x.isolator_force, self.y.isolator_force))

    @property
    def base_shear_peak(self) -> np.ndarray:
        """(2,) peak |base shear| (story 1, above the isolators) in x and y [kN]."""
        return np.array([np.max(np.abs(r.base_shear)) for r in (self.x, self.y)])

    @property
    def floor_accel_abs_peak(self) -> np.ndarray:
        """(2, stories) peak |absolute floor acceleration| per direction, floor 1 first [m/s^2]."""
        return np.array([np.max(np.abs(r.floor_accel_abs), axis=0) for r in (self.x, self.y)])

    @property
    def drift_ratio_peak(self) -> np.ndarray:
        """(2, stories) peak |story drift ratio| per direction, story 1 first [-]."""
        return np.array([np.max(np.abs(r.drift_ratio), axis=0) for r in (self.x, self.y)])

    def summary(self) -> dict[str, float]:
        """Peak demands: ``isolator_plan_disp_peak`` [m] (vector sum), its residual [m], the
        peak isolator force in plan [kN], and per direction (suffix ``_x``, ``_y``) the peak
        isolator displacement [m], base shear [kN], drift ratio [-], floor and roof absolute
        accelerations [m/s^2]; isolator work in plan [kN m], energy error, steps."""
        out = {
            "isolator_plan_disp_peak": float(self.isolator_plan_disp_max),
            "isolator_plan_disp_residual": float(self.isolator_plan_disp[-1]),
            "isolator_plan_force_peak": float(np.max(self.isolator_plan_force)),
        }
        for name, r in zip(DIRECTIONS, (self.x, self.y)):
            s = r.summary()
            for key in ("isolator_disp_peak", "base_shear_peak", "drift_ratio_peak", "floor_accel_abs_peak",
                        "roof_accel_abs_peak"):
                out[f"{key}_{name}"] = s[key]
        out["isolator_work"] = float(self.energy["isolator"][-1])
        out["energy_error"] = float(self.energy_error)
        out["newton_iterations_mean"] = (
            float(np.mean(self.newton_iterations[1:])) if self.time.size > 1 else 0.0
        )
        out["subdivided_steps"] = int(self.subdivided_steps.size)
        return out


# ------------------------------------------------------------------------------ inputs
def _plan_ground(ground, dt) -> tuple[str, np.ndarray, float]:
    """(name, (n, 2) ground acceleration [m/s^2] at the analysis step, step [s])."""
    if hasattr(ground, "accel") and hasattr(ground, "dt"):
        name = str(getattr(ground, "name", "record"))
        try:
            rdt = float(ground.dt)
            acc = np.asarray(ground.accel, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"ground {name!r}: dt [s] must be a number and accel [m/s^2] an (n, 2) array of numbers"
            ) from None
        step = dt
    elif isinstance(ground, (str, bytes, Mapping)) or ground is None:
        raise ValueError(
            "ground must be an (n, 2) acceleration array [m/s^2] (with dt [s]) or a record pair "
            f"with .accel (n, 2) [m/s^2] and .dt [s], got {type(ground).__name__}"
        )
    else:
        name = "ground"
        try:
            acc = np.asarray(ground, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"ground must be an (n, 2) acceleration array [m/s^2] or a record pair (.accel, .dt), "
                f"got {type(ground).__name__}"
            ) from None
        if dt is None:
            raise ValueError("dt [s] is required with a ground acceleration array: the step of its samples")
        try:
            rdt = float(dt)
        except (TypeError, ValueError):
            raise ValueError(f"dt = {dt!r} is invalid: expected a finite number > 0 s") from None
        step = None
    if acc.ndim != 2 or acc.shape[1] != 2 or acc.shape[0] < 2:
        one = ""
        if acc.ndim == 1:
            one = " (one component: use structures.time_history, or pair it with the other)"
        raise ValueError(
            f"ground {name!r}: accel must be an (n, 2) array (x, y per sample, n >= 2) [m/s^2], "
            f"got shape {acc.shape}{one}"
        )
    return on_step("ground", name, acc, rdt, step)


def _chains(building, building_y) -> tuple[Chain, Chain]:
    """The x and y superstructures (validated: the same floors in both directions)."""
    _, cx = _model(building)
    if building_y is None:
        return cx, cx
    if not isinstance(building_y, ShearBuilding):
        raise ValueError(f"building_y must be a ShearBuilding or None, got {type(building_y).__name__}")
    for field_name in ("story_masses", "base_mass", "story_heights"):
        a, b = getattr(building, field_name), getattr(building_y, field_name)
        if a != b:
            raise ValueError(
                f"building_y.{field_name} = {b!r} differs from building.{field_name} = {a!r}: the two "
                "directions share the floors (the same masses and heights); only story_stiffness, "
                "damping_ratio and damping may differ"
            )
    if building_y.isolator != building.isolator:
        raise ValueError(
            "building_y.isolator differs from building.isolator: the isolator layer is one coupled "
            "plan law under both directions; give building_y the same isolator (e.g. "
            "dataclasses.replace(building, story_stiffness=...))"
        )
    _, cy = _model(building_y)
    return cx, cy


def _law(building, law, params) -> tuple[plan_laws.PlanLawSpec, np.ndarray]:
    """The plan law and its packed parameters (the building's isolator's when not given)."""
    if not isinstance(building, ShearBuilding):
        raise ValueError(f"building must be a ShearBuilding, got {type(building).__name__}")
    iso = building.isolator
    pspec = plan_laws.get(iso.law if law is None else law)
    if params is None:
        if pspec.name != iso.law:
            raise ValueError(
                f"params are required for law {pspec.name!r}: the building's isolator follows "
                f"{iso.law!r}, whose parameters do not apply"
            )
        return pspec, iso.packed()
    return pspec, pspec.law.pack(params)


def _layer(building, pspec, params: np.ndarray) -> Layer:
    iso = building.isolator
    return Layer(params, float(iso.count), float(iso.length_scale),
                 np.array(pspec.initial_state, dtype=float))


def kernel(pspec: plan_laws.PlanLawSpec) -> ModuleType:
    """The plan Newmark kernel (:mod:`structures.dynamics.plan_newmark`) instantiated for ``pspec``."""
    return specialise.instantiate(TEMPLATE, {"plan_step": pspec.step}, f"plan_{pspec.name}")


# ------------------------------------------------------------------------------ verbs
def plan_time_history(
    building,
    law=None,
    params=None,
    ground=None,
    *,
    building_y: ShearBuilding | None = None,
    dt: float | None = None,
    **newmark,
) -> PlanResponse:
    """Nonlinear time history of ``building`` in plan under two horizontal ground components.

    Newmark (``gamma``, ``beta``) with Newton-Raphson on the coupled isolator's 2 x 2 tangent,
    condensed onto the two base DOFs (:mod:`structures.dynamics.plan_newmark`), started from rest; the
    steps are those of OpenSees' Newmark + Newton + NormDispIncr on a 3-D lumped-mass model of the
    same building (``tests/opensees_plan_building.py``).  A ground motion along x alone gives the
    unidirectional :func:`structures.time_history` in x (bit for bit for the laws whose plan form
    reduces to the unidirectional law along an axis) and rest in y.  Torsion is not modelled
    (:data:`TORSION`).

    Parameters
    ----------
    building : :class:`structures.ShearBuilding`: floors, the x-direction stories, the isolator
        layer (``count`` bearings, ``length_scale``) and, by default, its law and parameters.
    law : plan law name (``rrfrei.laws.plan.names()``) or :class:`rrfrei.laws.plan.PlanLawSpec`;
        None: the plan form of ``building.isolator.law``.
    params : the law's parameters (mapping by name or array in its ``param_names`` order, at
        the scale it was calibrated on); None: ``building.isolator.params`` (same law only).
    ground : (n, 2) ground acceleration (x, y) [m/s^2] sampled every ``dt``, or a record pair:
        any object with ``.accel`` (n, 2) [m/s^2] and ``.dt`` [s] (and optionally ``.name``),
        such as ``ground_motions.RecordPair``.
    building_y : the y-direction superstructure (same ``story_masses``, ``base_mass``,
        ``story_heights`` and isolator; its own ``story_stiffness``, ``damping_ratio``,
        ``damping``); None: the same as x.
    dt : with an array ``ground``, the step of its samples [s] (required; the analysis runs at
        it); with a record pair, the analysis step [s] (None: the pair's; a smaller one
        interpolates both components linearly).
    **newmark : ``gamma``, ``beta``, ``tol`` (here on ||du||_2 over all 2 (stories + 1) DOFs [m]),
        ``max_iter``, ``max_subdivisions``: as :func:`structures.time_history`
        (:func:`structures.dynamics.history.solver_settings`).

    Raises
    ------
    ValueError : bad building, law, parameters, ground (names sample and component), dt or
        options.
    ConvergenceError : a step failed at every subdivision; names the record, time and state.
    """
    pspec, p = _law(building, law, params)
    chain_x, chain_y = _chains(building, building_y)
    solver = solver_settings(False, **newmark)
    name, ag, h = _plan_ground(ground, dt)
    n, ndof = ag.shape[0], chain_x.mass.size
    hist = PlanHistories.allocate(n, ndof)
    run = kernel(pspec).integrate(chain_x, chain_y, _layer(building, pspec, p), ag, h, solver, hist)
    if run.status != 0:
        k = run.failed_step
        iso = building.isolator
        raise ConvergenceError(
            failure("ground", name, k, h, solver, run.status)
            + f"isolator displacement ({hist.disp[0, k - 1, 0]:.6g}, "
            f"{hist.disp[1, k - 1, 0]:.6g}) m, force ({hist.isolator_force[0, k - 1]:.6g}, "
            f"{hist.isolator_force[1, k - 1]:.6g}) kN; plan law {pspec.name!r} with parameters "
            f"{pspec.law.as_dict(p)}, {iso.count} bearings, length_scale {iso.length_scale:g}"
        )
    time = np.arange(n) * h
    x, y = (hist.direction(d) for d in range(2))
    ex, ey = _plan_energy.by_direction(hist.energy)
    return PlanResponse(
        record=name,
        time=time,
        x=response(name, time, x, ex, _energy.balance_error(ex)),
        y=response(name, time, y, ey, _energy.balance_error(ey)),
        isolator_plan_disp=np.hypot(x.disp[:, 0], y.disp[:, 0]),
        isolator_plan_disp_max=float(run.iso_plan_disp_peak),
        isolator_plan_force=np.hypot(x.isolator_force, y.isolator_force),
        energy=_plan_energy.total(hist.energy),
        energy_error=float(run.energy_error),
        newton_iterations=hist.iterations,
        subdivided_steps=np.flatnonzero(hist.levels > 0),
    )


def plan_time_history_batch(
    building,
    law=None,
    params=None,
    ground=None,
    *,
    building_y: ShearBuilding | None = None,
    dt: float | None = None,
    n_blocks: int | None = None,
    **newmark,
) -> dict[str, np.ndarray]:
    """Peak demands of ``building`` in plan under ``ground`` for many isolator parameter sets.

    Runs m analyses in parallel (blocks of runs on threads, as
    :func:`structures.time_history_batch`), each the integration of :func:`plan_time_history`.

    Parameters
    ----------
    params : (m, n_params) array in the law's ``param_names`` order (law scale, before
        similitude), e.g. posterior draws; every row is validated by the law.  None: the
        building's isolator parameters (one run).
    n_blocks : number of parallel blocks (default: 4 per Numba thread, at most m).
    Other parameters as :func:`plan_time_history`.

    Returns
    -------
    dict of arrays over the m runs: ``iso_plan_disp_peak`` [m] (vector sum),
    ``iso_plan_disp_residual`` [m], ``iso_disp_peak`` (m, 2) per direction [m],
    ``base_shear_peak`` (m, 2) [kN], ``drift_peak`` (m, 2, stories) drift ratio [-],
    ``floor_acc_peak`` (m, 2, stories) absolute [m/s^2], ``iso_energy`` (isolator work in plan at
    the end) [kN m], ``energy_error`` [-], ``iso_plan_disp_max_abs`` [m] (= peak; for a failed
    run the largest reached before it failed), ``subdivided_steps``, ``status`` (0 = converged)
    and ``converged`` (bool).  Runs that failed hold NaN demands.
    """
    if not isinstance(building, ShearBuilding):
        raise ValueError(f"building must be a ShearBuilding, got {type(building).__name__}")
    if params is None:
        pspec, p0 = _law(building, law, None)
        P = p0[None, :]
    else:
        pspec = plan_laws.get(building.isolator.law if law is None else law)
        spec = pspec.law
        P = param_rows(spec, params)
    P = np.ascontiguousarray(P)
    chain_x, chain_y = _chains(building, building_y)
    solver = solver_settings(False, **newmark)
    _, ag, h = _plan_ground(ground, dt)
    layer = _layer(building, pspec, first_row(P))
    res = run_batch(kernel(pspec).batch, (chain_x, chain_y, layer, P, ag, h, solver),
                    PlanBatch.allocate(P.shape[0], chain_x.mass.size - 1), P.shape[0], n_blocks)
    return batch_demands(res, {"iso_plan_disp_peak": "iso_plan_disp_peak",
                               "iso_plan_disp_residual": "iso_plan_disp_residual",
                               "iso_disp_peak": "iso_disp_peak", "base_shear_peak": "base_shear_peak",
                               "drift_peak": "drift_peak", "floor_acc_peak": "accel_peak",
                               "iso_energy": "iso_work", "energy_error": "energy_error"},
                         ("iso_plan_disp_max_abs", "iso_plan_disp_peak"), ("subdivided_steps",))
