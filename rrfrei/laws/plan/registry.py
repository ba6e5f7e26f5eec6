"""Registry of the coupled bidirectional (plan) laws: one entry per law, keyed by the name of
its unidirectional law (:mod:`rrfrei.laws.registry`), whose parameters it shares.

Kernel contract
---------------
Every plan law provides a Numba step kernel (``PlanLawSpec.step``)::

    step(p, sc, u, v, dt, st, f, k) -> status

* ``p``   float64 array of the law's parameters, in the unidirectional law's
  ``LawSpec.param_names`` order (kN, m, s);
* ``sc``  committed state (read only), float64 array of length ``PlanLawSpec.state_size``;
* ``u``   (2,) trial shear displacements [m] along the two horizontal axes (x, y);
* ``v``   (2,) trial shear velocities [m/s] (0 under static displacement control);
* ``dt``  time step since the last commit [s] (1.0 under static control, as in OpenSees);
* ``st``  trial state: on entry the previous trial, on exit the new trial state;
* ``f``   (2,) output: shear forces [kN];
* ``k``   (2, 2) output: tangent dF_i/du_j [kN/m];
* returns a status, 0 = converged, < 0 = failure (:data:`rrfrei.laws.STATUS_MESSAGES`).

A driver commits by copying ``st`` into ``sc`` once a step has converged.  Kernels that call a
plan law (the history loop :mod:`rrfrei.laws.plan._history`, the plan building's Newmark
integrator) are templates instantiated per law (:mod:`rrfrei.laws.specialise`) with the slot
``plan_step`` bound to ``PlanLawSpec.step``; in the history loop the step is carried by the
adapter :mod:`rrfrei.laws.plan._arrays`, or by the law's own carrier (``PlanLawSpec.carrier``:
its state in scalars, the same results bit for bit).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rrfrei.laws import registry as _laws


@dataclass(frozen=True)
class Carrier:
    """A plan law's local solver as the history loop carries it: the jitted module-level
    functions bound to the slots ``plan_begin``, ``plan_update``, ``plan_commit`` and
    ``plan_end`` of :mod:`rrfrei.laws.plan._history` (contracts there)."""

    begin: Callable
    update: Callable
    commit: Callable
    end: Callable


@dataclass(frozen=True)
class PlanLawSpec:
    """A coupled bidirectional law.

    Attributes
    ----------
    name : the unidirectional law's name (``rrfrei.laws.get(name)`` gives the parameters).
    step : the jitted step kernel (contract in the module docstring).
    state_size : length of the state vector.
    description : one line, with the OpenSees source it ports.
    initial_state : the virgin state (zeros when not given).
    static_calls : 1, or 2 for a law whose step starts from the trial state on entry (a local
        iteration from the trial z): the history driver then calls it twice per step, as
        OpenSees' static displacement-controlled analysis updates the element twice
        (:mod:`rrfrei.laws.plan._history`).
    settled_index : with ``static_calls = 2``, the index of a state entry that the step sets
        to 1.0 when a second call with the same displacement and committed state would
        provably return the same trial state, force and tangent (e.g. its last local iteration
        left z bit for bit unchanged), else 0.0; the history driver then skips that call.  -1:
        always call twice.
    carrier : optional, the law's local solver in the form the history loop carries it
        (:class:`Carrier`, the slots of :mod:`rrfrei.laws.plan._history`), with the same results
        as the loop with ``step`` bit for bit; ``None``: the step carried by
        :mod:`rrfrei.laws.plan._arrays`.  A law writes one to carry its state through the time
        loop in local scalars (``rrfrei.laws.plan.bouc_wen``).
    """

    name: str
    step: Callable = field(compare=False, repr=False)
    state_size: int
    description: str
    initial_state: np.ndarray = field(default=None, compare=False, repr=False)  # type: ignore[assignment]
    static_calls: int = 1
    settled_index: int = -1
    carrier: Carrier | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.static_calls not in (1, 2):
            raise ValueError(
                f"plan law {self.name!r}: static_calls must be 1 or 2, got {self.static_calls!r}"
            )
        if not (self.settled_index == -1
                or self.static_calls == 2 and 0 <= self.settled_index < self.state_size):
            raise ValueError(
                f"plan law {self.name!r}: settled_index must be -1 or, with static_calls = 2, an "
                f"index into the state (0 .. {self.state_size - 1}), got {self.settled_index!r}"
            )
        if self.initial_state is None:
            object.__setattr__(self, "initial_state", np.zeros(self.state_size))
        init = np.asarray(self.initial_state, dtype=float)
        if init.shape != (self.state_size,):
            raise ValueError(
                f"plan law {self.name!r}: initial_state has shape {init.shape}, expected "
                f"({self.state_size},)"
            )
        object.__setattr__(self, "initial_state", init)

    @property
    def law(self) -> _laws.LawSpec:
        """The unidirectional law: parameter names, units, bounds, priors, ``pack``."""
        return _laws.get(self.name)

    @property
    def opensees_element(self) -> str:
        """The OpenSees element whose coupled 3-D form the plan law ports: the unidirectional
        law's (``LawSpec.opensees``), "" for none."""
        return self.law.opensees_element

    def opensees_args(self, params: Mapping[str, float] | np.ndarray, *, orient: Sequence[float],
                      materials: Sequence[int] | None = None) -> list:
        """Arguments of ``ops.element(self.opensees_element, tag, i_node, j_node, *args)`` that
        build the law at ``params`` in a 3-D model (``-ndm 3 -ndf 6``), both shear directions
        active: the unidirectional law's argument list (:meth:`rrfrei.laws.LawSpec.opensees_args`)
        with ``ndm = 3``; ``orient`` puts local y and z (the two shear directions) along the
        plan axes."""
        return self.law.opensees_args(params, ndm=3, orient=orient, materials=materials)


