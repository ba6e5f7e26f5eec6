"""The catalogue of PRF gap effects and the stress of the PRF model augmented by them.

Each :class:`Effect` names its parameters with bounds, neutral values (the base model) and fit
starts; :func:`augmented_stress` evaluates the augmented model (kernels in
:mod:`rubber.gap.kernels`).  Units: MPa, s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rubber import integrate as _k
from rubber.gap.kernels import augmented_nominal
from rubber.prf import PRFModel, PRFParams, _as_model, check_history

__all__ = ["EFFECT_PARAMS", "EFFECTS", "Effect", "augmented_stress", "effect_values"]


@dataclass(frozen=True)
class Effect:
    """One catalogue effect: parameter names, bounds, neutral values and fit starts."""

    name: str
    params: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    neutral: tuple[float, ...]
    starts: tuple[tuple[float, ...], ...]
    log: tuple[bool, ...]
    meaning: str

    def __post_init__(self) -> None:
        n = len(self.params)
        if not 1 <= n <= 3 or any(len(x) != n for x in (self.bounds, self.neutral, self.log)):
            raise ValueError(f"effect {self.name!r}: expected 1-3 parameters with bounds, neutral, log each")
        for p, (lo, hi), v in zip(self.params, self.bounds, self.neutral):
            if not lo <= v <= hi:
                raise ValueError(f"effect {self.name!r}: neutral {p} = {v} outside bounds [{lo}, {hi}]")


EFFECTS: dict[str, Effect] = {
    "mullins": Effect(
        "mullins", ("d_mullins", "beta_mullins"), ((0.0, 0.95), (0.01, 2.0)), (0.0, 0.3),
        ((0.1, 0.3), (0.3, 0.1), (0.3, 0.5)), (False, True),
        "Ogden-Roxburgh damage of the equilibrium network on reloading below the previous maximum"),
    "permanent_set": Effect(
        "permanent_set", ("s_set",), ((0.0, 0.6),), (0.0,), ((0.1,), (0.3,)), (False,),
        "reference stretch of the equilibrium network lambda_p = 1 + s (lambda_max - 1)"),
}
EFFECT_PARAMS = {p: (e.name, i) for e in EFFECTS.values() for i, p in enumerate(e.params)}


def effect_values(effect_params: Mapping[str, float] | None) -> tuple[float, float, float]:
    """(s_set, d_mullins, beta_mullins), neutral where not given; ValueError naming a bad one."""
    v = {p: EFFECTS[e].neutral[i] for p, (e, i) in EFFECT_PARAMS.items()}
    for n, x in dict(effect_params or {}).items():
        if n not in EFFECT_PARAMS:
            raise ValueError(f"effect parameter {n!r}: expected one of {sorted(EFFECT_PARAMS)}")
        e, i = EFFECT_PARAMS[n]
        lo, hi = EFFECTS[e].bounds[i]
        if not (isinstance(x, (int, float)) and math.isfinite(x) and lo <= x <= hi):
            raise ValueError(f"{n} = {x!r}: expected a number in [{lo}, {hi}]")
        v[n] = float(x)
    return v["s_set"], v["d_mullins"], v["beta_mullins"]


def augmented_stress(params: PRFParams | PRFModel, time, stretch,
                     effect_params: Mapping[str, float] | None = None, *, rtol: float = 1e-6) -> np.ndarray:
    """Nominal stress (MPa) of the PRF model with catalogue effects, starting virgin.

    Parameters
    ----------
    params : PRFParams or PRFModel (any number of chains).
    time, stretch : sample times (s, strictly increasing) and stretches (piecewise linear).
    effect_params : effect parameters by name (``d_mullins``, ``beta_mullins``, ``s_set``); missing
        ones are neutral, so ``None`` gives the base model.
    rtol : integrator tolerance (as :func:`rubber.simulate`).

    Returns
    -------
    Nominal stress P = (eta Delta_Yeoh(lambda / lambda_p) + sum_k Delta_k) / lambda, MPa.
    """
    s, d, beta = effect_values(effect_params)
    t, lam = check_history(time, stretch)
    eq, ch = _as_model(params).arrays()
    out = np.empty(t.size)
    st = augmented_nominal(t, lam, eq, ch, float(rtol), s, d, beta, out)
    if st != _k.OK:
        raise ValueError(f"integration failed: {_k.STATUS_TEXT[st]}")
    return out
