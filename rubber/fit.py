"""Fit the three-chain PRF model to uniaxial tests with CMA-ES (``cma``), then a bounded least-squares
polish, and report the local (Fisher) information and the identifiable combinations.

Objective (the study's): f = sum over tests of sum (s_exp - s_pred)^2 / sum s_exp^2, nominal stress.
Search space: each free parameter mapped to [0, 1] over its bounds, logarithmically for C1 and nkT,
linearly otherwise.  The B/C labels are ordered (C1_B <= C1_C, chains swapped when violated; the model
is invariant under the swap) so the two viscous chains cannot exchange roles between runs.

Flow-threshold parameterisation (``bounds="auto"``, or a bounds dict naming ``Dth_B``/``Dth_C``).
The flow constant C1 (MPa^-C3 s^-1) spans tens of decades and is coupled to C3 through the stress
scale, so a box in C1 reaches parameter sets that no data can support (issue 16.3: C1 ~ 1e19 with
C3 ~ 4 on kPa data, a chain that relaxes in microseconds).  The search instead runs over the flow
threshold D (MPa): the stress difference |Delta| at which the virgin chain (lambda_v = 1, so
lambda_ch = 1) flows at the reference rate r_ref (1/s).  From the uniaxial Bergstrom-Boyce rule of
``docs/reference/prf_model.md`` section 4, du/dt = c_tau C1 (lambda_ch - 1 + xi)^C2 |Delta|^C3 sign(Delta)
with c_tau = (2/3)^((C3 + 1)/2) (Frobenius tau) or 1 (Mises tau), hence::

    r_ref = c_tau C1 xi^C2 D^C3    <=>    C1 = r_ref / (c_tau xi^C2 D^C3)

(:func:`c1_from_threshold`; :meth:`rubber.BBChain.flow_threshold` is the inverse).  D is searched on a
log scale in [1e-3 S, 10 S], S the largest |P| of the data: below 1e-3 S a chain carries no stress the
data can see (it behaves as the lower bound), above 10 S it never flows (it behaves as the upper
bound), so the box loses nothing and cannot run away.  C1 is computed back for every evaluation, and
the results, ``params.json`` and the cards keep the model's native C1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rrfrei.budget import TimeBudget
from rrfrei.budget import progress as _progress

from . import integrate as _k
from .extrapolation import check, stretch_range
from .io import Test
from .polish import least_squares_best
from .prf import PARAM_NAMES, BBChain, PRFParams, simulate
from .study import BOX

DEFAULT_FIXED = {"C2_B": -1.0, "C2_C": -1.0, "xi": 5e-3}
LOG_PARAMS = ("C1_B", "C1_C", "nkt_B", "nkt_C", "Dth_B", "Dth_C")
FAIL_F = 1e3
"""Objective value of a parameter set whose evaluation fails (integrator status, non-finite stress or a
numerical exception): a bad point for CMA-ES, never the end of a fit (a perfect miss scores 1 per test)."""
REF_RATE = 0.093
"""Default reference rate r_ref (1/s) of the flow thresholds: the study's engineering strain rate."""
DTH_RANGE = (1e-3, 10.0)
"""Flow-threshold box of ``bounds="auto"`` as multiples of the data's largest |P| (see module docstring)."""
N_LOCK_MIN = 4.0
"""Lower bound of N in ``bounds="auto"``: the chain at rest is at most half-way to its lock,
x = lambda_ch / sqrt(N) = 1 / sqrt(N) <= 1/2, i.e. lambda_lock = sqrt(N) >= 2 (see :func:`auto_bounds`)."""
_EVAL_ERRORS = (ValueError, ArithmeticError)  # ZeroDivisionError, OverflowError, FloatingPointError


