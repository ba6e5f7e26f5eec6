"""Fit the three-chain PRF model to uniaxial tests with CMA-ES (``cma``), then a bounded least-squares
polish, and report the local (Fisher) information and the identifiable combinations.

Objective (the study's): f = sum over tests of sum (s_exp - s_pred)^2 / sum s_exp^2, nominal stress.
Search space: each free parameter mapped to [0, 1] over its bounds, logarithmically for C1 and nkT,
linearly otherwise.  The B/C labels are ordered (C1_B <= C1_C, chains swapped when violated; the model
is invariant under the swap) so the two viscous chains cannot exchange roles between runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import integrate as _k
from .io import Test
from .prf import PARAM_NAMES, BBChain, PRFParams, simulate
from .study import BOX

DEFAULT_FIXED = {"C2_B": -1.0, "C2_C": -1.0, "xi": 5e-3}
LOG_PARAMS = ("C1_B", "C1_C", "nkt_B", "nkt_C")
FAIL_F = 1e3


def objective(params: PRFParams, tests: list[Test], *, tau: str = "frobenius", rtol: float = 1e-6
              ) -> np.ndarray:
    """f per test: sum (s_exp - s_pred)^2 / sum s_exp^2 (nominal stress).  FAIL_F on a failed integration."""
    m = params.to_model()
    eq, ch = m.arrays(tau)
    out = []
    for t in tests:
        pred = np.empty(t.time.size)
        st = _k.nominal_stress(t.time, t.stretch, eq, ch, rtol, pred)
        if st != _k.OK or not np.all(np.isfinite(pred)):
            out.append(FAIL_F)
        else:
            out.append(float(np.sum((t.stress - pred) ** 2) / np.sum(t.stress**2)))
    return np.array(out)


def _swap(d: dict) -> dict:
    if d["C1_B"] > d["C1_C"]:
        d = dict(d)
        for n in ("nkt", "N", "C1", "C2", "C3"):
            d[n + "_B"], d[n + "_C"] = d[n + "_C"], d[n + "_B"]
    return d


def initial_modulus(tests: list[Test]) -> float:
    """Young's modulus E0 (MPa) of the first loading: slope of P against lambda - 1 for lambda - 1 <= 2 %."""
    es = []
    for t in tests:
        e = t.stretch - 1.0
        k = np.nonzero((e > 1e-4) & (e <= 0.02))[0]
        if k.size == 0:
            k = np.arange(1, min(5, t.time.size))
        es.append(float(np.sum(t.stress[k] * e[k]) / np.sum(e[k] ** 2)))
    return float(np.median(es))


def auto_bounds(tests: list[Test]) -> dict[str, tuple[float, float]]:
    """The study's box with moduli scaled by E0(data)/E0_ref (E0_ref = 40 MPa, the study's material at
    0.093/s), C1 widened for the stress scale, and N widened to the data's largest chain stretch."""
    s = initial_modulus(tests) / 40.0
    if not s > 0:
        raise ValueError(f"bounds='auto': initial modulus {s * 40:.3g} MPa of the data is not positive")
    b = dict(BOX)
    for n in ("C10", "C20", "C30", "nkt_B", "nkt_C"):
        lo, hi = BOX[n]
        b[n] = (lo * s, hi * s) if n != "C10" else (0.05 * s, hi * s)
    lmax = max(float(np.max(t.stretch)) for t in tests)
    i1 = lmax**2 + 2 / lmax
    nhi = max(5.0, 2.0 * i1)
    for c in "BC":
        b["N_" + c] = (1.0, nhi)
        b["C1_" + c] = (1e-6, 5.0 * max(1.0, 1.0 / s) ** 10)
    return b


@dataclass(frozen=True)
class FitResult:
    """A fitted parameter set with its errors, cost and local identifiability.

    fisher : J^T J of the residual vector with respect to the free parameters in scaled units
    (ln of positive parameters, absolute for C20/C30), so f(theta + d) ~ f + d^T fisher d.
    rel_sigma : change of each free parameter (relative, absolute for C20/C30) that raises f by 1e-4
    with the others re-optimised (a 1 % RMS misfit); > 1 means practically unidentifiable.
    """

    params: PRFParams
    f: dict
    f_total: float
    evaluations: int
    free: tuple[str, ...]
    fisher: np.ndarray
    correlations: np.ndarray
    rel_sigma: dict
    combinations: dict
    runs: list = field(default_factory=list)

    def summary(self) -> str:
        lines = [f"f_total = {self.f_total:.4e} ({self.evaluations} evaluations)"]
        for n, v in self.params.as_dict().items():
            s = self.rel_sigma.get(n)
            lines.append(f"  {n:6s} = {v:12.6g}" + (f"   rel. 1-sigma {s:.3g}" if s is not None else ""))
        for n, v in self.combinations.items():
            lines.append(f"  {n:14s} = {v:.6g}")
        return "\n".join(lines)


