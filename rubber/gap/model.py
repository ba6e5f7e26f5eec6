"""The PRF model as a gap-engine model family: :class:`RubberModel` and its optimum :class:`RubberFit`.

PRF fits are optimizer fits (CMA-ES from :mod:`rubber.fit`, then bounded least squares) without a
posterior; the model keeps the engine's interface (:class:`rrfrei.gap.GapModel`).  Units: MPa, s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm as _norm

from rrfrei.gap.model import LEVEL, FitResult, GapModel, Prediction, white_noise
from rubber import integrate as _k
from rubber.fit import (
    _EVAL_ERRORS,
    DEFAULT_FIXED,
    FAIL_F,
    _resolve_bounds,
    _run_cma,
    _Space,
    least_squares_best,
)
from rubber.gap.effects import EFFECTS, augmented_stress, effect_values
from rubber.gap.kernels import augmented_nominal
from rubber.io import Test
from rubber.prf import PARAM_NAMES, PRFParams

__all__ = ["RubberFit", "RubberModel"]

LSQ_EVALS_PER_DIM2 = 20
"""Evaluation budget of one least-squares run: 20 (1 + k)^2 model evaluations for k unknowns
(about ten Gauss-Newton iterations with their Jacobians).  ``max_nfev`` alone does not count the
Jacobian's evaluations, and with slow (stiff) parameter sets a run could otherwise go on for an
hour; the best point evaluated is returned."""
Z_BAND = float(_norm.ppf(0.5 + LEVEL / 2))  # 1.96 for LEVEL = 0.95




def _tests(data) -> list[Test]:
    ts = [data] if isinstance(data, Test) else list(data)
    if not ts or not all(isinstance(t, Test) for t in ts):
        raise ValueError(f"data = {type(data).__name__}: expected a rubber.Test or a list of them")
    return ts


@dataclass(frozen=True)
class RubberFit(FitResult):
    """Optimum of a PRF model (with effects) fitted to uniaxial tests; no posterior.

    ``predict`` returns the optimum's prediction with a band of +- 1.96 ``sigma`` (the RMS residual on
    the calibration data); ``loglik`` is the Gaussian log density at the optimum.  ``rss`` is the
    weighted residual sum of squares of :func:`rubber.objective` (sum over tests of
    sum (s_exp - s_pred)^2 / sum s_exp^2), ``n`` data points, ``k`` free parameters.
    """

    name: str
    prf: PRFParams
    effect_params: dict
    sigma: float
    noise: float
    rss: float
    n: int
    k: int
    rtol: float = 1e-6

    @property
    def params(self) -> dict[str, float]:  # type: ignore[override]
        return {**self.prf.as_dict(), **self.effect_params}

    @property
    def bic(self) -> float:
        """n ln(rss / n) + k ln n: Gaussian residuals, sd proportional to each test's RMS stress."""
        return self.n * math.log(self.rss / self.n) + self.k * math.log(self.n)

    @property
    def aic(self) -> float:
        return self.n * math.log(self.rss / self.n) + 2 * self.k

    def stress(self, data) -> np.ndarray:
        """Predicted nominal stress (MPa) at the optimum, concatenated over the tests."""
        return np.concatenate([augmented_stress(self.prf, t.time, t.stretch, self.effect_params,
                                                rtol=self.rtol) for t in _tests(data)])

    def predict(self, data) -> Prediction:
        f = self.stress(data)
        h = Z_BAND * self.sigma
        return Prediction(mean=f, lower=f - h, upper=f + h, draws=f[None, :], sigma=np.array([self.sigma]))

    def loglik(self, data) -> np.ndarray:
        y = np.concatenate([t.stress for t in _tests(data)])
        r = y - self.stress(data)
        s = self.sigma
        return (-0.5 * (r / s) ** 2 - math.log(s) - 0.5 * math.log(2 * math.pi))[None, :]