def c1_from_threshold(dth: float, c3: float, *, rate: float = REF_RATE, c2: float = -1.0, xi: float = 5e-3,
                      tau: str = "frobenius") -> float:
    """Flow constant C1 (MPa^-C3 s^-1, Marc notation) of a chain whose virgin flow threshold is ``dth``.

    C1 = r_ref / (c_tau xi^C2 D^C3), c_tau = (2/3)^((C3 + 1)/2) for tau = "frobenius", 1 for "mises":
    the virgin chain (lambda_ch = 1) flows at du/dt = ``rate`` (1/s) when |Delta| = ``dth`` (MPa).
    Inverse of :meth:`rubber.BBChain.flow_threshold`; equation from ``docs/reference/prf_model.md`` s. 4.
    """
    c_tau = 1.0 if tau == "mises" else (2.0 / 3.0) ** ((c3 + 1.0) / 2.0)
    return float(math.exp(math.log(rate) - math.log(c_tau) - c2 * math.log(xi) - c3 * math.log(dth)))


def objective(params: PRFParams, tests: list[Test], *, tau: str = "frobenius", rtol: float = 1e-6
              ) -> np.ndarray:
    """f per test: sum (s_exp - s_pred)^2 / sum s_exp^2 (nominal stress, dimensionless).

    A test whose evaluation fails (integrator status not ok, a non-finite stress, or a numerical
    exception such as ZeroDivisionError inside the kernel) scores :data:`FAIL_F`: inside an optimiser
    a failing parameter set is a bad point, never the end of the fit.
    """
    m = params.to_model()
    eq, ch = m.arrays(tau)
    out = []
    for t in tests:
        pred = np.empty(t.time.size)
        try:
            st = _k.nominal_stress(t.time, t.stretch, eq, ch, rtol, pred)
        except _EVAL_ERRORS:
            st = -1
        if st != _k.OK or not np.all(np.isfinite(pred)):
            out.append(FAIL_F)
        else:
            out.append(min(FAIL_F, float(np.sum((t.stress - pred) ** 2) / np.sum(t.stress**2))))
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


def loading_rate(tests: list[Test]) -> float:
    """Reference stretch rate r_ref (1/s) of a data set: the geometric mean over tests of each test's
    median |d lambda/dt| while the stretch changes (three significant digits)."""
    rs = []
    for t in tests:
        r = np.abs(np.diff(t.stretch) / np.diff(t.time))
        r = r[r > 1e-12]
        if r.size:
            rs.append(float(np.median(r)))
    if not rs:
        raise ValueError("tests: the stretch never changes, so there is no loading rate")
    return float(f"{math.exp(np.mean(np.log(rs))):.3g}")


def auto_bounds(tests: list[Test]) -> dict:
    """Search box scaled to the data (for materials other than the study's polyurethane).

    * moduli (C10, C20, C30, nkt_B, nkt_C): the study's box times E0(data) / E0_ref, E0 from
      :func:`initial_modulus`, E0_ref = 40 MPa (the study's material at 0.093/s);
    * flow: thresholds ``Dth_B``, ``Dth_C`` in [1e-3 S, 10 S] (MPa; S = largest |P| of the data) at the
      reference rate ``ref_rate`` = :func:`loading_rate` instead of C1 (module docstring; C1 follows from
      C1 = r_ref / (c_tau xi^C2 D^C3)), so the box cannot reach run-away flow constants;
    * locking: N in [4, max(5, 2 I1(lambda_max))] (:data:`N_LOCK_MIN`).  The Eight-Chain spring is the
      five-term series of the inverse Langevin function L^-1(x), x = lambda_ch / sqrt(N),
      lambda_ch = sqrt(I1 / 3), whose radius of convergence is x = 1, where the chain is fully extended
      (L^-1 -> infinity).  With N close to 1 the chain sits at its lock already at rest
      (x = 1/sqrt(N) = 0.98 for N = 1.0447) and beyond it as soon as it is stretched: N no longer means
      a locking stretch, the truncated series is used far outside its range and N trades off against
      nkT.  N >= 4 keeps the chain at rest at most half-way to its lock (x <= 1/2, where the series
      matches L^-1 to 0.3 %, lambda_lock >= 2) and leaves every larger locking stretch to the data.
      (A bound from the data's largest stretch, x <= 0.9 at lambda_max, was tried and rejected: a
      flowing chain's elastic stretch is far below the applied one, so it excluded admissible N.)
    """
    s = initial_modulus(tests) / 40.0
    if not s > 0:
        raise ValueError(f"bounds='auto': initial modulus {s * 40:.3g} MPa of the data is not positive")
    b = dict(BOX)
    for n in ("C10", "C20", "C30", "nkt_B", "nkt_C"):
        lo, hi = BOX[n]
        b[n] = (lo * s, hi * s) if n != "C10" else (0.05 * s, hi * s)
    lmax = max(float(np.max(t.stretch)) for t in tests)
    i1 = lmax**2 + 2 / lmax
    nlo = N_LOCK_MIN
    nhi = max(5.0, 2.0 * i1)
    smax = max(float(np.max(np.abs(t.stress))) for t in tests)
    for c in "BC":
        b["N_" + c] = (nlo, nhi)
        del b["C1_" + c]
        b["Dth_" + c] = (DTH_RANGE[0] * smax, DTH_RANGE[1] * smax)
    b["ref_rate"] = loading_rate(tests)
    return b


