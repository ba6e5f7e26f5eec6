"""The PRF model as a gap-engine model family: :class:`RubberModel` and its optimum :class:`RubberFit`.

PRF fits are optimizer fits (CMA-ES from :mod:`rubber.fit`, then bounded least squares) with a
Laplace approximation at the optimum: in the unit coordinates ``z`` of the search, covariance
``(J^T J / s^2 + I)^-1`` (``J`` the Jacobian of the weighted residuals, ``s^2`` their variance, the
unit ridge a standard-normal prior on the box's scale), from which :data:`DRAWS` parameter sets are
drawn.  The model is a :class:`rrfrei.gap.GapModel` the one engine (:func:`rrfrei.gap.diagnose`)
scores like the isolator and the building models: per-draw log-likelihoods for its leave-one-out
and block rule, predictions with a band.  Units: MPa, s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm as _norm

from rrfrei.errors import NumericalFailure
from rrfrei.gap.fitting import laplace_cov, laplace_factor
from rrfrei.gap.model import LEVEL, FitResult, GapModel, Prediction, white_noise
from rubber import integrate as _k
from rubber.fit import (
    _EVAL_ERRORS,
    DEFAULT_FIXED,
    FAIL_F,
    _resolve_bounds,
    _run_cma,
    _Space,
)
from rubber.gap.effects import EFFECTS, augmented_stress, effect_values
from rubber.gap.kernels import augmented_nominal
from rubber.io import Test
from rubber.polish import least_squares_best
from rubber.prf import PARAM_NAMES, PRFParams

__all__ = ["RubberFit", "RubberModel"]

LSQ_EVALS_PER_DIM2 = 20
"""Evaluation budget of one least-squares run: 20 (1 + k)^2 model evaluations for k unknowns
(about ten Gauss-Newton iterations with their Jacobians).  ``max_nfev`` alone does not count the
Jacobian's evaluations, and with slow (stiff) parameter sets a run could otherwise go on for an
hour; the best point evaluated is returned."""
Z_BAND = float(_norm.ppf(0.5 + LEVEL / 2))  # 1.96 for LEVEL = 0.95
DRAWS = 40
"""Laplace draws of a fit (each one a PRF simulation per test when predicting)."""




def _tests(data) -> list[Test]:
    ts = [data] if isinstance(data, Test) else list(data)
    if not ts or not all(isinstance(t, Test) for t in ts):
        raise ValueError(f"data = {type(data).__name__}: expected a rubber.Test or a list of them")
    return ts


@dataclass(frozen=True)
class RubberFit(FitResult):
    """Optimum of a PRF model (with effects) fitted to uniaxial tests, and its Laplace draws.

    ``predict`` returns the optimum's prediction with a band of +- 1.96 sqrt(``sigma``^2 + the draws'
    variance) (``sigma`` the RMS residual on the calibration data); ``loglik`` is the Gaussian log
    density of each draw (rows; the optimum alone when there are no draws).  ``rss`` is the
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
    draws: tuple = ()  # ((PRFParams, effect params), ...): Laplace draws; () = the optimum only
    ess: float = float("nan")  # importance effective sample size of the draws (of DRAWS)
    notes: list = field(default_factory=list, compare=False, repr=False)  # rrfrei.notes.Note
    _memo: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def note(self) -> str:
        """The fit's notes joined (the gap engine reports them with the most severe severity)."""
        return "; ".join(str(n) for n in self.notes)

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

    def draw_stress(self, data) -> np.ndarray:
        """(S, n) nominal stress (MPa) of each Laplace draw (the optimum alone without draws);
        a draw the integrator cannot follow gives the optimum's stress (counted in ``failed_draws``)."""
        tests = _tests(data)
        key = tuple(id(t) for t in tests)
        if key not in self._memo:
            f0 = self.stress(tests)
            rows, failed = [], 0
            for prf, ep in self.draws:
                try:
                    f = np.concatenate([augmented_stress(prf, t.time, t.stretch, ep, rtol=self.rtol)
                                        for t in tests])
                    ok = np.all(np.isfinite(f))
                except (*_EVAL_ERRORS, ValueError, RuntimeError):
                    ok = False
                failed += not ok
                rows.append(f if ok else f0)
            if failed:
                text = (f"PRF model {self.name!r} on {', '.join(t.name for t in tests)}: {failed} of "
                        f"{len(self.draws)} Laplace draws failed in the integrator; the band uses the "
                        "optimum's stress in their place")
                self.add_note(text, "critical" if 2 * failed > len(self.draws) else "warning")
            # the tests are kept so that their ids stay theirs
            self._memo[key] = (np.array(rows) if rows else f0[None, :], failed, tests)
        return self._memo[key][0]

    def failed_draws(self, data) -> int:
        """How many Laplace draws the integrator could not follow on ``data``."""
        self.draw_stress(data)
        return self._memo[tuple(id(t) for t in _tests(data))][1]

    def predict(self, data) -> Prediction:
        f = self.stress(data)
        d = self.draw_stress(data)
        h = Z_BAND * np.sqrt(self.sigma**2 + (d.var(axis=0) if d.shape[0] > 1 else 0.0))
        return Prediction(mean=f, lower=f - h, upper=f + h, draws=d, sigma=np.full(d.shape[0], self.sigma))

    def loglik(self, data) -> np.ndarray:
        y = np.concatenate([t.stress for t in _tests(data)])
        r = y[None, :] - self.draw_stress(data)
        s = self.sigma
        return -0.5 * (r / s) ** 2 - math.log(s) - 0.5 * math.log(2 * math.pi)


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

    @property
    def candidate_effects(self) -> tuple[str, ...]:
        """The effects :func:`rrfrei.gap.diagnose` tries on this model: the PRF catalogue
        (:data:`rubber.gap.EFFECTS`), not the isolator laws'."""
        return tuple(EFFECTS)

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
    def fit(self, data, *, seed: int = 0,
            start: FitResult | Sequence[FitResult] | None = None) -> RubberFit:
        """Optimum of the PRF (and effect) parameters on ``data`` (a Test or list of Tests), from
        the global search or, given ``start`` (a RubberFit or several, as the gap engine passes
        them), by least squares from each start's PRF parameters (and effect parameters it has)."""
        tests = _tests(data)
        space = _Space(tuple(n for n in PARAM_NAMES if n not in self.fixed),
                       _resolve_bounds(self.bounds, tests), self.fixed)
        eff = [(e, i) for e in self.effects for i in range(len(EFFECTS[e].params))]
        if start is not None:
            given = [start] if isinstance(start, FitResult) else list(start)
            if not given or not all(isinstance(f, RubberFit) for f in given):
                kinds = sorted({type(f).__name__ for f in given}) or ["empty"]
                raise ValueError(f"start = {', '.join(kinds)}: expected a RubberFit or a list of them")
            base_x = [_x_of(space, f.prf) for f in given]
            known = {k: v for f in given for k, v in f.effect_params.items()}
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
        draws, ess = self._laplace_draws(space, eff, tests, z, float(rss), int(n), seed)
        return RubberFit(name=self.name, prf=prf, effect_params=ep, sigma=float(np.sqrt(np.mean(resid**2))),
                         noise=noise, rss=float(rss), n=int(n), k=nb + len(eff), rtol=self.rtol,
                         draws=draws, ess=ess)

    def _laplace_draws(self, space: _Space, eff, tests: list[Test], z: np.ndarray, rss: float, n: int,
                       seed: int) -> tuple[tuple, float]:
        """:data:`DRAWS` parameter sets from the Laplace approximation at the optimum ``z`` (unit
        coordinates) corrected by importance sampling, and the importance effective sample size.

        Proposal: covariance (J^T J / s^2 + I)^-1 (:func:`rrfrei.gap.fitting.laplace_cov`, drawn
        through :func:`~rrfrei.gap.fitting.laplace_factor`), J by forward differences (step 1e-6,
        taken inward at a bound), s^2 = rss / (n - k); draws outside the box are clipped to it,
        draws the PRF model rejects are redrawn (at most 20 DRAWS tries).  Each draw is weighted by the exact
        Gaussian likelihood exp(-rss(z) / 2 s^2) over the proposal density, and DRAWS equally
        weighted draws are resampled (systematic resampling).  The PRF model is far from linear in
        its parameters: an ESS of a few draws says that the posterior is much narrower than the
        Laplace proposal, and the band then rests on the residual scale ``sigma``."""
        k, nb = z.size, len(space.free)
        resid = self._residuals(space, eff, tests)
        r0 = resid(z)
        J = np.empty((r0.size, k))
        for j in range(k):
            h = 1e-6 if z[j] + 1e-6 <= 1.0 else -1e-6
            zj = z.copy()
            zj[j] += h
            J[:, j] = (resid(zj) - r0) / h
        s2 = rss / max(n - k, 1)
        if not s2 > 0.0:
            return (), float("nan")
        try:
            cov, _ = laplace_cov(J, s2, k, f"rubber model {self.name!r}")
        except NumericalFailure:  # a non-finite Jacobian: no draws, the band rests on sigma
            return (), float("nan")
        L = laplace_factor(cov)
        rng = np.random.default_rng([int(seed), 0x52554242])
        zs, log_w = [], []
        for _ in range(20 * DRAWS):
            if len(zs) == DRAWS:
                break
            u = rng.standard_normal(k)
            zd = np.clip(z + L @ u, 1e-9, 1 - 1e-9)
            try:
                space.params(zd[:nb])
            except ValueError:
                continue
            rd = resid(zd)  # importance weight: exact Gaussian likelihood over the Laplace density
            log_w.append(-0.5 * float(rd @ rd) / s2 + 0.5 * float(u @ u))
            zs.append(zd)
        if not zs:
            return (), float("nan")
        lw = np.array(log_w)
        w = np.exp(lw - lw.max())
        w /= w.sum()
        ess = float(1.0 / np.sum(w**2))
        # sampling-importance-resampling (systematic): equally weighted draws for the engine
        idx = np.minimum(np.searchsorted(np.cumsum(w), (rng.random() + np.arange(DRAWS)) / DRAWS),
                         len(zs) - 1)
        out = []
        for i in idx:
            zd = zs[int(i)]
            out.append((space.params(zd[:nb]),
                        {EFFECTS[e].params[j]: _from_unit(e, j, v) for (e, j), v in zip(eff, zd[nb:])}))
        return tuple(out), ess

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

    def _residuals(self, space: _Space, eff, tests: list[Test]):
        """z -> residuals weighted as :func:`rubber.objective` (each test by its RMS stress); a
        point the integrator cannot follow gives large residuals, never an exception."""
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

        return _resid

    def _lsq(self, space: _Space, eff, tests: list[Test], z0: np.ndarray) -> tuple[np.ndarray, float]:
        _resid = self._residuals(space, eff, tests)
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