def combinations(p: PRFParams, rate: float = 0.093, tau: str = "frobenius") -> dict[str, float]:
    """Identifiable combinations: small-strain moduli, flow thresholds |Delta| (MPa) of the virgin
    chains at du/dt = ``rate``, and the equilibrium nominal stress at lambda = 1.1, 1.2, 1.3."""
    from .prf import equilibrium_stress

    m = p.to_model()
    out = {"mu0_A": m.equilibrium.mu0, "mu0_B": m.chains[0].mu0, "mu0_C": m.chains[1].mu0,
           "Dth_B": m.chains[0].flow_threshold(rate, tau), "Dth_C": m.chains[1].flow_threshold(rate, tau)}
    for lam in (1.1, 1.2, 1.3):
        out[f"Peq({lam})"] = float(equilibrium_stress(p, lam))
    return out


class _Space:
    def __init__(self, free, bounds, fixed):
        self.free = tuple(free)
        self.lo = np.array([bounds[n][0] for n in free], float)
        self.hi = np.array([bounds[n][1] for n in free], float)
        self.log = np.array([n in LOG_PARAMS for n in free])
        self.fixed = dict(fixed)

    def values(self, x):
        x = np.clip(x, 0.0, 1.0)
        lin = self.lo + x * (self.hi - self.lo)
        llo = np.log(np.maximum(self.lo, 1e-300))
        lg = np.exp(llo + x * (np.log(self.hi) - llo))
        return np.where(self.log, lg, lin)

    def params(self, x) -> PRFParams:
        d = dict(self.fixed)
        d.update(zip(self.free, (float(v) for v in self.values(x))))
        return PRFParams(**_swap(d))

    def x_of(self, p: PRFParams):
        d = p.as_dict()
        v = np.array([d[n] for n in self.free])
        xl = (np.log(v) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo)) if self.log.any() else v
        xs = (v - self.lo) / (self.hi - self.lo)
        return np.clip(np.where(self.log, xl, xs), 0.0, 1.0)


def _resolve_bounds(bounds, tests) -> dict:
    if bounds is None:
        return dict(BOX)
    if isinstance(bounds, str):
        if bounds == "auto":
            return auto_bounds(tests)
        raise ValueError(f"bounds = {bounds!r}: expected None, 'auto' or a dict name -> (lo, hi)")
    b = dict(BOX)
    for n, v in dict(bounds).items():
        if n not in PARAM_NAMES:
            raise ValueError(f"bounds: unknown parameter {n!r} (expected one of {PARAM_NAMES})")
        try:
            lo, hi = float(v[0]), float(v[1])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"bounds[{n!r}] = {v!r}: expected (lo, hi)") from None
        if not lo < hi:
            raise ValueError(f"bounds[{n!r}] = {v!r}: expected lo < hi")
        b[n] = (lo, hi)
    return b


def _run_cma(args):
    space, tests, x0, sigma0, popsize, max_evals, seed, tau, rtol = args
    import cma

    opts = {"bounds": [0.0, 1.0], "popsize": popsize, "maxfevals": max_evals, "seed": seed,
            "verb_log": 0, "verb_disp": 0, "tolfun": 1e-14, "tolx": 1e-12}
    es = cma.CMAEvolutionStrategy(list(x0), sigma0, opts)

    def f(x):
        try:
            return float(np.sum(objective(space.params(x), tests, tau=tau, rtol=rtol)))
        except ValueError:
            return FAIL_F

    while not es.stop():
        xs = es.ask()
        es.tell(xs, [f(x) for x in xs])
    return np.array(es.result.xbest), float(es.result.fbest), int(es.result.evaluations)


def _residuals(space, tests, x, tau, rtol):
    p = space.params(x)
    m = p.to_model()
    eq, ch = m.arrays(tau)
    r = []
    for t in tests:
        pred = np.empty(t.time.size)
        st = _k.nominal_stress(t.time, t.stretch, eq, ch, rtol, pred)
        if st != _k.OK:
            pred[:] = 0.0
        r.append((t.stress - pred) / math.sqrt(np.sum(t.stress**2)))
    return np.concatenate(r)


