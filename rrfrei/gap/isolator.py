"""The isolator implementation of the gap engine's model interface (:mod:`rrfrei.gap.model`).

Fit: the optimum of the law parameters under iid Gaussian residuals (noise profiled out, flat
priors inside the physical bounds) by bounded least squares (``scipy.optimize.least_squares``,
trust-region reflective) from several starts: the baseline starts from the optimum of
:func:`rrfrei.calibration.optimum.find_map` with :func:`rrfrei.calibrate`'s own settings (so its
least-squares optimum is never worse than calibrate's) and from a shorter search with another
seed (``GLOBAL_EVALS`` evaluations per parameter), keeping the best; an augmented
law starts from the baseline optimum with each effect at the catalogue's starting values.
Every start runs ``SCREEN_ITERATIONS`` iterations, then only the starts that may still win are
continued (:func:`_worth_continuing`), and a start that only creeps is stopped (:class:`_Guard`).
Posterior: ``draws`` samples of the Laplace approximation ``N(theta*, (J^T J / s^2 + I)^-1)`` in
coordinates scaled by each parameter's typical size (the identity is a weak ridge: one scale of
prior spread in directions the data do not fix), clipped to the bounds, then importance-resampled
to the posterior under flat priors with the noise integrated out, ``p(theta | y) ~ RSS^(-n/2)``
(systematic resampling), and ``sigma^2 = RSS(theta) / chi2_n`` per draw.
This is the "short posterior" of the diagnosis; the full emcee posterior of
:func:`rrfrei.calibrate` is the reference for reporting a chosen law.
"""

from __future__ import annotations

import hashlib
import json
import math
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative  # the forward differences least squares takes

from rrfrei.blas import one_blas_thread
from rrfrei.budget import TimeBudget
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.gap.catalogue import Scales, catalogue
from rrfrei.gap.fitting import _Guard, _worth_continuing, laplace_cov
from rrfrei.gap.model import (
    LEVEL,
    MIN_BAND_SAMPLES,
    FitResult,
    GapModel,
    Prediction,
    gaussian_loglik,
    test_scales,
    white_noise,
)
from rrfrei.io import ShearTest, concat_tests
from rrfrei.laws import LawSpec, get
from rrfrei.laws.specialise import history

__all__ = ["IsolatorFit", "IsolatorModel", "RETRY_SUBSTEPS", "simulate_retry"]

MIN_ESS = 5.0
"""Below this effective sample size of the importance weights a fit says its draws are degenerate."""
GLOBAL_EVALS = 300
"""CMA-ES evaluations per free parameter of the baseline's global search (then least squares)."""
SCREEN_ITERATIONS = 30
"""Iterations every start of a multi-start fit runs before the starts are compared
(:func:`_worth_continuing`)."""
CHECKPOINT_FORMAT = 2
"""Version of the checkpoint files (part of their key: a change invalidates old ones)."""
_UNIT_SCALES = Scales(force=1.0, disp=1.0, vel=1.0, energy=1.0)
"""Scales at which an effect's ``scales`` hint is read for its parameter names only."""


_HISTORIES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_WRITABLE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""test -> the concatenation of its ``preceding`` tests and itself (built once per test)."""


def _history_of(test: ShearTest) -> ShearTest:
    full = _HISTORIES.get(test)
    if full is None:
        full = concat_tests([*test.preceding, test], name=test.name)
        _HISTORIES[test] = full
    return full


def _writable(test: ShearTest) -> tuple[np.ndarray, np.ndarray]:
    """Writable copies of ``test``'s (read-only) displacement and time, kept per test: Numba
    compiles a read-only array as a second signature of the law's whole loop."""
    w = _WRITABLE.get(test)
    if w is None:
        w = _WRITABLE[test] = (np.array(test.disp, dtype=float), np.array(test.time, dtype=float))
    return w


