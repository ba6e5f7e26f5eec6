"""Catalogue of unmodelled effects: metadata for fitting and signature screens.

The kernels, parameter specs and these hints live in one module per effect of
:mod:`rrfrei.laws.effects` (every effect wraps any base law, so ``bouc_wen+rate`` is itself a
law; its ``hints`` are a :class:`rrfrei.laws.effects.DiagnosisHints`).  Here the table is read
into the diagnosis's catalogue; each effect has

* ``starts(scales)``: a few starting values of its parameters, from the test's force, displacement,
  velocity and energy scales, for the refit of the augmented law;
* ``scales(scales)``: the typical size of each parameter (conditioning of the least-squares fit);
* ``box(scales)``: the search box of the refit, inside the physical bounds (a slip capacity far
  above the test's forces, for example, is the base law and has no gradient);
* ``screen(ctx)``: a cheap signature score from the baseline residuals alone, a correlation in
  [0, 1] of the residual with the effect's tell-tale regressor:

  ============  ======================================================================
  degradation   r sgn(F) against cumulative dissipated energy (the force fades)
  mullins       r sgn(F) on first vs repeated cycles of an amplitude (first is stiffer)
  rollover      r sgn(u) against |u|^2 (shape changes with |u|)
  rate          r against velocity beyond the sign of velocity (needs real time)
  asymmetry     r against |F| (a scaling that is even in the force, not odd)
  slip          r sgn(F) against the excess of |F| over its 80th percentile (capped force)
  stiffening    r sgn(u) against (|u| - half the peak)_+^2, added force only (smooth stiffening)
  pinching      r sgn(F) on a band of small predicted |F| below the previous peak, force removed only
  scragging     r sgn(F) against the running peak |u| beyond |u| (permanent softening)
  ============  ======================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from rrfrei.laws.effects import EFFECTS

__all__ = ["EffectInfo", "Scales", "ScreenContext", "catalogue", "screen_all"]


@dataclass(frozen=True)
class Scales:
    """Data scales of a test: force [kN], displacement [m], velocity [m/s], work [kN m]."""

    force: float
    disp: float
    vel: float
    energy: float


@dataclass(frozen=True)
class ScreenContext:
    """Baseline residuals and the regressors the screens need (one calibration test)."""

    disp: np.ndarray
    vel: np.ndarray  # zeros without real time
    force_pred: np.ndarray
    resid: np.ndarray  # measured - predicted
    energy: np.ndarray  # cumulative dissipated energy of the measured force
    first_cycle: np.ndarray  # bool: sample in the first cycle at its amplitude level
    has_time: bool


@dataclass(frozen=True)
class EffectInfo:
    """Fitting and screening metadata of one catalogue effect."""

    name: str
    screen: Callable[[ScreenContext], float]
    starts: Callable[[Scales], list[dict[str, float]]]
    scales: Callable[[Scales], dict[str, float]]
    box: Callable[[Scales], dict[str, tuple[float, float]]] = lambda s: {}
    needs_time: bool = False
    variants: tuple = ()
    """Further ways to fit the effect (:class:`rrfrei.laws.effects.Variant`)."""
    variant: str = ""
    """The variant these hints are ("": the primary fit)."""

    def as_variant(self, name: str) -> EffectInfo:
        """These hints with the starts, scales and box of the variant ``name`` ("": unchanged)."""
        if not name:
            return self
        for v in self.variants:
            if v.name == name:
                return replace(self, starts=v.starts, scales=v.scales, box=v.box, variant=name)
        raise ValueError(f"effect {self.name!r} has no variant {name!r}; its variants: "
                         f"{', '.join(v.name for v in self.variants) or '(none)'}")

    @property
    def spec(self):
        return EFFECTS[self.name]

    @property
    def description(self) -> str:
        return EFFECTS[self.name].description


def catalogue() -> dict[str, EffectInfo]:
    """The diagnosis's candidates: every effect of the table (:data:`rrfrei.laws.effects.EFFECTS`)
    that carries diagnosis hints, in their stated order.  Read at each call, so an effect module
    registered at any time (one module, one :func:`rrfrei.laws.effects.register_effect`) is a
    candidate without editing this file."""
    out = []
    for name, eff in EFFECTS.items():
        h = eff.hints
        if h is not None:
            out.append((h.order, name, EffectInfo(name, h.screen, h.starts, h.scales, h.box, h.needs_time,
                                                   tuple(h.variants))))
    return {name: info for _, name, info in sorted(out, key=lambda t: (t[0], t[1]))}


def screen_all(ctx: ScreenContext) -> dict[str, float]:
    """Signature score of every catalogue effect (NaN: cannot be judged, e.g. rate without time,
    or its regression failed numerically: a screen is a hint and never ends a diagnosis)."""
    from rrfrei.errors import NUMERICAL_ERRORS

    out = {}
    for name, info in catalogue().items():
        try:
            out[name] = float(info.screen(ctx))
        except NUMERICAL_ERRORS:
            out[name] = float("nan")
    return out