class RubberModel(GapModel):
    """The three-chain PRF model, optionally with catalogue effects, fitted by optimisation.

    Parameters
    ----------
    effects : catalogue effects (:data:`EFFECTS`) added to the PRF model (name ``prf+mullins``).
    fixed : PRF parameters held fixed (default ``rubber.fit.DEFAULT_FIXED``: C2 = -1, xi = 5e-3).
    bounds : None, "auto" or a dict name -> (lo, hi), as :func:`rubber.fit`.
    start : PRF parameters the first CMA-ES run (or, with ``max_evals = 0``, the least squares) starts at.
    restarts, max_evals : CMA-ES runs and evaluations per run of the baseline's global search
        (``max_evals = 0``: least squares from ``start`` only).
    rtol : integrator tolerance during the search.

    Fit: baseline = CMA-ES (``rubber.fit``'s search space and runner) then bounded least squares
    (trust-region reflective) in the same [0, 1] coordinates; augmented = least squares over the PRF
    and effect parameters from the baseline optimum combined with each effect start (and neutral).
    """

    def __init__(self, effects: Sequence[str] = (), *, fixed: Mapping[str, float] | None = None,
                 bounds=None, start: PRFParams | None = None, restarts: int = 2, max_evals: int = 3000,
                 rtol: float = 1e-6) -> None:
        effects = tuple(effects)
        for e in effects:
            if e not in EFFECTS:
                raise ValueError(f"effect {e!r}: expected one of {sorted(EFFECTS)}")
        if len(set(effects)) != len(effects):
            raise ValueError(f"effects = {effects!r}: expected each effect once")
        self.effects = effects
        self.fixed = dict(DEFAULT_FIXED if fixed is None else fixed)
        for n in self.fixed:
            if n not in PARAM_NAMES:
                raise ValueError(f"fixed: unknown parameter {n!r} (expected one of {PARAM_NAMES})")
        if "xi" not in self.fixed:
            raise ValueError("fixed: 'xi' must be fixed (it is not identifiable)")
        if start is not None and not isinstance(start, PRFParams):
            raise ValueError(f"start = {type(start).__name__}: expected PRFParams or None")
        if not isinstance(restarts, (int, np.integer)) or restarts < 1:
            raise ValueError(f"restarts = {restarts!r}: expected an integer >= 1")
        if not isinstance(max_evals, (int, np.integer)) or max_evals < 0:
            raise ValueError(f"max_evals = {max_evals!r}: expected an integer >= 0")
        if max_evals == 0 and start is None:
            raise ValueError("max_evals = 0 (least squares only) needs a start")
        self.bounds, self.start, self.restarts, self.max_evals, self.rtol = \
            bounds, start, int(restarts), int(max_evals), float(rtol)

    @property
    def name(self) -> str:  # type: ignore[override]
        return "+".join(("prf", *self.effects))

    def augment(self, effects: Sequence[str]) -> RubberModel:
        return RubberModel((*self.effects, *[e for e in effects if e not in self.effects]), fixed=self.fixed,
                           bounds=self.bounds, start=self.start, restarts=self.restarts,
                           max_evals=self.max_evals, rtol=self.rtol)

    def observed(self, data) -> np.ndarray:
        return np.concatenate([np.asarray(t.stress, dtype=float) for t in _tests(data)])

    def groups(self, data) -> np.ndarray:
        """Loading cycles: a new group starts at every local minimum of the stretch (holds ignored)."""
        out, g0 = [], 0
        for t in _tests(data):
            g = np.zeros(t.stretch.size, dtype=np.int64)
            cur, prev = 0, 0.0
            for j, dl in enumerate(np.diff(t.stretch), start=1):
                if dl != 0.0:
                    if prev < 0.0 < dl:
                        cur += 1
                    prev = dl
                g[j] = cur
            out.append(g0 + g)
            g0 += cur + 1
        return np.concatenate(out)

    # --- fitting ---------------------------------------------------------------------------
    def fit(self, data, *, seed: int = 0, start: FitResult | None = None) -> RubberFit:
        """Optimum of the PRF (and effect) parameters on ``data`` (a Test or list of Tests)."""
        tests = _tests(data)
        space = _Space(tuple(n for n in PARAM_NAMES if n not in self.fixed),
                       _resolve_bounds(self.bounds, tests), self.fixed)
        eff = [(e, i) for e in self.effects for i in range(len(EFFECTS[e].params))]
        if start is not None:
            if not isinstance(start, RubberFit):
                raise ValueError(f"start = {type(start).__name__}: expected a RubberFit")
            base_x = [_x_of(space, start.prf)]
            known = dict(start.effect_params)
        else:
            base_x, known = self._global(space, tests, seed), {}
        starts = [[]]
        for e in self.effects:
            ef = EFFECTS[e]
            if all(p in known for p in ef.params):
                opts = [tuple(known[p] for p in ef.params)]
            else:
                opts = [ef.neutral, *ef.starts]
            starts = [s0 + list(o) for s0 in starts for o in opts]
        nb = len(space.free)
        best = None
        for xb in base_x:
            for es in starts:
                z0 = np.concatenate([xb, [_to_unit(e, i, v) for (e, i), v in zip(eff, es)]])
                z0 = np.clip(z0, 1e-9, 1 - 1e-9)
                sol = self._lsq(space, eff, tests, z0)
                if best is None or sol[1] < best[1]:
                    best = sol
        z, rss = best
        prf = space.params(z[:nb])
        ep = {EFFECTS[e].params[i]: _from_unit(e, i, v) for (e, i), v in zip(eff, z[nb:])}
        n = sum(t.time.size for t in tests)
        resid = np.concatenate([t.stress - augmented_stress(prf, t.time, t.stretch, ep, rtol=self.rtol)
                                for t in tests])
        noise = float(np.sqrt(np.mean([white_noise(t.stress - augmented_stress(
            prf, t.time, t.stretch, ep, rtol=self.rtol)) ** 2 for t in tests])))
        return RubberFit(name=self.name, prf=prf, effect_params=ep, sigma=float(np.sqrt(np.mean(resid**2))),
                         noise=noise, rss=float(rss), n=int(n), k=nb + len(eff), rtol=self.rtol)

    def _global(self, space: _Space, tests: list[Test], seed: int) -> list[np.ndarray]:
        if self.max_evals == 0:
            return [_x_of(space, self.start)]
        rng = np.random.default_rng(seed)
        x0s = [rng.uniform(0.2, 0.8, len(space.free)) for _ in range(self.restarts)]
        if self.start is not None:
            x0s[0] = _x_of(space, self.start)
        runs = [_run_cma((space, tests, x0, 0.3, 16, self.max_evals, int(seed) * 1000 + i + 1, "frobenius",
                          self.rtol, None)) for i, x0 in enumerate(x0s)]
        return [min(runs, key=lambda r: r[1])[0]]

    def _lsq(self, space: _Space, eff, tests: list[Test], z0: np.ndarray) -> tuple[np.ndarray, float]:

        nb = len(space.free)
        scale = [math.sqrt(float(np.sum(t.stress**2))) for t in tests]
        big = math.sqrt(FAIL_F / sum(t.time.size for t in tests))

        def _resid(z):
            try:
                p = space.params(z[:nb])
            except ValueError:
                return np.full(sum(t.time.size for t in tests), big)
            e = {EFFECTS[n].params[i]: _from_unit(n, i, v) for (n, i), v in zip(eff, z[nb:])}
            s, d, beta = effect_values(e)
            eq, ch = p.to_model().arrays()
            out = []
            for t, sc in zip(tests, scale):
                f = np.empty(t.time.size)
                try:  # a kernel exception (ZeroDivisionError, overflow) is a bad point, not the end
                    st = augmented_nominal(t.time, t.stretch, eq, ch, self.rtol, s, d, beta, f)
                except _EVAL_ERRORS:
                    st = -1
                if st != _k.OK or not np.all(np.isfinite(f)):
                    out.append(np.full(t.time.size, big))
                else:
                    out.append((t.stress - f) / sc)
            return np.concatenate(out)

        k = z0.size
        budget = LSQ_EVALS_PER_DIM2 * (1 + k) ** 2  # evaluations, finite-difference Jacobians included
        z, cost, _ = least_squares_best(_resid, z0, stop=lambda n: n >= budget, x_scale=1.0, diff_step=1e-6,
                                        max_nfev=60 * (1 + k), xtol=1e-12, ftol=1e-12, gtol=1e-12)
        return z, cost


def _x_of(space: _Space, p: PRFParams) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):  # _Space.x_of takes logs of every column
        return space.x_of(p)


def _to_unit(effect: str, i: int, v: float) -> float:
    ef = EFFECTS[effect]
    lo, hi = ef.bounds[i]
    if ef.log[i]:
        return (math.log(v) - math.log(lo)) / (math.log(hi) - math.log(lo))
    return (v - lo) / (hi - lo)


def _from_unit(effect: str, i: int, x: float) -> float:
    ef = EFFECTS[effect]
    lo, hi = ef.bounds[i]
    x = min(max(float(x), 0.0), 1.0)
    v = math.exp(math.log(lo) + x * (math.log(hi) - math.log(lo))) if ef.log[i] else lo + x * (hi - lo)
    return float(min(max(v, lo), hi))  # exp(log(.)) may round past a bound