def _simulate(spec: LawSpec, p: np.ndarray, test: ShearTest,
              out: np.ndarray | None = None, substeps: int = 1) -> tuple[int, np.ndarray]:
    """Force [kN] of ``test``'s samples, and the driver's status (``substeps`` sub-increments of
    the law per sample; 1: the sample steps themselves).

    When the test has ``preceding`` tests (:meth:`rrfrei.io.ShearTest.after`) the law is driven
    through them first, along their concatenation with the test (:func:`rrfrei.io.concat_tests`:
    real time only if every part has it), so the state the specimen carries into the test is in
    the force; only the test's own samples are returned.
    """
    n = len(test)
    if np.shape(p) != (len(spec.param_names),):
        raise ValueError(f"law {spec.name!r}: {np.shape(p)} parameter values, expected "
                         f"({len(spec.param_names)},) in the order {', '.join(spec.param_names)}")
    F = np.empty(n) if out is None else out
    sc = np.array(spec.initial_state, dtype=float)
    if not test.preceding:
        T = np.empty(n)
        disp, time = _writable(test)
        status, _ = history(spec)(p, sc, sc.copy(), disp, time, bool(test.has_time), substeps, F, T)
        return int(status), F
    full = _history_of(test)
    Ff = np.empty(len(full))
    T = np.empty(len(full))
    disp, time = _writable(full)
    status, _ = history(spec)(p, sc, sc.copy(), disp, time, bool(full.has_time), substeps, Ff, T)
    F[:] = Ff[len(full) - n:]
    return int(status), F


def _failed(r: np.ndarray, big: float) -> bool:
    """Whether residuals ``r`` are a fit's failure value (``big`` everywhere: the simulation failed)."""
    return bool(r.size and r[0] == big and np.all(r == big))


DIFF_STEP = 1e-6
"""Relative step of the forward differences of the fits' Jacobian (scipy's ``diff_step``)."""


def one_sided_jacobian(resid, lb: np.ndarray, ub: np.ndarray, big: float):
    """``(fun, jac)`` for least squares: ``fun`` is ``resid`` remembering its last point, ``jac``
    the forward-difference Jacobian of ``resid`` that least squares takes with ``diff_step =``
    :data:`DIFF_STEP` (scipy's ``approx_derivative``, the same steps and numbers), except where a
    forward step fails (``resid`` returns its failure value ``big`` everywhere: the law's local
    iteration failed there): that column is the backward difference, and zero when both sides
    fail.

    An optimum can sit on the edge of the region where OpenSees' local iteration of a law fails
    (a real test; its rounded parameters fail).  A failed step read as a difference gives a column
    of size ``big / h``, and the trust region cannot then leave the start in any direction, even
    along an added effect's parameter whose small value lowers the error: every refit ended at its
    start.  The backward step stays on OpenSees' side of the edge.
    """
    def failed(r: np.ndarray) -> bool:
        return _failed(r, big)

    last: dict = {}

    def fun(x: np.ndarray) -> np.ndarray:
        r = resid(x)
        last["x"], last["r"] = np.array(x, dtype=float), r
        return r

    def jac(x: np.ndarray) -> np.ndarray:
        hit = "x" in last and np.array_equal(last["x"], x)
        f0 = last["r"] if hit else resid(x)  # least squares asks at the point it just evaluated
        bad: list[np.ndarray] = []

        def recording(xp: np.ndarray) -> np.ndarray:
            r = resid(xp)
            if failed(r):
                bad.append(np.array(xp, dtype=float))
            return r

        J = approx_derivative(recording, x, method="2-point", rel_step=DIFF_STEP, f0=f0, bounds=(lb, ub))
        J = np.atleast_2d(J)
        if bad and not failed(f0):
            for xp in bad:
                j = int(np.argmax(np.abs(xp - x)))
                h = float(xp[j] - x[j])
                xm = np.array(x, dtype=float)
                xm[j] = x[j] - h
                fm = resid(xm) if lb[j] <= xm[j] <= ub[j] and h != 0.0 else None
                J[:, j] = 0.0 if fm is None or failed(fm) else (f0 - fm) / h
        return J

    return fun, jac


RETRY_SUBSTEPS = (1, 4, 16)
"""Sub-increments per sample tried, in turn, when a prediction's simulation fails
(:func:`simulate_retry`)."""


def simulate_retry(spec: LawSpec, p: np.ndarray, test: ShearTest) -> tuple[int, np.ndarray, int]:
    """:func:`_simulate` for a prediction: a failing local solve (status != 0 or a non-finite
    force) is retried with :data:`RETRY_SUBSTEPS` sub-increments per sample.

    Returns ``(status, force [kN], substeps used)``, status 0 on success.  A failed run's force
    is NaN from its first sample on, never the uninitialised memory a failed driver leaves
    behind.  More sub-increments change the result by the law's step-size dependence (implicit
    integration over each increment): a retried prediction is the law refined in time, which the
    caller reports.
    """
    status = -99
    F = np.empty(len(test))
    for sub in RETRY_SUBSTEPS:
        try:
            status, _ = _simulate(spec, p, test, F, substeps=sub)
        except NUMERICAL_ERRORS:
            status = -98
        if status == 0 and np.all(np.isfinite(F)):
            return 0, F, sub
    F[:] = np.nan
    return (status if status != 0 else -3), F, RETRY_SUBSTEPS[-1]