_REGISTRY: dict[str, PlanLawSpec] = {}


def register(spec: PlanLawSpec) -> PlanLawSpec:
    """Add a plan law to the registry (one per unidirectional law name)."""
    return _laws.add_entry(_REGISTRY, spec, "plan law")


def _discover() -> None:
    _laws.discover("rrfrei.laws.plan")


def names() -> tuple[str, ...]:
    """Names of the laws with a bidirectional form, in :func:`rrfrei.laws.names` order."""
    _discover()
    order = {n: i for i, n in enumerate(_laws.names())}
    return tuple(sorted(_REGISTRY, key=lambda n: (order.get(n, len(order)), n)))


def get(name: str | PlanLawSpec | _laws.LawSpec) -> PlanLawSpec:
    """The plan law of ``name`` (a law name or its :class:`~rrfrei.laws.LawSpec`).

    Raises ValueError for a law without a bidirectional form (e.g. an augmented law such as
    ``bouc_wen+rate``: the gap effects are unidirectional), naming the laws that have one.
    """
    if isinstance(name, PlanLawSpec):
        return name
    key = name.name if isinstance(name, _laws.LawSpec) else name
    if not isinstance(key, str):
        raise ValueError(f"a law name must be a string, got {name!r}")
    key = key.strip()
    _discover()
    if key in _REGISTRY:
        return _REGISTRY[key]
    raise ValueError(
        f"law {key!r} has no coupled bidirectional form (an (n, 2) displacement history needs "
        f"one); laws with a bidirectional form: {', '.join(names()) or '(none)'}"
    )


NONFINITE_DISP = -5
"""Status of a whole-history driver whose displacement history holds a non-finite value, with
the first such sample as its index: the drivers scan ``disp`` before the first step (inside the
compiled call, cheaper than a numpy check before it), and ``simulate_force`` raises the ValueError
of :func:`rrfrei.simulate.as_plan_history` that names the sample and component."""

HISTORY = "rrfrei.laws.plan._history"
"""The template of the plan laws' whole-history loop (:mod:`rrfrei.laws.plan._history`)."""

ARRAYS = "rrfrei.laws.plan._arrays"
"""The template that carries an array step kernel through the loop (:mod:`rrfrei.laws.plan._arrays`)."""

_DRIVERS: dict[tuple[str, bool], tuple[PlanLawSpec, Callable]] = {}


def driver(spec: PlanLawSpec) -> Callable:
    """The law's whole-history driver (jitted): the instance of :data:`HISTORY`, the one loop,
    bound to the law's carrier (``PlanLawSpec.carrier``) where it has one, else to its step
    carried by :data:`ARRAYS` (:func:`generic_driver`):
    ``drive(p, sc, st, disp, time, use_time, substeps, force, tangent) -> (status, index)``.
    """
    return _driver(spec, spec.carrier is None)


def generic_driver(spec: PlanLawSpec) -> Callable:
    """The loop with the law's step carried by :data:`ARRAYS` (whatever ``spec.carrier``): the
    reference a law's own carrier must equal bit for bit."""
    return _driver(spec, True)


def _driver(spec: PlanLawSpec, arrays: bool) -> Callable:
    from rrfrei.laws.specialise import instantiate

    hit = _DRIVERS.get((spec.name, arrays))
    if hit is not None and hit[0] is spec:
        return hit[1]
    key = f"plan_{spec.name}"
    carrier = spec.carrier
    if arrays:
        adapter = instantiate(ARRAYS, {"plan_step": spec.step, "plan_static_calls": spec.static_calls,
                                       "plan_settled_index": spec.settled_index}, key)
        carrier = Carrier(adapter.begin, adapter.update, adapter.commit, adapter.end)
    bindings = {"plan_begin": carrier.begin, "plan_update": carrier.update,
                "plan_commit": carrier.commit, "plan_end": carrier.end}
    drive = instantiate(HISTORY, bindings, key).drive
    _DRIVERS[(spec.name, arrays)] = (spec, drive)
    return drive