@dataclass(frozen=True)
class FitResult:
    """A fitted parameter set with its errors, cost and local identifiability.

    fisher : J^T J of the residual vector with respect to the free parameters in scaled units
    (ln of positive parameters, absolute for C20/C30), so f(theta + d) ~ f + d^T fisher d.
    rel_sigma : change of each free parameter (relative, absolute for C20/C30) that raises f by 1e-4
    with the others re-optimised (a 1 % RMS misfit); > 1 means practically unidentifiable; NaN where
    the finite difference could not be evaluated (reason in ``uncertainty_notes``).
    ref_rate : reference rate (1/s) of the flow thresholds Dth_B, Dth_C in ``combinations``.
    flow_thresholds : the chains searched by flow threshold instead of C1 (empty: C1 searched).
    uncertainty_notes : one-sided differences, NaN uncertainties and failures of the post-fit
    uncertainty step, with reasons (empty when every central difference worked).
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
    ref_rate: float = REF_RATE
    flow_thresholds: tuple[str, ...] = ()
    uncertainty_notes: tuple[str, ...] = ()
    stopped_by: str | None = None
    """``"time_budget"`` when the wall-clock budget ended the search early (the best point found
    so far is returned and polished as far as the budget allowed); None for a complete fit."""
    stretch_range: tuple[float, float] | None = None
    """(min, max) stretch of the fitted tests: the range the fit is evidence for."""
    extrapolation: tuple = ()
    """Fitted tests within 10 % of a fitted chain's locking stretch
    (:func:`rubber.extrapolation.check`: :class:`rrfrei.extrapolation.Extrapolation` records)."""

    def summary(self) -> str:
        lines = [f"f_total = {self.f_total:.4e} ({self.evaluations} evaluations)"]
        for n, v in self.params.as_dict().items():
            s = self.rel_sigma.get(n)
            lines.append(f"  {n:6s} = {v:12.6g}" + (f"   rel. 1-sigma {s:.3g}" if s is not None else ""))
        for n, v in self.combinations.items():
            lines.append(f"  {n:14s} = {v:.6g}")
        lines += [f"  note: {x}" for x in self.uncertainty_notes]
        if self.stretch_range is not None:
            lines.append(f"  fitted stretch range {self.stretch_range[0]:.4g} to {self.stretch_range[1]:.4g}")
        lines += [f"  warning: {x.message}" for x in self.extrapolation]
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
    """Map between the unit cube [0, 1]^k of the optimisers and a PRFParams.

    Coordinates are the free parameters, except that a free C1_k becomes the flow threshold Dth_k
    (MPa at ``bounds["ref_rate"]`` 1/s) when the bounds name ``Dth_k``; C1_k = r_ref / (c_tau xi^C2 D^C3).
    """

    def __init__(self, free, bounds, fixed, tau: str = "frobenius"):
        self.free = tuple(free)
        self.fixed = dict(fixed)
        self.tau = tau
        self.ref_rate = float(bounds.get("ref_rate", REF_RATE))
        self.threshold = tuple(c for c in "BC" if "C1_" + c in self.free and "Dth_" + c in bounds)
        self.coords = tuple("Dth_" + n[3:] if n[:3] == "C1_" and n[3:] in self.threshold else n
                            for n in self.free)
        self.lo = np.array([bounds[n][0] for n in self.coords], float)
        self.hi = np.array([bounds[n][1] for n in self.coords], float)
        self.log = np.array([n in LOG_PARAMS for n in self.coords])

    def values(self, x):
        x = np.clip(x, 0.0, 1.0)
        lin = self.lo + x * (self.hi - self.lo)
        llo = np.log(np.maximum(self.lo, 1e-300))
        lg = np.exp(llo + x * (np.log(np.maximum(self.hi, 1e-300)) - llo))
        return np.clip(np.where(self.log, lg, lin), self.lo, self.hi)  # exp(log(.)) may round past a bound

    def native(self, x) -> dict:
        """Native parameter values (dict, before the B/C ordering) at unit coordinates x."""
        d = dict(self.fixed)
        d.update(zip(self.coords, (float(v) for v in self.values(x))))
        for c in self.threshold:
            d["C1_" + c] = c1_from_threshold(d.pop("Dth_" + c), d["C3_" + c], rate=self.ref_rate,
                                             c2=d["C2_" + c], xi=d["xi"], tau=self.tau)
        return d

    def params(self, x) -> PRFParams:
        return PRFParams(**_swap(self.native(x)))

    def coord_values(self, p: PRFParams) -> np.ndarray:
        d = p.as_dict()
        for c in self.threshold:
            d["Dth_" + c] = BBChain(d["nkt_" + c], d["N_" + c], d["C1_" + c], d["C2_" + c], d["C3_" + c],
                                    d["xi"]).flow_threshold(self.ref_rate, self.tau)
        return np.array([d[n] for n in self.coords], float)

    def x_of(self, p: PRFParams):
        v = self.coord_values(p)
        with np.errstate(divide="ignore", invalid="ignore"):
            xl = (np.log(v) - np.log(self.lo)) / (np.log(self.hi) - np.log(self.lo))
        xs = (v - self.lo) / (self.hi - self.lo)
        return np.clip(np.nan_to_num(np.where(self.log, xl, xs), nan=0.5), 0.0, 1.0)


def _resolve_bounds(bounds, tests) -> dict:
    if bounds is None:
        return dict(BOX)
    if isinstance(bounds, str):
        if bounds == "auto":
            return auto_bounds(tests)
        raise ValueError(f"bounds = {bounds!r}: expected None, 'auto' or a dict name -> (lo, hi)")
    b = dict(BOX)
    for n, v in dict(bounds).items():
        if n == "ref_rate":
            try:
                r = float(v)
            except (TypeError, ValueError):
                r = math.nan
            if not (r > 0 and math.isfinite(r)):
                raise ValueError(f"bounds['ref_rate'] = {v!r}: expected a stretch rate > 0 (1/s)")
            b[n] = r
            continue
        if n not in PARAM_NAMES and n not in ("Dth_B", "Dth_C"):
            raise ValueError(f"bounds: unknown parameter {n!r} (expected one of {PARAM_NAMES}, Dth_B, "
                             "Dth_C or ref_rate)")
        try:
            lo, hi = float(v[0]), float(v[1])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"bounds[{n!r}] = {v!r}: expected (lo, hi)") from None
        if not lo < hi:
            raise ValueError(f"bounds[{n!r}] = {v!r}: expected lo < hi")
        if n[:4] == "Dth_" and not lo > 0:
            raise ValueError(f"bounds[{n!r}] = {v!r}: expected a flow threshold range with lo > 0 (MPa)")
        b[n] = (lo, hi)
    return b


def _run_cma(args, bar=None):
    """One CMA-ES run; stops early (keeping its best point) once the wall clock passes ``deadline``
    (seconds since the epoch, so that it also holds in a worker process; None: no deadline)."""
    space, tests, x0, sigma0, popsize, max_evals, seed, tau, rtol, deadline = args
    import time

    import cma

    opts = {"bounds": [0.0, 1.0], "popsize": popsize, "maxfevals": max_evals, "seed": seed,
            "verb_log": 0, "verb_disp": 0, "tolfun": 1e-14, "tolx": 1e-12}
    es = cma.CMAEvolutionStrategy(list(x0), sigma0, opts)

    def f(x):
        try:
            v = float(np.sum(objective(space.params(x), tests, tau=tau, rtol=rtol)))
        except _EVAL_ERRORS:  # a parameter set the model rejects, or a kernel exception: a bad point
            return FAIL_F * len(tests)
        return v if math.isfinite(v) else FAIL_F * len(tests)

    while not es.stop():
        xs = es.ask()
        es.tell(xs, [f(x) for x in xs])
        if bar is not None:
            bar.update(len(xs))
        if deadline is not None and time.time() >= deadline:
            break
    return np.array(es.result.xbest), float(es.result.fbest), int(es.result.evaluations)


def _residuals(space, tests, x, tau, rtol):
    """Weighted residuals (s_exp - s_pred) / ||s_exp|| of every test.  A failing evaluation (invalid
    parameter set, integrator status, non-finite stress, kernel exception) gives the residuals of a
    zero prediction (f = 1 per test): finite, so least squares steps back instead of stopping."""
    try:
        p = space.params(x)
        eq, ch = p.to_model().arrays(tau)
    except _EVAL_ERRORS:
        eq = ch = None
    r = []
    for t in tests:
        pred = np.zeros(t.time.size)
        if eq is not None:
            try:
                st = _k.nominal_stress(t.time, t.stretch, eq, ch, rtol, pred)
            except _EVAL_ERRORS:
                st = -1
            if st != _k.OK or not np.all(np.isfinite(pred)):
                pred[:] = 0.0
        r.append((t.stress - pred) / math.sqrt(np.sum(t.stress**2)))
    return np.concatenate(r)


def _test_residuals(p: PRFParams, tests: list[Test], tau: str, rtol: float) -> np.ndarray:
    return np.concatenate([(t.stress - simulate(p, t.time, t.stretch, tau=tau, rtol=rtol).nominal)
                           / math.sqrt(np.sum(t.stress**2)) for t in tests])


def fisher_report(params: PRFParams, tests: list[Test], free: tuple[str, ...], *, tau: str = "frobenius",
                  rtol: float = 1e-9, bounds: dict | None = None
                  ) -> tuple[np.ndarray, np.ndarray, dict, tuple[str, ...]]:
    """:func:`fisher_information` plus the reasons for every parameter it could not difference.

    Finite differences of the weighted residual vector r (f = r.r, r_i = (s_exp - s_pred) / ||s_exp||)
    in scaled units s(theta): ln(theta) for positive parameters (step h = 1e-4); theta itself for C20,
    C30 and parameters <= 0 (step h = 1e-4 max(|theta|, 1e-3 (hi - lo)) with the parameter's bounds,
    1e-4 max(|theta|, 0.1) without).  Each step must stay inside ``bounds[name]`` and give a valid
    parameter set (e.g. C3 >= 1).  Where only one side does (a parameter on its bound), the one-sided
    difference into the box is used, (r(s + h) - r(s)) / h or (r(s) - r(s - h)) / h (first order
    instead of second).  Where neither side can be evaluated, the parameter's column is NaN and so are
    its rel_sigma and correlations; the others come from the finite columns.

    Parameters
    ----------
    params : the (fitted) point.
    tests : the data; free : names of the free parameters.
    tau, rtol : flow-stress convention and integrator tolerance of the differences.
    bounds : name -> (lo, hi) in native units (MPa, s); names missing are bounded only by validity.

    Returns
    -------
    fisher : (k, k) J^T J in the scaled units.
    correlations : (k, k).
    rel_sigma : name -> sqrt(1e-4) sd (the change raising f by 1e-4, others re-optimised).
    notes : one line per parameter differenced one-sided or not at all, with the reason.
    """
    d0 = params.as_dict()
    bounds = bounds or {}
    notes: list[str] = []
    r0 = None
    cols = []
    for n in free:
        v = d0[n]
        rel = v > 0 and n not in ("C20", "C30")
        lo, hi = bounds.get(n, (-math.inf, math.inf))
        scale = 1e-3 * (hi - lo) if math.isfinite(hi - lo) else 0.1
        h = 1e-4 if rel else 1e-4 * max(abs(v), scale)
        rs = {}
        why = []
        for sgn in (+1, -1):
            w = v * math.exp(sgn * h) if rel else v + sgn * h
            if not lo <= w <= hi:
                why.append(f"{n} = {w:.6g} outside its bounds [{lo:.6g}, {hi:.6g}]")
                continue
            try:
                rs[sgn] = _test_residuals(PRFParams(**{**d0, n: w}), tests, tau, rtol)
            except _EVAL_ERRORS as exc:
                why.append(f"{n} = {w:.6g}: {exc}".splitlines()[0])
        if len(rs) == 2:
            cols.append((rs[1] - rs[-1]) / (2 * h))
            continue
        if rs and r0 is None:
            try:
                r0 = _test_residuals(params, tests, tau, rtol)
            except _EVAL_ERRORS as exc:
                notes.append(f"uncertainty: the fitted point itself cannot be re-evaluated ({exc})")
                r0 = False
        if rs and r0 is not False:
            sgn, r = next(iter(rs.items()))
            cols.append(sgn * (r - r0) / h)
            notes.append(f"{n}: one-sided difference ({'; '.join(why)})")
        else:
            cols.append(np.full(sum(t.time.size for t in tests), np.nan))
            notes.append(f"{n}: no uncertainty, neither difference step can be evaluated ({'; '.join(why)})")
    j = np.array(cols).T
    ok = np.all(np.isfinite(j), axis=0)
    k = len(free)
    fim = np.full((k, k), np.nan)
    jo = j[:, ok]
    fim[np.ix_(ok, ok)] = jo.T @ jo
    cov = np.full((k, k), np.nan)
    if ok.any():
        cov[np.ix_(ok, ok)] = np.linalg.pinv(jo.T @ jo, rcond=1e-15)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    sd[~ok] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    rel_sigma = {n: float(math.sqrt(1e-4) * s) for n, s in zip(free, sd)}
    return fim, corr, rel_sigma, tuple(notes)


def fisher_information(params: PRFParams, tests: list[Test], free: tuple[str, ...], *, tau: str = "frobenius",
                       rtol: float = 1e-9, bounds: dict | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """J^T J, correlations and profiled relative 1-sigma (f + 1e-4) at ``params`` (central differences
    in ln(theta) for positive parameters, in theta for C20/C30 and others that may be <= 0; one-sided
    at a bound or where a step would leave the valid parameter set; NaN where neither side works).
    See :func:`fisher_report`, which also returns the reasons."""
    return fisher_report(params, tests, free, tau=tau, rtol=rtol, bounds=bounds)[:3]


def fit(tests: list[Test] | Test, *, fixed: dict | None = None, bounds=None, seed: int = 0,
        restarts: int = 2, max_evals: int = 6000, popsize: int = 16, sigma0: float = 0.3,
        x0: PRFParams | None = None, polish: bool = True, tau: str = "frobenius", rtol: float = 1e-6,
        pool=None, time_budget: float | None = None, progress: bool = False,
        polish_evals: int | None = None) -> FitResult:
    """Fit a :class:`PRFParams` to uniaxial tests by CMA-ES with restarts and a least-squares polish.

    Parameters
    ----------
    tests : Test or list of Test (nominal stress, MPa).
    fixed : parameters held fixed (default C2_B = C2_C = -1, xi = 5e-3, the study's choice).
    bounds : None (the study's box ``rubber.BOX``, C1 searched), "auto" (:func:`auto_bounds`: box
        scaled to the data, flow thresholds searched instead of C1, N bounded away from the lock) or a
        dict name -> (lo, hi) overriding entries of the box; naming ``Dth_B``/``Dth_C`` (MPa) searches
        that chain's flow threshold at ``"ref_rate"`` (a number, 1/s; default 0.093) instead of C1.
    seed : seeds the restarts' starting points and CMA-ES (reproducible).
    restarts : number of independent CMA-ES runs (random starts; the first starts at ``x0`` if given).
    max_evals : evaluation budget per run.  pool : anything with ``.map`` to run restarts in parallel.
    tau : flow-stress convention; rtol : integrator tolerance during the search.
    time_budget : wall-clock limit [s] of the search and the polish (None: none).  When it is
        reached, the best point so far is kept, the post-fit uncertainty step still runs, and the
        result says ``stopped_by="time_budget"``.
    progress : tqdm bar over the CMA-ES evaluations (serial restarts) and the polish, on stderr.
    polish_evals : cap on the evaluations of the least-squares polish, finite-difference Jacobians
        included (default None: the polish stops by its tolerances or after ``60 (1 + free)``
        iterations, ``free`` the number of searched parameters).

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
    if polish_evals is not None and int(polish_evals) < 1:
        raise ValueError(f"polish_evals = {polish_evals!r}: expected >= 1 (or None for the default)")
    b = _resolve_bounds(bounds, tests)
    free = tuple(n for n in PARAM_NAMES if n not in fixed)
    space = _Space(free, b, fixed, tau)
    for n, lo, hi, lg in zip(space.coords, space.lo, space.hi, space.log):
        if lg and lo <= 0:
            raise ValueError(f"bounds[{n!r}] = {(lo, hi)}: log-scaled parameter needs lo > 0")
    rng = np.random.default_rng(seed)
    starts = [rng.uniform(0.2, 0.8, len(free)) for _ in range(int(restarts))]
    if x0 is not None:
        starts[0] = space.x_of(x0)
    import time

    budget = TimeBudget(time_budget, "rubber fit", "--time-budget")
    deadline = None if budget.seconds is None else time.time() + budget.seconds
    jobs = [(space, tests, s, sigma0, popsize, max_evals, int(seed) * 1000 + i + 1, tau, rtol, deadline)
            for i, s in enumerate(starts)]
    if pool is not None:
        runs = list(pool.map(_run_cma, jobs))
    else:
        with _progress(len(jobs) * int(max_evals), "CMA-ES", enabled=progress, unit="eval") as bar:
            runs = [_run_cma(j, bar) for j in jobs]
    nev = sum(r[2] for r in runs)
    xb, fb, _ = min(runs, key=lambda r: r[1])
    if polish and not budget.expired():
        cap = math.inf if polish_evals is None else int(polish_evals)
        r0 = _residuals(space, tests, xb, tau, rtol)
        with _progress(None, "polish (least squares)", enabled=progress, unit="eval") as bar:
            def resid(x):
                bar.update()
                return _residuals(space, tests, x, tau, rtol)

            xb, _, n = least_squares_best(resid, xb, start_cost=float(r0 @ r0),
                                          stop=lambda n: n >= cap or budget.expired(), x_scale=1.0,
                                          diff_step=1e-6, max_nfev=60 * (1 + len(free)),
                                          xtol=1e-14, ftol=1e-14, gtol=1e-14)
        nev += n
    stopped = "time_budget" if budget.expired() else None
    p = space.params(xb)
    fs = objective(p, tests, tau=tau, rtol=min(rtol, 1e-8))
    fd = {t.name: float(v) for t, v in zip(tests, fs)}
    fim, corr, rs, notes = _safe_fisher(p, tests, free, tau, b)
    return FitResult(p, fd, float(np.sum(fs)), nev, free, fim, corr, rs,
                     combinations(p, rate=space.ref_rate, tau=tau), [(float(r[1]), int(r[2])) for r in runs],
                     ref_rate=space.ref_rate, flow_thresholds=tuple("Dth_" + c for c in space.threshold),
                     uncertainty_notes=notes, stopped_by=stopped, stretch_range=stretch_range(tests),
                     extrapolation=tuple(check(p, tests)))


def _safe_fisher(p: PRFParams, tests: list[Test], free: tuple[str, ...], tau: str, bounds: dict):
    """The post-fit uncertainty step; a failure leaves NaN uncertainties and a note, never loses the fit."""
    nb = {n: v for n, v in bounds.items() if n in PARAM_NAMES}
    try:
        return fisher_report(p, tests, free, tau=tau, bounds=nb)
    except (*_EVAL_ERRORS, np.linalg.LinAlgError) as exc:
        k = len(free)
        nan = np.full((k, k), np.nan)
        return nan, nan.copy(), {n: math.nan for n in free}, (f"uncertainty step failed: {exc}",)


def chain_mu0(nkt: float, n: float) -> float:
    return BBChain(nkt, n, 0.0).mu0
