"""Batched Gaussian log-likelihoods of a shear test under any registered law (Numba, parallel).

Model: measured force ``F_i = f(u_1..u_i; theta) + e_i`` where ``f`` is the law driven along the
measured displacement history (the law's whole-history driver,
:func:`rrfrei.laws.specialise.history`: one implicit update per sample, exactly as an OpenSees
displacement-controlled analysis) and the residuals ``e`` are

* ``noise="iid"``: independent N(0, sigma^2);
* ``noise="ar1"``: stationary AR(1), ``e_i = rho e_{i-1} + w_i``, ``w_i ~ N(0, sigma^2)``,
  ``e_1 ~ N(0, sigma^2 / (1 - rho^2))``.

The noise model (parameters, bounds, priors, MLE, pointwise densities) is one
:class:`~.noise.NoiseModel` (:mod:`.noise`); the batch kernels below fuse the law run with the
sum of its pointwise densities (their equality is tested).

The walkers of the ensemble are evaluated in parallel (``prange``), each along the whole history
with preallocated work rows: no allocation per time step.  The kernels
(:mod:`rrfrei.calibration._batch`) are a template instantiated per law, with the law's driver
inlined.  A law that fails (status < 0) or a
non-positive sigma gives ``-inf``.

Dense records (:data:`DENSE_POINTS`): the law is always driven along the *whole* measured history
(its state depends on every sample), but above ``DENSE_POINTS`` samples the likelihood is
evaluated at every ``stride``-th sample only, at most :data:`LIKELIHOOD_POINTS` of them
(:func:`likelihood_points`), with the noise model (iid, or AR(1) between consecutive kept
samples) applying to the kept residuals.  Why: the residuals of a densely sampled lab record
are dominated by slowly varying model error, strongly correlated from one sample to the next;
counting 33,000 such residuals as independent makes the posterior about 16x too narrow and
ridge-shaped (the ensemble's autocorrelation time on the CLT record SPC1 rose to ~1,500 steps),
while every ``stride``-th residual is close to independent, carries the same information about
the loop's shape, and keeps the stored pointwise log-likelihood (LOO, files) small.  The
subsample is a fixed, regular grid (deterministic; no seed needed) and is reported in the
calibration's diagnostics.

Decimated input path (:func:`path_points`, ``Problem.path_idx``): on a dense quasi-static
record the law need not take one implicit step per recorded sample either.  ``rrfrei.calibrate``
drives a rate-independent law along every k-th sample of each half-cycle (>= 100 samples per
half-cycle by default, :data:`HALF_CYCLE_POINTS`), always keeping the reversals and the
likelihood's samples; the model force at a likelihood sample then differs from the whole
record's by the law's step-size error only, which is measured at the optimum
(``rrfrei.calibration.path_error``) and refined until it is below a tenth of the noise sd.  On the
CLT record SPC1 (33,028 samples, 56 reversals) the path has 7,808 samples (4.2x fewer law
steps per evaluation) and the force along it is within 0.15 kN RMS (0.04 sigma) of the whole
record's at the optimum.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from rrfrei.calibration.noise import NOISE_MODELS, NoiseModel, noise_model, pointwise_from_residuals
from rrfrei.io import ShearTest
from rrfrei.laws import LawSpec, Prior
from rrfrei.laws.specialise import history, instantiate

__all__ = ["Problem", "NOISE_MODELS", "DENSE_POINTS", "LIKELIHOOD_POINTS", "HALF_CYCLE_POINTS",
           "likelihood_points", "path_points", "half_cycles", "law_forces", "pointwise_from_residuals"]

DENSE_POINTS = 5000
"""Records with more samples than this are "dense": the likelihood uses a regular subsample."""
LIKELIHOOD_POINTS = 2000
"""Most samples the likelihood of a dense record uses by default (``likelihood_points="auto"``)."""


def likelihood_points(n: int, points: int | str | None = "auto") -> np.ndarray:
    """Indices of the samples the likelihood uses, out of ``n`` recorded samples.

    Parameters
    ----------
    n : number of samples of the test.
    points : ``"auto"`` (or None): all samples when ``n <= DENSE_POINTS``, otherwise every
        ``ceil(n / LIKELIHOOD_POINTS)``-th sample; ``"all"``: every sample; an integer N >= 2:
        every ``ceil(n / N)``-th sample (all of them when N >= n).

    Returns
    -------
    Sorted int64 indices, starting at 0, evenly spaced by ``stride``.
    """
    if points is None or (isinstance(points, str) and points.strip().lower() == "auto"):
        target = n if n <= DENSE_POINTS else LIKELIHOOD_POINTS
    elif isinstance(points, str) and points.strip().lower() == "all":
        target = n
    elif isinstance(points, (int, np.integer)) and not isinstance(points, bool) and points >= 2:
        target = int(points)
    else:
        raise ValueError(f"likelihood_points = {points!r}: expected 'auto', 'all' or an integer >= 2")
    stride = max(1, math.ceil(n / target))
    return np.arange(0, n, stride, dtype=np.int64)


HALF_CYCLE_POINTS = 100
"""Fewest samples per half-cycle the law's decimated input path keeps (``half_cycle_points="auto"``
on a dense record, :func:`path_points`)."""


def half_cycles(disp: np.ndarray) -> np.ndarray:
    """Sample indices bounding the half-cycles of ``disp``: 0, every reversal (the last sample
    before the sign of the non-zero increments changes) and n - 1, increasing and unique."""
    u = np.asarray(disp, dtype=float)
    n = u.size
    du = np.diff(u)
    nz = np.flatnonzero(du != 0.0)
    if nz.size == 0:
        return np.array([0, n - 1], dtype=np.int64) if n > 1 else np.zeros(1, dtype=np.int64)
    s = np.sign(du[nz])
    rev = nz[np.flatnonzero(s[1:] != s[:-1]) + 1]  # first increment of the new sign: its start
    return np.unique(np.concatenate([[0], rev, [n - 1]])).astype(np.int64)


def path_points(disp: np.ndarray, per_half_cycle: int | str | None = "auto",
                keep: np.ndarray | None = None, *, dense: bool | None = None) -> np.ndarray:
    """Indices of the samples the law is driven along (its input path), out of ``disp``'s.

    Decimation of a dense quasi-static record: each half-cycle (between reversals,
    :func:`half_cycles`) with ``m`` samples keeps every ``k = max(1, floor(m / N))``-th sample,
    ``N = per_half_cycle`` (so >= N samples per half-cycle, all of them when it has fewer than
    2N), plus every reversal, the last sample and the samples ``keep`` (the likelihood's, whose
    model forces must be on the path).  A rate-independent law driven along the kept samples
    walks the same displacement path with larger increments, one implicit update each; its force
    there differs from the full path's by the law's step-size error, which
    :func:`rrfrei.calibrate` measures at the optimum and reports (and refines ``N`` until it is
    small, see ``half_cycle_points`` there).

    Parameters
    ----------
    disp : displacement history [m].
    per_half_cycle : ``"auto"`` (or None): :data:`HALF_CYCLE_POINTS` when the record is dense
        (``dense``, default: more than :data:`DENSE_POINTS` samples), else every sample;
        ``"all"``: every sample; an integer N >= 2.
    keep : sample indices always on the path.
    dense : override of the density test of ``"auto"``.

    Returns
    -------
    Sorted unique int64 indices, from 0 to n - 1.
    """
    u = np.asarray(disp, dtype=float)
    n = u.size
    word = per_half_cycle.strip().lower() if isinstance(per_half_cycle, str) else None
    if per_half_cycle is None or word == "auto":
        dense = n > DENSE_POINTS if dense is None else bool(dense)
        N = HALF_CYCLE_POINTS if dense else None
    elif word == "all":
        N = None
    elif (isinstance(per_half_cycle, (int, np.integer)) and not isinstance(per_half_cycle, bool)
          and per_half_cycle >= 2):
        N = int(per_half_cycle)
    else:
        raise ValueError(f"half_cycle_points = {per_half_cycle!r}: expected 'auto', 'all' or an "
                         "integer >= 2")
    if N is None or n < 3:
        return np.arange(n, dtype=np.int64)
    b = half_cycles(u)
    parts = [b]
    for a, z in zip(b[:-1], b[1:]):
        k = max(1, (z - a) // N)
        parts.append(np.arange(a, z, k, dtype=np.int64))
    if keep is not None:
        parts.append(np.asarray(keep, dtype=np.int64))
    return np.unique(np.concatenate(parts))


_LOG2PI = math.log(2.0 * math.pi)
BATCH = "rrfrei.calibration._batch"
"""The template of the batched kernels (``forces_batch``, ``loglik_batch``), bound per law."""


def batch_kernels(spec: LawSpec):
    """The batched kernels of law ``spec``: the instance of :data:`BATCH` bound to the law's
    whole-history driver (:func:`rrfrei.laws.specialise.history`)."""
    return instantiate(BATCH, {"law_drive": history(spec)}, spec.name)


def law_forces(spec: LawSpec, P: np.ndarray, test: ShearTest) -> tuple[np.ndarray, np.ndarray]:
    """(forces (rows, n) [kN], status (rows,)) of law parameter rows ``P`` driven along ``test``'s
    displacement history (one batch, walkers in parallel); a failed row is NaN, status < 0."""
    P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
    # writable copies: a test's arrays are read-only, and Numba compiles a read-only argument as a
    # second signature of the kernel (tens of seconds cold) beside the calibration's writable one
    disp = np.array(test.disp, dtype=float)
    use_time = bool(test.has_time)
    time = np.array(test.time if use_time else np.zeros_like(disp), dtype=float)
    return _forces(spec, P, disp, time, use_time)


@contextmanager
def _threads_for(rows: int):
    """One Numba thread for a batch of one row (the optimiser's polish, the path check): the
    row runs on one thread anyway, and waking the idle pool costs more than the row when the
    cores are shared (OpenMP's waiting threads spin); larger batches keep every thread."""
    if rows > 1:
        yield
        return
    import numba

    n = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(n)


def _forces(spec: LawSpec, P, disp, time, use_time) -> tuple[np.ndarray, np.ndarray]:
    F = np.empty((P.shape[0], disp.size))
    T = np.empty_like(F)
    status = np.zeros(P.shape[0], dtype=np.int64)
    with _threads_for(P.shape[0]):
        batch_kernels(spec).forces_batch(P, np.array(spec.initial_state, dtype=float), disp, time,
                                         use_time, F, T, status)
    F[status != 0] = np.nan
    return F, status


@dataclass(eq=False)
class Problem:
    """A law, a test, the fixed values, the noise model and the priors: everything the optimiser
    and the sampler need, behind public methods.

    ``theta`` rows are ``[free law parameters (spec order)..., noise parameters]`` (``sigma``
    [kN], and ``rho`` for AR(1)); their bounds are :attr:`lower` / :attr:`upper`, the one place
    the sampler and the optimiser read them.  ``lik_idx``: the samples the likelihood uses
    (:func:`likelihood_points`; None: all of them).  ``noise`` is a :class:`~.noise.NoiseModel`
    (a name is resolved with :func:`~.noise.noise_model`).  The problem counts the law
    evaluations of its own test (:attr:`n_evals`).

    Two evaluation paths of one likelihood: :meth:`log_likelihood` (the Numba batch: the law run
    and the residual density fused in one pass per walker, for the sampler) and
    :meth:`pointwise` (the noise model's per-sample densities of given forces, stored for LOO and
    used by the optimiser's profile, :meth:`profile_log_prob`); their sums agree to rounding.
    """

    spec: LawSpec
    test: ShearTest
    free: tuple[str, ...]
    fixed: dict[str, float]
    noise: NoiseModel
    priors: dict[str, Prior]
    lik_idx: np.ndarray | None = None
    path_idx: np.ndarray | None = None
    template: np.ndarray = field(init=False)
    free_idx: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.noise = noise_model(self.noise)
        names = self.spec.param_names
        tmpl = np.zeros(len(names))
        for i, p in enumerate(self.spec.params):
            if p.name in self.fixed:
                tmpl[i] = self.fixed[p.name]
            elif p.name not in self.free:
                tmpl[i] = p.default  # optional parameter at its default
        self.template = tmpl
        self.free_idx = np.array([names.index(n) for n in self.free], dtype=np.int64)
        disp = np.asarray(self.test.disp, dtype=float)
        obs = np.ascontiguousarray(self.test.force)
        n = disp.size
        idx = np.arange(n, dtype=np.int64) if self.lik_idx is None else np.asarray(self.lik_idx, np.int64)
        if idx.ndim != 1 or idx.size < 2 or idx.min() < 0 or idx.max() >= n or np.any(np.diff(idx) <= 0):
            raise ValueError(f"lik_idx must be >= 2 increasing sample indices in [0, {n}), got {idx!r}")
        path = np.arange(n, dtype=np.int64) if self.path_idx is None else np.asarray(self.path_idx, np.int64)
        if (path.ndim != 1 or path.size < 2 or path[0] != 0 or path.max() >= n
                or np.any(np.diff(path) <= 0)):
            raise ValueError(f"path_idx must be >= 2 increasing sample indices in [0, {n}) starting "
                             f"at 0, got {path!r}")
        pos = np.searchsorted(path, idx)
        if np.any(pos >= path.size) or np.any(path[np.minimum(pos, path.size - 1)] != idx):
            raise ValueError("path_idx must hold every likelihood sample (lik_idx)")
        self.lik_idx = np.ascontiguousarray(idx)
        self.path_idx = np.ascontiguousarray(path)
        self._lik_pos = np.ascontiguousarray(pos.astype(np.int64))  # likelihood samples on the path
        self._disp = np.ascontiguousarray(disp[path])
        self._obs_l = np.ascontiguousarray(obs[idx])
        self._use_time = bool(self.test.has_time)
        time = np.asarray(self.test.time, dtype=float)[path] if self._use_time else np.zeros(path.size)
        self._time = np.ascontiguousarray(time)
        self._state0 = np.array(self.spec.initial_state, dtype=float)
        law_bounds = self.spec.bounds(self.free).reshape(-1, 2)
        self.lower = np.concatenate([law_bounds[:, 0], self.noise.lower])
        self.upper = np.concatenate([law_bounds[:, 1], self.noise.upper])
        self._n_evals = 0

    # --- layout ---------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return self.free + self.noise.params

    @property
    def ndim(self) -> int:
        return len(self.names)

    @property
    def n_evals(self) -> int:
        """Law runs along the problem's own test so far (likelihood, forces, profile)."""
        return self._n_evals

    @property
    def n_points(self) -> int:
        """Samples of the test."""
        return int(np.asarray(self.test.disp).size)

    @property
    def n_path(self) -> int:
        """Samples the law is driven along (``path_idx``; all of them unless decimated)."""
        return int(self._disp.size)

    @property
    def decimated(self) -> bool:
        return self.n_path < self.n_points

    @property
    def n_like(self) -> int:
        """Samples the likelihood uses (``lik_idx``)."""
        return int(self.lik_idx.size)

    @property
    def subsampled(self) -> bool:
        return self.n_like < self.n_points

    @property
    def observed(self) -> np.ndarray:
        """Measured forces [kN] at the likelihood's samples."""
        return self._obs_l

    def at_points(self, F: np.ndarray) -> np.ndarray:
        """Rows of model forces ``F`` along the law's path (:meth:`forces`) taken at the
        likelihood's samples (``F`` itself when the likelihood uses every path sample)."""
        F = np.atleast_2d(F)
        return F[:, self._lik_pos] if self.n_like < self.n_path else F

    def residuals_at_points(self, F_points: np.ndarray) -> np.ndarray:
        """Residuals for model forces already taken at the likelihood's samples (rows)."""
        return self._obs_l[None, :] - np.atleast_2d(F_points)

    def residuals(self, F: np.ndarray) -> np.ndarray:
        """Residuals (measured - model) at the likelihood's samples, for path forces ``F``."""
        return self._obs_l[None, :] - self.at_points(F)

    def full_params(self, theta: np.ndarray) -> np.ndarray:
        """(nw, n_params) law parameter rows (free + fixed + defaults) for ``theta`` rows (the
        noise columns, if any, are ignored)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        P = np.repeat(self.template[None, :], theta.shape[0], axis=0)
        P[:, self.free_idx] = theta[:, : len(self.free)]
        return np.ascontiguousarray(P)

    def noise_params(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(sigma, rho or None) columns of ``theta`` rows."""
        return self.noise.split(np.atleast_2d(theta)[:, len(self.free):])

    # --- densities ------------------------------------------------------------------------
    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        lp = np.zeros(theta.shape[0])
        inside = np.all((theta >= self.lower) & (theta <= self.upper), axis=1)
        lp[~inside] = -np.inf
        with np.errstate(over="ignore", invalid="ignore"):  # rows outside the bounds are -inf anyway
            for j, name in enumerate(self.names):
                lp += self.priors[name].logpdf(theta[:, j])
        if self.spec.check is not None:
            P = self.full_params(theta)
            for w in np.flatnonzero(np.isfinite(lp)):
                try:
                    self.spec.check(P[w])
                except ValueError:
                    lp[w] = -np.inf
        return lp

    def log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """Joint log-likelihood of ``theta`` rows (the Numba batch, walkers in parallel)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        nw = theta.shape[0]
        P = self.full_params(theta)
        sigma, rho = self.noise_params(theta)
        F = np.empty((nw, self.n_path))
        T = np.empty_like(F)
        out = np.empty(nw)
        batch_kernels(self.spec).loglik_batch(
            P, self._state0, self._disp, self._time, self._use_time, self._obs_l, self._lik_pos,
            sigma, rho if rho is not None else np.zeros(nw), rho is not None, F, T, out)
        self._n_evals += nw
        return out

    def log_prob(self, theta: np.ndarray) -> np.ndarray:
        """Vectorised log posterior (emcee ``vectorize=True``); -inf outside the support."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        lp = self.log_prior(theta)
        ok = np.isfinite(lp)
        if ok.any():
            lp[ok] += self.log_likelihood(theta[ok])
        lp[~np.isfinite(lp)] = -np.inf
        return lp

    def pointwise(self, F_points: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(rows, n_like) log densities of the residuals of model forces ``F_points`` (already
        at the likelihood's samples) given the noise columns of ``theta`` rows."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        return self.noise.pointwise(self.residuals_at_points(F_points), theta[:, len(self.free):])

    def profile_log_prob(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(theta rows, log posterior) for free law-parameter rows ``X`` with the noise
        parameters profiled out: set to their maximum-likelihood values given the residuals
        (:meth:`.noise.NoiseModel.mle`), the optimiser's objective.  A failing law row is -inf."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        k = len(self.noise.params)
        F, status = self.forces(self.full_params(X))
        noise = np.full((X.shape[0], k), np.nan)
        ok = status == 0
        if ok.any():
            noise[ok] = self.noise.mle(self.residuals(F[ok]))
        theta = np.column_stack([X, noise])
        lp = self.log_prior(np.where(np.isfinite(theta), theta, 1.0))
        lp[~ok] = -np.inf
        good = np.flatnonzero(np.isfinite(lp))
        if good.size:
            lp[good] += self.pointwise(self.at_points(F[good]), theta[good]).sum(axis=1)
        lp[~np.isfinite(lp)] = -np.inf
        return theta, lp

    # --- forces ---------------------------------------------------------------------------
    def forces(self, P: np.ndarray, test: ShearTest | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(forces, status (nw,)) of law parameter rows ``P`` along ``test`` (all its samples), or
        by default along the problem's own path (``(nw, n_path)`` forces at ``path_idx``; these
        runs count in :attr:`n_evals`); see :func:`law_forces`."""
        if test is not None:
            return law_forces(self.spec, P, test)
        P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
        self._n_evals += P.shape[0]
        return _forces(self.spec, P, self._disp, self._time, self._use_time)
