"""Sim-to-real gap diagnosis for the PRF model (issue 7, point 6): which unmodelled effect explains
where a calibrated PRF model misses a held-out protocol.

The model family is a :class:`rrfrei.gap.GapModel` (:class:`RubberModel`), so the generic engine's
interface is kept; but PRF fits are optimizer fits (CMA-ES from :mod:`rubber.fit`, then bounded least
squares) without a posterior, so the engine's leave-one-cycle-out PSIS ranking does not apply.  The
ranking here (:func:`rank_effects`) uses what an optimizer fit has: an information criterion on the
calibration data and the error on held-out protocols.

Effect catalogue (:data:`EFFECTS`), both acting on the equilibrium (Yeoh) network only; the viscous
Bergstrom-Boyce chains see the total stretch as before, so the effects post-process the equilibrium
row of the PRF simulation and the augmented model is exactly the base model at neutral values.

``mullins`` (parameters ``d_mullins`` = 1/r, ``beta_mullins``): Ogden-Roxburgh damage
    Delta_A = eta Delta_A0,   eta = 1 - d erf((W_max - W) / (beta W_max)),
    W the Yeoh energy of the current (elastic) stretch, W_max its maximum over the history.
    Ogden & Roxburgh (1999), Proc. R. Soc. A 455:2861, eq. (5.4); the m = 0 member of the
    ``m + beta W_max`` denominator of Abaqus' *MULLINS EFFECT.  Reloading below the previous maximum is
    softer than virgin loading (eta < 1) and rejoins it at W = W_max.  Neutral: d = 0.
``permanent_set`` (parameter ``s_set``): the equilibrium network's reference stretch moves with the
    largest stretch reached, F = F_e F_p, lambda_p = 1 + s (lambda_max - 1), lambda_max = max(1, max
    lambda), and Delta_A = Delta_Yeoh(lambda / lambda_p).  The set grows with the maximum stretch, as
    observed for filled rubbers (Dorfmann & Ogden 2004, Int. J. Solids Struct. 41:1855; review by
    Diani, Fayolle & Gilormini 2009, Eur. Polym. J. 45:601); the linear law is our choice, the
    simplest with that property.  Neutral: s = 0.

Units: MPa, s; nominal stress P = (Delta_A + sum_k Delta_k) / lambda.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.stats import norm as _norm

from rrfrei.gap.model import LEVEL, FitResult, GapModel, Prediction, white_noise
from rrfrei.gap.residuals import gap, systematic_gap

from . import integrate as _k
from .fit import _EVAL_ERRORS, DEFAULT_FIXED, FAIL_F, _resolve_bounds, _run_cma, _Space, least_squares_best
from .io import Test
from .prf import PARAM_NAMES, PRFModel, PRFParams, _as_model, check_history

__all__ = ["Effect", "EFFECTS", "CRITERION", "MARGIN", "augmented_stress", "RubberModel", "RubberFit",
           "EffectRow", "RubberGapReport", "rank_effects"]

CRITERION = "BIC"
MARGIN = 10.0
"""An effect must lower BIC by more than this (Kass & Raftery 1995: Delta BIC > 10 is 'very strong')."""
LSQ_EVALS_PER_DIM2 = 20
"""Evaluation budget of one least-squares run: 20 (1 + k)^2 model evaluations for k unknowns
(about ten Gauss-Newton iterations with their Jacobians).  ``max_nfev`` alone does not count the
Jacobian's evaluations, and with slow (stiff) parameter sets a run could otherwise go on for an
hour; the best point evaluated is returned."""
Z_BAND = float(_norm.ppf(0.5 + LEVEL / 2))  # 1.96 for LEVEL = 0.95


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


# --- Numba kernels ---------------------------------------------------------------------------
@njit(cache=True)
def set_reference(lam, s, out):
    """lambda_p[j] = 1 + s (max(1, max_{i<=j} lambda_i) - 1): reference stretch after permanent set."""
    lmax = 1.0
    for j in range(lam.shape[0]):
        if lam[j] > lmax:
            lmax = lam[j]
        out[j] = 1.0 + s * (lmax - 1.0)


@njit(cache=True)
def mullins_factor(w, d, beta, out):
    """Ogden-Roxburgh eta[j] = 1 - d erf((W_max - W_j) / (beta W_max)), W_max the running maximum."""
    wmax = 0.0
    for j in range(w.shape[0]):
        if w[j] > wmax:
            wmax = w[j]
        if d == 0.0 or wmax <= 0.0:
            out[j] = 1.0
        else:
            out[j] = 1.0 - d * math.erf((wmax - w[j]) / (beta * wmax))


@njit(cache=True)
def equilibrium_delta(lam, eq, s, d, beta, out):
    """Delta_A (MPa) of the equilibrium Yeoh network with permanent set ``s`` and Mullins ``d, beta``."""
    m = lam.shape[0]
    lp = np.empty(m)
    set_reference(lam, s, lp)
    w = np.empty(m)
    for j in range(m):
        le = lam[j] / lp[j]
        out[j] = _k.yeoh_delta(le, eq[0], eq[1], eq[2])
        w[j] = _k.yeoh_energy(le, eq[0], eq[1], eq[2])
    eta = np.empty(m)
    mullins_factor(w, d, beta, eta)
    for j in range(m):
        out[j] = out[j] * eta[j]


@njit(cache=True)
def augmented_nominal(time, lam, eq, chains, rtol, s, d, beta, out):
    """Nominal stress of the augmented PRF model into ``out``; returns the integrator status.

    Same summation order as :func:`rubber.integrate.nominal_stress`, so neutral effect values
    (s = d = 0) give the base model bit for bit.
    """
    m = time.shape[0]
    k = chains.shape[0]
    u = np.empty((k, m))
    dch = np.empty((k + 1, m))
    diss = np.empty((k, m))
    st, na, nr = _k.simulate_kernel(time, lam, eq, chains, rtol, u, dch, diss)
    da = np.empty(m)
    equilibrium_delta(lam, eq, s, d, beta, da)
    for j in range(m):
        acc = da[j]
        for r in range(1, k + 1):
            acc += dch[r, j]
        out[j] = acc / lam[j]
    return st


# --- public evaluation -----------------------------------------------------------------------
def _effect_values(effect_params: Mapping[str, float] | None) -> tuple[float, float, float]:
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
    s, d, beta = _effect_values(effect_params)
    t, lam = check_history(time, stretch)
    eq, ch = _as_model(params).arrays()
    out = np.empty(t.size)
    st = augmented_nominal(t, lam, eq, ch, float(rtol), s, d, beta, out)
    if st != _k.OK:
        raise ValueError(f"integration failed: {_k.STATUS_TEXT[st]}")
    return out


# --- the model family ------------------------------------------------------------------------
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
            s, d, beta = _effect_values(e)
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


# --- ranking ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class EffectRow:
    """One effect's augmented fit against the baseline (gaps as NRMSE, pooled)."""

    effect: str
    model: str
    delta_bic: float
    holdout_before: float
    holdout_after: float
    systematic_calibration_before: float
    systematic_calibration_after: float
    systematic_holdout_before: float
    systematic_holdout_after: float
    shrink_calibration: float
    shrink_holdout: float
    accepted: bool
    params: dict

    def as_dict(self) -> dict:
        return {k: (_num(v) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class RubberGapReport:
    """Result of :func:`rank_effects`: diagnosis (effect name or ``none``), per-effect rows, gaps."""

    model: str
    diagnosis: str
    criterion: str
    margin: float
    rows: tuple[EffectRow, ...]
    gap_before: tuple[float, float]  # (calibration, held-out) NRMSE of the baseline
    gap_after: tuple[float, float]   # the same for the diagnosed effect (= before for "none")
    noise: tuple[float, float]       # noise level (MPa) on calibration and held-out data
    fits: dict = field(default_factory=dict, repr=False, compare=False)

    def as_dict(self) -> dict:
        return {"model": self.model, "diagnosis": self.diagnosis, "criterion": self.criterion,
                "margin": self.margin, "rows": [r.as_dict() for r in self.rows],
                "gap_before": {"calibration": _num(self.gap_before[0]), "holdout": _num(self.gap_before[1])},
                "gap_after": {"calibration": _num(self.gap_after[0]), "holdout": _num(self.gap_after[1])},
                "noise_MPa": {"calibration": _num(self.noise[0]), "holdout": _num(self.noise[1])}}

    def table(self) -> str:
        """Markdown table of the ranking (best held-out error first) and the diagnosis."""
        lines = [f"Diagnosis: **{self.diagnosis}** (rule: Delta {self.criterion} < -{self.margin:g} on the "
                 "calibration data and lower held-out NRMSE)", "",
                 f"Gap (NRMSE) before: calibration {self.gap_before[0]:.4f}, "
                 f"held-out {self.gap_before[1]:.4f}; "
                 f"after: calibration {self.gap_after[0]:.4f}, held-out {self.gap_after[1]:.4f}", "",
                 f"| effect | Delta {self.criterion} | held-out NRMSE before | after | systematic cal. "
                 "before | after | systematic held-out before | after | shrink cal. | shrink held-out "
                 "| accepted |",
                 "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows:
            lines.append(f"| {r.effect} | {r.delta_bic:.1f} | {r.holdout_before:.4f} | "
                         f"{r.holdout_after:.4f} | "
                         f"{r.systematic_calibration_before:.4f} | {r.systematic_calibration_after:.4f} | "
                         f"{r.systematic_holdout_before:.4f} | {r.systematic_holdout_after:.4f} | "
                         f"{r.shrink_calibration:.2f} | {r.shrink_holdout:.2f} | "
                         f"{'yes' if r.accepted else 'no'} |")
        return "\n".join(lines)


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _shrink(before: float, after: float) -> float:
    return 1.0 - after / before if before > 0 else float("nan")


def rank_effects(model: RubberModel, data, holdout, *, effects: Sequence[str] | None = None, seed: int = 0,
                 margin: float = MARGIN) -> RubberGapReport:
    """Which catalogue effect closes the gap of a PRF model fitted by optimisation (no posterior).

    Steps: fit the baseline on the calibration tests ``data``; refit each effect's augmented model
    from the baseline optimum; score each on the calibration data by BIC and on the held-out tests
    ``holdout`` (protocols not used for fitting) by the pooled NRMSE.

    Rule: an effect is *accepted* when it lowers BIC on the calibration data by more than ``margin``
    (default 10, "very strong" evidence on the Kass & Raftery 1995 scale) AND lowers the pooled
    held-out NRMSE.  The diagnosis is the accepted effect with the lowest held-out NRMSE, else
    ``"none"``.  BIC rather than AIC because the question is which effect is present (BIC is
    consistent for selecting the true model, AIC aims at prediction, which the held-out error
    already measures); its likelihood is Gaussian with sd proportional to each test's RMS stress
    (the weighting of :func:`rubber.objective`), sd profiled out, so BIC = n ln(RSS/n) + k ln n.
    Residuals of a misfit are autocorrelated, which makes BIC overstate the evidence: that is why
    the held-out error must agree.

    Parameters
    ----------
    model : the baseline :class:`RubberModel` (no effects).
    data : calibration Test or list of Tests; holdout : one or more held-out Tests.
    effects : catalogue effects to try (default all of :data:`EFFECTS`).
    seed : seeds the baseline's CMA-ES search.
    margin : BIC margin of the rule.

    Returns
    -------
    RubberGapReport (rows ordered by held-out NRMSE after, lowest first).
    """
    if not isinstance(model, RubberModel) or model.effects:
        raise ValueError(f"model = {getattr(model, 'name', model)!r}: expected a RubberModel without effects")
    cal = _tests(data)
    hos = _tests(holdout)
    effects = list(EFFECTS) if effects is None else list(effects)
    for e in effects:
        if e not in EFFECTS:
            raise ValueError(f"effect {e!r}: expected one of {sorted(EFFECTS)}")
    if not (isinstance(margin, (int, float)) and margin >= 0):
        raise ValueError(f"margin = {margin!r}: expected a number >= 0")
    base = model.fit(cal, seed=seed)
    y_cal, y_ho = model.observed(cal), model.observed(hos)

    def noise_of(tests):
        return float(np.sqrt(np.mean([white_noise(t.stress - base.stress(t)) ** 2 for t in tests])))

    sig_cal, sig_ho = noise_of(cal), noise_of(hos)
    f_cal, f_ho = base.stress(cal), base.stress(hos)
    g0 = (gap(y_cal, f_cal), gap(y_ho, f_ho))
    s0 = (systematic_gap(y_cal, f_cal, sig_cal), systematic_gap(y_ho, f_ho, sig_ho))
    fits: dict[str, RubberFit] = {base.name: base}
    rows = []
    for e in effects:
        fit = model.augment([e]).fit(cal, seed=seed, start=base)
        fits[fit.name] = fit
        a_cal, a_ho = fit.stress(cal), fit.stress(hos)
        h1 = gap(y_ho, a_ho)
        s1 = (systematic_gap(y_cal, a_cal, sig_cal), systematic_gap(y_ho, a_ho, sig_ho))
        dbic = fit.bic - base.bic
        rows.append(EffectRow(
            effect=e, model=fit.name, delta_bic=float(dbic), holdout_before=g0[1], holdout_after=h1,
            systematic_calibration_before=s0[0], systematic_calibration_after=s1[0],
            systematic_holdout_before=s0[1], systematic_holdout_after=s1[1],
            shrink_calibration=_shrink(s0[0], s1[0]), shrink_holdout=_shrink(s0[1], s1[1]),
            accepted=bool(dbic < -margin and h1 < g0[1]), params=dict(fit.effect_params)))
    rows.sort(key=lambda r: r.holdout_after)
    ok = [r for r in rows if r.accepted]
    diagnosis = ok[0].effect if ok else "none"
    g1 = g0 if not ok else (gap(y_cal, fits[ok[0].model].stress(cal)), ok[0].holdout_after)
    return RubberGapReport(model=base.name, diagnosis=diagnosis, criterion=CRITERION, margin=float(margin),
                           rows=tuple(rows), gap_before=g0, gap_after=g1, noise=(sig_cal, sig_ho), fits=fits)

