"""Catalogue of unmodelled effects: metadata for fitting and signature screens.

The kernels and parameter specs live in :mod:`rrfrei.laws.effects` (every effect wraps any base
law, so ``bouc_wen+rate`` is itself a law).  Here each effect gets

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
  ============  ======================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rrfrei.laws.effects import EFFECTS

__all__ = ["EffectInfo", "CATALOGUE", "Scales", "ScreenContext", "screen_all"]


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


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return 0.0 if den == 0 else abs(float((a * b).sum()) / den)


def _partial(r: np.ndarray, x: np.ndarray, controls: list[np.ndarray]) -> float:
    """|corr| of r and x after regressing both on the controls (and a constant)."""
    C = np.column_stack([np.ones_like(r), *controls])
    br, *_ = np.linalg.lstsq(C, r, rcond=None)
    bx, *_ = np.linalg.lstsq(C, x, rcond=None)
    return _corr(r - C @ br, x - C @ bx)


def _sf(ctx: ScreenContext) -> np.ndarray:
    return np.sign(ctx.force_pred)


def _screen_degradation(ctx: ScreenContext) -> float:
    return _partial(ctx.resid * _sf(ctx), ctx.energy, [np.abs(ctx.disp)])


def _screen_mullins(ctx: ScreenContext) -> float:
    return _partial(ctx.resid * _sf(ctx), ctx.first_cycle.astype(float), [np.abs(ctx.disp)])


def _screen_rollover(ctx: ScreenContext) -> float:
    return _partial(ctx.resid * np.sign(ctx.disp), ctx.disp**2, [np.abs(ctx.disp)])


def _screen_rate(ctx: ScreenContext) -> float:
    if not ctx.has_time or not np.any(ctx.vel):
        return float("nan")
    return _partial(ctx.resid, ctx.vel, [np.sign(ctx.vel), ctx.disp])


def _screen_asymmetry(ctx: ScreenContext) -> float:
    return _partial(ctx.resid, np.abs(ctx.force_pred), [ctx.force_pred])


def _screen_slip(ctx: ScreenContext) -> float:
    a = np.abs(ctx.force_pred)
    return _partial(ctx.resid * _sf(ctx), np.maximum(a - np.quantile(a, 0.8), 0.0), [a])


@dataclass(frozen=True)
class EffectInfo:
    """Fitting and screening metadata of one catalogue effect."""

    name: str
    screen: Callable[[ScreenContext], float]
    starts: Callable[[Scales], list[dict[str, float]]]
    scales: Callable[[Scales], dict[str, float]]
    box: Callable[[Scales], dict[str, tuple[float, float]]] = lambda s: {}
    needs_time: bool = False

    @property
    def spec(self):
        return EFFECTS[self.name]

    @property
    def description(self) -> str:
        return EFFECTS[self.name].description


CATALOGUE: dict[str, EffectInfo] = {
    "degradation": EffectInfo(
        "degradation", _screen_degradation,
        lambda s: [{"deg_rate": 0.1 / s.energy}, {"deg_rate": 0.5 / s.energy}],
        lambda s: {"deg_rate": 1.0 / s.energy}, lambda s: {"deg_rate": (0.0, 100.0 / s.energy)}),
    "mullins": EffectInfo(
        "mullins", _screen_mullins, lambda s: [{"mullins": 0.1}, {"mullins": 0.3}],
        lambda s: {"mullins": 0.1}),
    "rollover": EffectInfo(
        "rollover", _screen_rollover,
        lambda s: [{"roll_k": -0.3 * s.force / s.disp, "roll_onset": 0.5 * s.disp},
                   {"roll_k": 0.3 * s.force / s.disp, "roll_onset": 0.5 * s.disp},
                   {"roll_k": -0.3 * s.force / s.disp, "roll_onset": 0.25 * s.disp}],
        lambda s: {"roll_k": s.force / s.disp, "roll_onset": s.disp},
        lambda s: {"roll_k": (-10 * s.force / s.disp, 10 * s.force / s.disp), "roll_onset": (0.0, s.disp)}),
    "rate": EffectInfo(
        "rate", _screen_rate,
        lambda s: [{"rate_c": 0.05 * s.force / s.vel}, {"rate_c": 0.2 * s.force / s.vel}],
        lambda s: {"rate_c": s.force / s.vel}, lambda s: {"rate_c": (0.0, 20 * s.force / s.vel)},
        needs_time=True),
    "asymmetry": EffectInfo(
        "asymmetry", _screen_asymmetry, lambda s: [{"asym": 0.05}, {"asym": -0.05}],
        lambda s: {"asym": 0.1}),
    "slip": EffectInfo(
        "slip", _screen_slip, lambda s: [{"slip_force": 0.9 * s.force}, {"slip_force": 0.75 * s.force}],
        lambda s: {"slip_force": s.force}, lambda s: {"slip_force": (0.2 * s.force, 2.0 * s.force)}),
}


def screen_all(ctx: ScreenContext) -> dict[str, float]:
    """Signature score of every catalogue effect (NaN: cannot be judged, e.g. rate without time,
    or its regression failed numerically: a screen is a hint and never ends a diagnosis)."""
    from rrfrei.errors import NUMERICAL_ERRORS

    out = {}
    for name, info in CATALOGUE.items():
        try:
            out[name] = float(info.screen(ctx))
        except NUMERICAL_ERRORS:
            out[name] = float("nan")
    return out