def fisher_information(params: PRFParams, tests: list[Test], free: tuple[str, ...], *, tau: str = "frobenius",
                       rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, dict]:
    """J^T J, correlations and profiled relative 1-sigma (f + 1e-4) at ``params`` (central differences
    in ln(theta) for positive parameters, in theta for C20/C30 and others that may be <= 0)."""
    d0 = params.as_dict()
    cols = []
    for n in free:
        v = d0[n]
        rel = v > 0 and n not in ("C20", "C30")
        h = 1e-4 if rel else 1e-4 * max(abs(v), 0.1)
        rs = []
        for s in (+1, -1):
            d = dict(d0)
            d[n] = v * math.exp(s * h) if rel else v + s * h
            m = PRFParams(**d)
            r = [(t.stress - simulate(m, t.time, t.stretch, tau=tau, rtol=rtol).nominal)
                 / math.sqrt(np.sum(t.stress**2)) for t in tests]
            rs.append(np.concatenate(r))
        cols.append((rs[0] - rs[1]) / (2 * h))
    j = np.array(cols).T
    fim = j.T @ j
    cov = np.linalg.pinv(fim, rcond=1e-15)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    rel_sigma = {n: float(math.sqrt(1e-4) * s) for n, s in zip(free, sd)}
    return fim, corr, rel_sigma


def fit(tests: list[Test] | Test, *, fixed: dict | None = None, bounds=None, seed: int = 0,
        restarts: int = 2, max_evals: int = 6000, popsize: int = 16, sigma0: float = 0.3,
        x0: PRFParams | None = None, polish: bool = True, tau: str = "frobenius", rtol: float = 1e-6,
        pool=None) -> FitResult:
    """Fit a :class:`PRFParams` to uniaxial tests by CMA-ES with restarts and a least-squares polish.

    Parameters
    ----------
    tests : Test or list of Test (nominal stress, MPa).
    fixed : parameters held fixed (default C2_B = C2_C = -1, xi = 5e-3, the study's choice).
    bounds : None (the study's box ``rubber.BOX``), "auto" (moduli rescaled by the data's initial
        modulus, for other materials) or a dict name -> (lo, hi) overriding entries of the box.
    seed : seeds the restarts' starting points and CMA-ES (reproducible).
    restarts : number of independent CMA-ES runs (random starts; the first starts at ``x0`` if given).
    max_evals : evaluation budget per run.  pool : anything with ``.map`` to run restarts in parallel.
    tau : flow-stress convention; rtol : integrator tolerance during the search.

    Returns
    -------
    FitResult (a new PRFParams, f per test, evaluations, Fisher information and combinations).
    """
    if isinstance(tests, Test):
        tests = [tests]
    tests = list(tests)
    if not tests or not all(isinstance(t, Test) for t in tests):
        raise ValueError("tests: expected one or more rubber.Test")
    fixed = dict(DEFAULT_FIXED if fixed is None else fixed)
    for n in fixed:
        if n not in PARAM_NAMES:
            raise ValueError(f"fixed: unknown parameter {n!r} (expected one of {PARAM_NAMES})")
    if "xi" not in fixed:
        raise ValueError("fixed: 'xi' must be fixed (it is not identifiable)")
    if int(restarts) < 1:
        raise ValueError(f"restarts = {restarts!r}: expected >= 1")
    b = _resolve_bounds(bounds, tests)
    free = tuple(n for n in PARAM_NAMES if n not in fixed)
    for n in free:
        if n in LOG_PARAMS and b[n][0] <= 0:
            raise ValueError(f"bounds[{n!r}] = {b[n]}: log-scaled parameter needs lo > 0")
    space = _Space(free, b, fixed)
    rng = np.random.default_rng(seed)
    starts = [rng.uniform(0.2, 0.8, len(free)) for _ in range(int(restarts))]
    if x0 is not None:
        starts[0] = space.x_of(x0)
    jobs = [(space, tests, s, sigma0, popsize, max_evals, int(seed) * 1000 + i + 1, tau, rtol)
            for i, s in enumerate(starts)]
    runs = list((pool.map if pool is not None else map)(_run_cma, jobs))
    nev = sum(r[2] for r in runs)
    xb, fb, _ = min(runs, key=lambda r: r[1])
    if polish:
        from scipy.optimize import least_squares

        r0 = _residuals(space, tests, xb, tau, rtol)
        sol = least_squares(lambda x: _residuals(space, tests, x, tau, rtol), xb, bounds=(0.0, 1.0),
                            x_scale=1.0, diff_step=1e-6, max_nfev=60 * (1 + len(free)), xtol=1e-14,
                            ftol=1e-14, gtol=1e-14)
        nev += int(sol.nfev) * (1 + len(free))
        if np.sum(sol.fun**2) < np.sum(r0**2):
            xb = sol.x
    p = space.params(xb)
    fs = objective(p, tests, tau=tau, rtol=min(rtol, 1e-8))
    fim, corr, rs = fisher_information(p, tests, free, tau=tau)
    fd = {t.name: float(v) for t, v in zip(tests, fs)}
    return FitResult(p, fd, float(np.sum(fs)), nev, free, fim, corr,
                     rs, combinations(p, tau=tau), [(float(r[1]), int(r[2])) for r in runs])


def chain_mu0(nkt: float, n: float) -> float:
    return BBChain(nkt, n, 0.0).mu0
