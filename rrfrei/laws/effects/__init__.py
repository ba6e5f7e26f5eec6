"""Augmentations ("effects") that wrap any base law's step kernel: the effect table.

An augmented law ``base+effect[+effect...]`` has the base law's parameters followed by each
effect's parameters, and the base state followed by each effect's state.  Its step kernel is an
instance of the template :mod:`rrfrei.laws.effects._augment` bound to the base law's step and to
each effect's kernel with its parameter and state offsets (:func:`compose`), so it has the plain
step signature of a law (:mod:`rrfrei.laws.registry`) and runs everywhere a law runs.  The
effects are the catalogue of unmodelled phenomena of the gap diagnosis (issue 7); each carries
its own screening and fitting hints (:class:`DiagnosisHints`), which :mod:`rrfrei.gap.catalogue`
reads from this table.

One effect is one module of this package that registers one :class:`EffectSpec`
(:func:`register_effect`); the modules are found when the package is imported, so adding an
effect edits no other file.

Composition (independent of the order in which effects are named)
-----------------------------------------------------------------
With ``f_b, k_b`` the base law's force and tangent at the displacement it sees::

    F = g(u, history) f_b + f_a(u, v)          (scaling effects g, additive effects f_a)
    K = g k_b + f_b dg/du + df_a/du

``g`` is the product of the scaling effects and ``f_a`` the sum of the additive ones; both are
accumulated by each effect's ``apply`` kernel, in the order the effects are named.  A *series*
effect (``slip``) puts a rigid-plastic slider of capacity ``capacity(p)`` in series with the whole
of that: the inner law sees ``u - u_s``.  Every effect is the base law exactly at its neutral
parameters (``EffectSpec.neutral``).

Kernels of an effect module
---------------------------
* an inner effect: ``apply(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka) -> (g, dg, fa, ka)``,
  with ``po`` / ``so`` the offsets of its parameters in ``p`` and of its state in ``sc``/``st``,
  ``fb, kb`` the base force [kN] and tangent [kN/m] (an effect that scales by a function of the
  base force, ``g(f_b)``, needs ``kb`` for its derivative ``dg/du = g'(f_b) k_b``), ``g, dg`` the
  scaling so far and its derivative [1/m], ``fa, ka`` the additive force [kN] and tangent [kN/m]
  so far; it writes its trial state into ``st``;
* a series effect: ``capacity(p, po, sc, so) -> F_s`` [kN], the slider's capacity, which may
  read the slider's committed state ``sc[so:]``; its first state variable (at ``so``) is the
  slider displacement u_s [m], its second, if it has two, the slip travel since the slider last
  stuck [m] (kept by the template: it grows by ``|du_s|`` in a step that slides and is 0 after a
  step that sticks); optionally ``stick(p, po) -> y_s`` [m], the slider's stick displacement (an
  elastic-plastic slider of stick stiffness ``F_s / y_s``, u_s its plastic slip; 0 or no
  ``stick`` kernel: rigid-plastic);
* optionally, beside an inner effect's ``apply``, a series elastic *slack* element:
  ``compliance(p, pc, F) -> (x_s, dx_s/dF)``, the element's deformation [m] as an increasing,
  bounded function of the force it carries (``|x_s| < p[pc]``, its travel; travel 0: no
  element, the law bit for bit without it), with ``pc = po + compliance_param``; its state is
  the effect's last three state variables: the element's deformation, the total displacement at
  which it was committed and its rate ``dx_s/du`` there (the predictor of the next step's solve).
  The whole law (inner law and slider) is in series with it
  (:func:`rrfrei.laws.effects._augment._slack`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rrfrei.laws.registry import LawSpec, ParamSpec, add_entry, import_entries

__all__ = ["DiagnosisHints", "EffectSpec", "Variant", "EFFECTS", "MAX_EFFECTS", "SLIP_NEVER", "compose",
           "register_effect"]

MAX_EFFECTS = 4
"""Most effects one augmented law combines (the positions of the template)."""

TEMPLATE = "rrfrei.laws.effects._augment"


@dataclass(frozen=True)
class Variant:
    """A second way the gap diagnosis fits an effect: more of its shape parameters free.

    The diagnosis fits an effect as its :class:`DiagnosisHints` say (the *primary* fit) and, for
    each variant, again with the variant's ``starts``, ``scales`` and ``box`` in their place (an
    optional parameter is fitted when ``scales`` names it); the variant stands for the effect only
    when it beats the primary fit by the diagnosis's own block rule (on the held-out blocks, or on
    the calibration test without held-out data), so the wider shape is taken when the data ask for
    it and not because it can bend further (:func:`rrfrei.gap.diagnose.diagnose`).

    Attributes
    ----------
    name : short label (``"cycles"``), shown as ``effect (name)`` in reports.
    description : the physics of the variant in one line.
    starts, scales, box : as in :class:`DiagnosisHints` (the variant's whole set, not a patch).
    """

    name: str
    description: str
    starts: Callable
    scales: Callable
    box: Callable = field(default=lambda s: {})


@dataclass(frozen=True)
class DiagnosisHints:
    """How the gap diagnosis screens and fits an effect (:mod:`rrfrei.gap`).

    ``s`` below is the test's data scales (``force`` [kN], ``disp`` [m], ``vel`` [m/s],
    ``energy`` [kN m]: :class:`rrfrei.gap.catalogue.Scales`) and ``ctx`` the baseline residuals
    and regressors (:class:`rrfrei.gap.catalogue.ScreenContext`).

    Attributes
    ----------
    screen : ``screen(ctx) -> float``, a signature score in [0, 1] (NaN: cannot be judged), e.g.
        the partial correlation of the residual with the effect's tell-tale regressor
        (:mod:`rrfrei.laws.effects._screens`).
    starts : ``starts(s) -> [dict]``, a few starting values of the parameters for the refit.
    scales : ``scales(s) -> dict``, the typical size of each parameter (conditioning).
    box : ``box(s) -> dict``, the refit's search box inside the physical bounds (default: those).
    needs_time : the effect can only be judged on a test with real time (velocities).
    order : position in the diagnosis's catalogue (its tables and tie-breaks).
    variants : further ways to fit the effect (:class:`Variant`), tried after the primary fit.
    """

    screen: Callable
    starts: Callable
    scales: Callable
    box: Callable = field(default=lambda s: {})
    needs_time: bool = False
    order: int = 100
    variants: tuple[Variant, ...] = ()


@dataclass(frozen=True)
class EffectSpec:
    """An effect: its parameters, state size, a one-line physical meaning and its kernel.

    ``neutral`` holds the parameter values at which the augmented law is the base law exactly.
    Exactly one of ``apply`` (an inner effect: scaling or additive) and ``capacity`` (a series
    rigid-plastic slider, one state variable) is given; see the package docstring.  ``hints``
    makes the effect a candidate of the gap diagnosis (:class:`DiagnosisHints`).  ``memory``: the
    state holds a damage history (a largest past displacement, a cumulative work) that a rest
    long against the loading lets the rubber recover (Mullins 1948, "Studies in the absorption of
    energy by rubber", J. Rubber Res. 17: softening recovers with time at rest; Thompson et al.
    2000, scragged bearings recover part of their virgin stiffness), so a model of runs separated
    by rests may start each run from the virgin state of such an effect.
    """

    name: str
    params: tuple[ParamSpec, ...]
    state_size: int
    description: str
    neutral: tuple[float, ...] = ()
    apply: Callable | None = field(default=None, compare=False, repr=False)
    capacity: Callable | None = field(default=None, compare=False, repr=False)
    hints: DiagnosisHints | None = field(default=None, compare=False, repr=False)
    compliance: Callable | None = field(default=None, compare=False, repr=False)
    compliance_param: int = 0
    stick: Callable | None = field(default=None, compare=False, repr=False)
    memory: bool = False

    def __post_init__(self) -> None:
        if (self.apply is None) == (self.capacity is None):
            raise ValueError(
                f"effect {self.name!r}: give exactly one kernel, apply (inner effect) or capacity "
                "(series slider)"
            )
        if self.capacity is not None and self.state_size not in (1, 2):
            raise ValueError(
                f"effect {self.name!r}: a series slider has state_size 1 (its displacement) or 2 "
                f"(and its slip travel since it last stuck), got {self.state_size}"
            )
        if self.stick is not None and self.capacity is None:
            raise ValueError(f"effect {self.name!r}: a stick kernel belongs to a series slider")
        if self.compliance is not None and (self.apply is None or self.state_size < 3
                                            or not 0 <= self.compliance_param < len(self.params)):
            raise ValueError(
                f"effect {self.name!r}: a slack compliance belongs to an inner effect with at "
                "least three state variables (its last three: the element's deformation, the "
                "displacement it was committed at and its rate there) and a travel "
                f"parameter among its {len(self.params)}, got compliance_param "
                f"{self.compliance_param}"
            )
        if len(self.neutral) != len(self.params):
            raise ValueError(
                f"effect {self.name!r}: neutral has {len(self.neutral)} values for "
                f"{len(self.params)} parameters"
            )

    @property
    def series(self) -> bool:
        return self.capacity is not None


EFFECTS: dict[str, EffectSpec] = {}


def register_effect(spec: EffectSpec) -> EffectSpec:
    """Add an effect to the table (names are unique)."""
    return add_entry(EFFECTS, spec, "effect")


def compose(base: LawSpec, effect_names: list[str]) -> LawSpec:
    """Compose ``base`` with the named effects into a new :class:`LawSpec`."""
    from rrfrei.laws import specialise
    from rrfrei.laws.effects import _neutral

    if base.effects:
        raise ValueError(f"law {base.name!r} is already augmented")
    if len(effect_names) > MAX_EFFECTS:
        raise ValueError(f"at most {MAX_EFFECTS} effects can be combined, got {len(effect_names)}")
    if len(set(effect_names)) != len(effect_names):
        raise ValueError(f"effects repeat in {effect_names}")
    params = list(base.params)
    state = base.state_size
    init = [np.asarray(base.initial_state)]
    inner: list[tuple[EffectSpec, int, int]] = []
    series: list[tuple[EffectSpec, int, int]] = []
    for name in effect_names:
        if name not in EFFECTS:
            raise ValueError(
                f"unknown effect {name!r}; available effects: {', '.join(EFFECTS) or '(none)'}"
            )
        eff = EFFECTS[name]
        (series if eff.series else inner).append((eff, len(params), state))
        params.extend(eff.params)
        state += eff.state_size
        init.append(np.zeros(eff.state_size))
    slack = [(e, po, so) for e, po, so in inner if e.compliance is not None]
    if len(slack) > 1:
        raise ValueError(
            f"at most one slack element can be combined, got {', '.join(e.name for e, _, _ in slack)}"
        )
    if len(series) > 1:
        raise ValueError(
            f"at most one series effect can be combined, got {', '.join(e.name for e, _, _ in series)}"
        )
    name = base.name + "".join("+" + n for n in effect_names)
    binds: dict[str, object] = {"base_step": base.step, "NB": len(base.params),
                                "NS": base.state_size}
    for k in range(MAX_EFFECTS):
        eff, po, so = inner[k] if k < len(inner) else (None, 0, 0)
        binds[f"effect_{k + 1}"] = eff.apply if eff is not None else _neutral.no_effect
        binds[f"P_{k + 1}"] = po
        binds[f"S_{k + 1}"] = so
    eff, po, so = series[0] if series else (None, 0, 0)
    binds["HAS_SERIES"] = eff is not None
    binds["series_capacity"] = eff.capacity if eff is not None else _neutral.no_capacity
    binds["series_stick"] = (eff.stick if eff is not None and eff.stick is not None
                             else _neutral.no_stick)
    binds["P_SERIES"] = po
    binds["S_SERIES"] = so
    binds["SERIES_TRAVEL"] = eff is not None and eff.state_size == 2
    eff, po, so = slack[0] if slack else (None, 0, 0)
    binds["HAS_SLACK"] = eff is not None
    binds["slack_compliance"] = eff.compliance if eff is not None else _neutral.no_compliance
    binds["P_SLACK"] = po + eff.compliance_param if eff is not None else 0
    binds["S_SLACK"] = so + eff.state_size - 3 if eff is not None else 0
    kernels = specialise.instantiate(TEMPLATE, binds, name)
    # the robust local solve (``local_solver="robust"``): the same template with the base law's
    # robust step; a positive status of that step (a deviation from OpenSees) passes through the
    # effects and the series and slack solves.  A base law without a local iteration needs none
    # (the effects' own series and slack solves are bracketed already).
    if base.step_robust is not None:
        step_robust = specialise.instantiate(TEMPLATE, {**binds, "base_step": base.step_robust},
                                             name + "_robust").step
    else:
        step_robust = kernels.step

    base_check = base.check
    nb = len(base.params)

    def _check(p: np.ndarray, _c=base_check, _nb=nb) -> None:
        if _c is not None:
            _c(p[:_nb])

    return LawSpec(
        name=name,
        step=kernels.step,
        step_robust=step_robust,
        params=tuple(params),
        state_size=state,
        description=base.description + " Augmented with " + ", ".join(effect_names) + ".",
        uses_velocity=True,
        check=_check,
        effects=tuple(effect_names),
        initial_state=np.concatenate(init),
    )


import_entries(__name__, __path__)  # each module of this package registers one effect

from rrfrei.laws.effects.slip import SLIP_NEVER  # noqa: E402  (re-exported)