@dataclass(eq=False)
class IsolatorFit(FitResult):
    """A fitted isolator law (optimum + Laplace draws)."""

    spec: LawSpec
    p_opt: np.ndarray
    P: np.ndarray  # (S, nparams) draws
    sig: np.ndarray  # (S,) noise sd draws
    sigma: float
    noise: float
    free: tuple[str, ...]
    seed: int = 0
    note: str = ""  # e.g. a regularised Laplace covariance
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.spec.name

    notes: list = field(default_factory=list, repr=False)
    """The texts :meth:`add_note` recorded, as :class:`rrfrei.notes.Note` (with a severity)."""

    @property
    def params(self) -> dict[str, float]:  # type: ignore[override]
        return self.spec.as_dict(self.p_opt)

    def predict(self, data: ShearTest) -> Prediction:
        key = id(data)
        if key in self._cache:
            return self._cache[key][1]
        S = self.P.shape[0]
        # importance resampling repeats draws: each distinct parameter vector is simulated once
        # (a simulation is deterministic, so the forces are the same as one run per draw)
        U, inv = np.unique(self.P, axis=0, return_inverse=True)
        inv = np.asarray(inv).reshape(-1)
        FU = np.empty((U.shape[0], len(data)))
        stU = np.zeros(U.shape[0], dtype=np.int64)
        subU = np.ones(U.shape[0], dtype=np.int64)
        for j in range(U.shape[0]):
            stU[j], FU[j], subU[j] = simulate_retry(self.spec, U[j], data)
        F = FU[inv]
        status = stU[inv]
        ok = status == 0  # simulate_retry: status 0 means every force finite
        n_ok = int(ok.sum())
        dname = getattr(data, "name", "?")
        refined = int(np.sum(subU[inv][ok] > 1))
        if not ok.any():
            st, f0, sub = simulate_retry(self.spec, self.p_opt, data)
            if st != 0:
                raise NumericalFailure(
                    f"law '{self.spec.name}' on test '{dname}': every posterior draw and the optimum "
                    f"fail (status {st}, also with {RETRY_SUBSTEPS[-1]} sub-increments per sample)")
            F, ok = f0[None, :], np.array([True])
            sig = np.array([self.sigma])
            refined = int(sub > 1)
        else:
            sig = self.sig[: F.shape[0]]
        if refined:
            self.add_note(
                f"law '{self.spec.name}' on test '{dname}': {refined} of {max(n_ok, 1)} predictions "
                f"ran with {'/'.join(map(str, RETRY_SUBSTEPS[1:]))} sub-increments per sample (the "
                "law's local solve failed on the sample steps)")
        if n_ok < S:
            bad = sorted({int(c) for c in status[status != 0]})
            self.add_note(
                f"law '{self.spec.name}' on test '{dname}': {S - n_ok} of {S} "
                f"posterior draws failed (status {', '.join(map(str, bad))}, "
                f"also with {RETRY_SUBSTEPS[-1]} sub-increments); "
                + (f"its band uses the {n_ok} that ran" if n_ok else
                   "its band is the optimum's prediction with the noise alone"),
                # a band from fewer than half the draws is not the posterior's band
                "critical" if 2 * n_ok < S else "warning")
        F, sig = F[ok], sig[ok]
        rng = np.random.default_rng(self.seed + 1)
        # at least MIN_BAND_SAMPLES noisy replicates, so that few surviving draws (or the optimum
        # alone) still give a band of the noise's width, never a zero-width one
        reps = -(-MIN_BAND_SAMPLES // F.shape[0])
        if reps > 1:
            F_rep, sig_rep = np.repeat(F, reps, axis=0), np.repeat(sig, reps)
        else:
            F_rep, sig_rep = F, sig
        Y = F_rep + rng.normal(size=F_rep.shape) * sig_rep[:, None]
        a = (1 - LEVEL) / 2
        lo, hi = np.quantile(Y, [a, 1 - a], axis=0)
        pred = Prediction(mean=F.mean(axis=0), lower=lo, upper=hi, draws=F, sigma=sig)
        self._cache[key] = (data, pred)  # keep data alive so id() stays unique
        return pred

    def loglik(self, data: ShearTest) -> np.ndarray:
        return gaussian_loglik(data.force, self.predict(data))


class IsolatorModel(GapModel):
    """An isolator law (possibly augmented) fitted to :class:`~rrfrei.io.ShearTest` data.

    Parameters
    ----------
    law : base law name or spec (``"bouc_wen"``), possibly already augmented.
    fixed : law parameters held at given values (e.g. ``{"alpha2": 0.0}``).
    draws : posterior (Laplace) draws per fit.
    """

    def __init__(self, law: str | LawSpec, *, fixed: Mapping[str, float] | None = None,
                 draws: int = 200, variants: Mapping[str, str] | None = None) -> None:
        self.spec = get(law)
        self.fixed = dict(fixed or {})
        for k in self.fixed:
            self.spec.param(k)
        if not isinstance(draws, (int, np.integer)) or draws < 10:
            raise ValueError(f"draws must be an integer >= 10, got {draws!r}")
        self.draws = int(draws)
        self.variant = {e: v for e, v in dict(variants or {}).items() if v}
        for e, v in self.variant.items():
            if e not in self.spec.effects:
                raise ValueError(f"variant {v!r} given for effect {e!r}, which law "
                                 f"{self.spec.name!r} does not have")
            catalogue()[e].as_variant(v)  # raises for an unknown variant

    def _info(self, effect: str):
        """The catalogue's hints of ``effect`` as this model fits it (its variant, if any)."""
        return catalogue()[effect].as_variant(self.variant.get(effect, ""))

    def variants(self, effect: str) -> tuple[str, ...]:
        return tuple(v.name for v in catalogue()[effect].variants)

    def effect_hints(self, effect: str):
        """The catalogue's fitting hints of ``effect`` (scales, box, starts) as this model fits it
        (its variant, if any): public for other models that fit the same law (the building)."""
        return self._info(effect)

    def free_parameters(self, data: ShearTest) -> tuple[tuple[str, ...], dict[str, float]]:
        """(fitted parameter names, fixed values) of this law on ``data`` (see :meth:`fit`)."""
        return self._free(data)

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.spec.name

    def augment(self, effects: Sequence[str], variants: Mapping[str, str] | None = None) -> IsolatorModel:
        """This law with ``effects`` added; ``variants``: effect -> variant to fit it by (the
        model's own choices are kept)."""
        base = self.spec.name.split("+")[0]
        have = list(self.spec.effects)
        return IsolatorModel("+".join([base, *have, *effects]), fixed=self.fixed, draws=self.draws,
                             variants={**self.variant, **dict(variants or {})})

    def observed(self, data: ShearTest) -> np.ndarray:
        return np.asarray(data.force, dtype=float)

    def groups(self, data: ShearTest) -> np.ndarray:
        from rrfrei.calibration.compare import cycle_groups

        return cycle_groups(np.asarray(data.disp))

    def cannot_judge(self, effect: str, data: ShearTest) -> str | None:
        if catalogue()[effect].needs_time and not data.has_time:
            return f"test {data.name!r} has no time column: {effect} effects cannot be judged"
        return None

    # --- fitting ---------------------------------------------------------------------------
    def _free(self, data: ShearTest) -> tuple[tuple[str, ...], dict[str, float]]:
        """Fitted and fixed parameters: an effect's optional shape parameter (one with a default,
        so that a user may leave it out) is fitted when the effect's ``scales`` hint names it."""
        sample = {k for eff in self.spec.effects
                  for k in self._info(eff).scales(_UNIT_SCALES)
                  if self.spec.param(k).optional}
        return self.spec.resolve_fixed(data.geometry, self.fixed, sample=frozenset(sample),
                                       source=f"test {data.name!r}")

    def _base_start(self, data: ShearTest, free, fixed, seed: int,
                    budget: TimeBudget | None = None) -> list[dict[str, float]]:
        """Start of the baseline least squares: the better (lower squared error) of the optimum of
        :func:`rrfrei.calibrate`'s own global search (same problem, seed and evaluations) and a
        shorter search from another seed (another basin).  Least squares never raises the squared
        error of its start, so the baseline is never worse than calibrate's optimum; one polish
        (not one per start) keeps the cost of long tests down."""
        from rrfrei.calibration import setup_problem
        from rrfrei.calibration.sampler import find_map

        base = get(self.spec.name.split("+")[0])
        bfix = {k: v for k, v in fixed.items() if k in base.param_names}
        prob = setup_problem(data, base, fixed=bfix)
        best, best_sse = None, math.inf
        y = np.asarray(data.force, dtype=float)
        for s, evals in ((seed, None), (seed + 1, GLOBAL_EVALS * max(len(prob.free), 1))):
            theta, _ = find_map(prob, s, max_evals=evals, budget=budget)
            vals = dict(bfix)
            vals.update({n: float(x) for n, x in zip(prob.free, theta[: len(prob.free)])})
            p = prob.template.copy()
            p[prob.free_idx] = theta[: len(prob.free)]
            try:
                st, f = _simulate(base, p, data)
                sse = float(np.sum((f - y) ** 2)) if st == 0 else math.inf
            except NUMERICAL_ERRORS:
                sse = math.inf
            if best is None or sse < best_sse:
                best, best_sse = vals, sse
        return [best]

    def early(self, data: ShearTest) -> ShearTest | None:
        """The first half of the test (small amplitudes of a growing protocol), or None."""
        n = len(data) // 2
        if n < 50:
            return None
        return ShearTest(data.name + "[first half]", data.time[:n], data.disp[:n], data.force[:n],
                         has_time=data.has_time, geometry=dict(data.geometry),
                         preceding=data.preceding)

    # --- checkpoints -------------------------------------------------------------------------
    def checkpoint_key(self, data: ShearTest) -> str:
        """SHA-256 of the test's samples and geometry (and those of its ``preceding`` tests, when
        it has any), the law, fixed values, draws and search size."""
        h = hashlib.sha256()
        for a in (data.time, data.disp, data.force):
            h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
        settings = {"has_time": bool(data.has_time),
                    "geometry": {str(k): repr(v) for k, v in sorted(dict(data.geometry).items())},
                    "law": self.spec.name, "fixed": sorted(self.fixed.items()),
                    "draws": self.draws, "global_evals": GLOBAL_EVALS, "format": CHECKPOINT_FORMAT}
        if self.variant:  # absent otherwise: the keys of primary fits are unchanged
            settings["variants"] = sorted(self.variant.items())
        if data.preceding:  # absent otherwise: the keys of tests without history are unchanged
            settings["preceding"] = [self.checkpoint_key(t) for t in data.preceding]
        h.update(json.dumps(settings, sort_keys=True).encode())
        return h.hexdigest()

    def fit_state(self, fit: IsolatorFit) -> dict[str, np.ndarray]:
        return {"law": np.array(fit.spec.name), "p_opt": fit.p_opt, "P": fit.P, "sig": fit.sig,
                "sigma": np.array(fit.sigma), "noise": np.array(fit.noise),
                "free": np.array(fit.free, dtype=str), "seed": np.array(fit.seed),
                "note": np.array(fit.note)}

    def restore(self, state: Mapping[str, np.ndarray]) -> IsolatorFit:
        return IsolatorFit(spec=get(str(state["law"])), p_opt=np.asarray(state["p_opt"], dtype=float),
                           P=np.asarray(state["P"], dtype=float), sig=np.asarray(state["sig"], dtype=float),
                           sigma=float(state["sigma"]), noise=float(state["noise"]),
                           free=tuple(str(x) for x in state["free"]), seed=int(state["seed"]),
                           note=str(state["note"]) if "note" in state else "")

    def fit(self, data: ShearTest, *, seed: int = 0,
            start: FitResult | Sequence[FitResult] | None = None,
            budget: TimeBudget | None = None) -> IsolatorFit:
        """Optimum and Laplace draws; ``start``: fits whose parameters seed the search (several
        allowed: each is combined with every catalogue start of the added effects).

        A start whose least-squares search fails is dropped; a simulation that fails (local
        Newton, non-finite force, rejected parameters) is a bad point (a large constant residual),
        never an exception.  ``budget`` is checked at every evaluation and raises
        :class:`rrfrei.budget.BudgetExceeded` once spent.

        Raises
        ------
        NumericalFailure
            when no start can be fitted, or the Laplace covariance cannot be formed; the message
            names the law, the test and the step.
        """
        if not isinstance(data, ShearTest):
            raise ValueError(f"data must be a ShearTest, got {type(data).__name__}")
        spec = self.spec
        where = f"law {spec.name!r} on test {data.name!r}"
        if budget is not None:
            budget.check()
        free, fixed = self._free(data)
        sc = test_scales(data)
        extra_bases: list[dict[str, float]] = []
        if isinstance(start, Sequence) and not isinstance(start, FitResult):
            extra_bases = [dict(s.params) for s in start[1:]]
            start = start[0] if start else None
        if start is not None:
            base_vals = dict(start.params)
        elif not spec.effects:
            base_vals, *more = self._base_start(data, free, fixed, seed, budget)
            extra_bases += more
        else:
            base_vals = {}
        if spec.effects and start is None:
            base_vals = IsolatorModel(spec.name.split("+")[0], fixed=self.fixed, draws=self.draws) \
                .fit(data, seed=seed, budget=budget).params
        starts: list[dict[str, float]] = [{}]
        scale = {n: max(abs(base_vals.get(n, 0.0)), 1e-12) for n in free}
        box: dict[str, tuple[float, float]] = {}
        for eff in spec.effects:
            info = self._info(eff)
            es = info.scales(sc)
            scale.update({k: v for k, v in es.items() if k in free})
            box.update(info.box(sc))
            missing = [k for k in es if k not in base_vals]
            if missing:
                neutral = dict(zip([q.name for q in info.spec.params], info.spec.neutral))
                bx = info.box(sc)
                neutral = {k: min(max(v, bx.get(k, (v, v))[0]), bx.get(k, (v, v))[1])
                           for k, v in neutral.items()}
                starts = [dict(s0, **e) for s0 in starts for e in [*info.starts(sc), neutral]]
        if spec.effects:
            starts = starts + [dict(b, **s0) for b in extra_bases for s0 in starts
                               if any(k not in base_vals for k in s0)]
        else:  # the base law: every start is a full set of its parameters
            starts = starts + [dict(b) for b in extra_bases]
        idx = {n: i for i, n in enumerate(spec.param_names)}
        p0 = np.array(spec.initial_state[:0].tolist() + [0.0] * len(spec.params))
        for p in spec.params:
            p0[idx[p.name]] = fixed.get(p.name, base_vals.get(p.name, p.default if p.optional else 0.0)
                                        if p.name in base_vals or p.optional else _mid(p))
        fi = np.array([idx[n] for n in free], dtype=int)
        s_vec = np.array([scale.get(n, 1.0) for n in free])
        lb = np.array([max(spec.param(n).lower, box.get(n, (-np.inf, 0))[0]) for n in free]) / s_vec
        ub = np.array([min(spec.param(n).upper, box.get(n, (0, np.inf))[1]) for n in free]) / s_vec
        y = np.asarray(data.force, dtype=float)
        F = np.empty(len(data))
        big = 10.0 * float(np.sqrt(np.mean(y**2))) + 1.0

        def resid(x: np.ndarray) -> np.ndarray:
            p = p0.copy()
            p[fi] = x * s_vec
            if budget is not None:
                budget.check()
            if spec.check is not None:
                try:
                    spec.check(p)
                except ValueError:
                    return np.full(y.size, big)
            try:
                st, _ = _simulate(spec, p, data, F)
            except NUMERICAL_ERRORS:
                return np.full(y.size, big)
            if st != 0 or not np.all(np.isfinite(F)):
                return np.full(y.size, big)
            return F - y

        # every start runs SCREEN_ITERATIONS iterations first; the cut starts are continued from the
        # lowest, each only while it can still win against the lowest cost reached so far
        # (:func:`_worth_continuing`), so starts that creep far above the others' optimum do not
        # run to max_nfev
        max_nfev = 200 * max(len(free), 1)

        fun, jac = one_sided_jacobian(resid, lb, ub, big)

        def search(x0, nfev, guard):
            with one_blas_thread():  # also when a fit runs outside the engine (the building's loop fit)
                return least_squares(fun, x0, bounds=(lb, ub), method="trf", x_scale=1.0,
                                     max_nfev=nfev, jac=jac, callback=guard)

        runs = []
        for s0 in starts:
            x0 = np.array([(s0[n] if n in s0 else p0[idx[n]]) for n in free]) / s_vec
            x0 = np.clip(x0, lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
            guard = _Guard(SCREEN_ITERATIONS)
            try:
                res = search(x0, max_nfev, guard)
            except ValueError:
                continue
            runs.append((res, guard))
        if runs:
            lead = min(r.cost for r, _ in runs)
            for i in sorted(range(len(runs)), key=lambda j: runs[j][0].cost):
                res, guard = runs[i]
                if guard.cut and _worth_continuing(guard.costs, lead):
                    try:
                        more = search(res.x, max(max_nfev - res.nfev, 1), _Guard(None))
                    except ValueError:
                        continue
                    if more.cost <= res.cost:
                        runs[i] = (more, guard)
                        lead = min(lead, more.cost)
        best = min((r for r, _ in runs), key=lambda r: r.cost, default=None)
        if best is None or not np.all(np.isfinite(best.x)):
            raise NumericalFailure(f"least-squares fit of {where}: every start failed "
                                   f"({len(starts)} starts)")
        p_opt = p0.copy()
        p_opt[fi] = best.x * s_vec
        r = best.fun
        n, k = y.size, len(free)
        rss = float(r @ r)
        sigma = math.sqrt(rss / n)
        # Laplace proposal in the scaled coordinates, with a weak ridge (prior sd of one parameter
        # scale) so unidentified directions do not spread without limit
        if not rss > 0.0 or not math.isfinite(rss):
            raise NumericalFailure(f"Laplace posterior of {where}: residual sum of squares at the "
                                   f"optimum is {rss!r} (expected finite > 0)")
        cov, note = laplace_cov(best.jac, rss / max(n - k, 1), k, where)
        # common random numbers: parameter j of the spec always gets the same normal column, so
        # nested laws (base vs base+effect) are compared with little Monte Carlo noise
        S = self.draws
        Zn = np.column_stack([np.random.default_rng([seed, int(j)]).normal(size=S) for j in fi]) \
            if k else np.zeros((S, 0))
        try:
            L = np.linalg.cholesky(cov) if k else np.zeros((0, 0))
        except np.linalg.LinAlgError:
            w, V = np.linalg.eigh(cov)
            L = V * np.sqrt(np.clip(w, 0, None))
        X = np.clip(best.x[None, :] + Zn @ L.T, lb, ub)
        X[0] = best.x
        # importance resampling to the posterior (flat prior on theta and log sigma, sigma
        # integrated out: p(theta | y) ~ RSS(theta)^(-n/2)), systematic resampling
        logw = np.full(S, -np.inf)
        rss_draw = np.empty(S)
        for i in range(S):
            ri = resid(X[i])
            rss_draw[i] = float(ri @ ri)
            if not _failed(ri, big):
                logw[i] = -0.5 * n * math.log(rss_draw[i]) + 0.5 * float(Zn[i] @ Zn[i])
        logw[0] = max(logw[0], -0.5 * n * math.log(rss))
        w = np.exp(logw - logw.max())
        w /= w.sum()
        u0 = np.random.default_rng([seed, 998]).uniform()
        pick = np.minimum(np.searchsorted(np.cumsum(w), (u0 + np.arange(S)) / S), S - 1)
        X = X[pick]
        P = np.repeat(p_opt[None, :], S, axis=0)
        P[:, fi] = X * s_vec
        rss_s = rss_draw[pick]  # the resampled draws' residuals were computed above
        sig = np.sqrt(rss_s / np.random.default_rng([seed, 999]).chisquare(n, size=S))
        self.last_ess = float(1.0 / np.sum(w**2))
        if self.last_ess < MIN_ESS:
            degenerate = (f"importance resampling of {where} degenerate (effective sample size "
                          f"{self.last_ess:.1f} of {S} Laplace draws, {len(np.unique(pick))} distinct): "
                          f"its bands and leave-one-out scores carry almost no parameter uncertainty")
            note = f"{note}; {degenerate}" if note else degenerate
        return IsolatorFit(spec=spec, p_opt=p_opt, P=P, sig=sig, sigma=sigma, noise=white_noise(r),
                           free=free, seed=seed, note=note)


def _mid(p) -> float:
    lo, hi = p.lower, p.upper
    return 0.5 * (lo + hi) if math.isfinite(lo) and math.isfinite(hi) else 0.0
