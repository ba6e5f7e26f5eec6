"""Batched Gaussian log-likelihoods of a shear test under any registered law (Numba, parallel).

Model: measured force ``F_i = f(u_1..u_i; theta) + e_i`` where ``f`` is the law driven along the
measured displacement history (the law's whole-history driver,
:func:`rrfrei.laws.specialise.history`: one implicit update per sample, exactly as an OpenSees
displacement-controlled analysis) and the residuals ``e`` are

* ``noise="iid"``: independent N(0, sigma^2);
* ``noise="ar1"``: stationary AR(1), ``e_i = rho e_{i-1} + w_i``, ``w_i ~ N(0, sigma^2)``,
  ``e_1 ~ N(0, sigma^2 / (1 - rho^2))``.  The pointwise log-likelihood of sample i is the
  conditional density ``log p(e_i | e_{i-1})`` (and the marginal for i = 1), so the points sum to
  the joint log-likelihood (Box & Jenkins, *Time Series Analysis*, ch. 7).

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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rrfrei.io import ShearTest
from rrfrei.laws import LawSpec, Prior
from rrfrei.laws.specialise import history, instantiate

__all__ = ["Problem", "NOISE_MODELS", "DENSE_POINTS", "LIKELIHOOD_POINTS", "likelihood_points"]

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

NOISE_MODELS = ("iid", "ar1")
_LOG2PI = math.log(2.0 * math.pi)
BATCH = "rrfrei.calibration._batch"
"""The template of the batched kernels (``forces_batch``, ``loglik_batch``), bound per law."""


def batch_kernels(spec: LawSpec):
    """The batched kernels of law ``spec``: the instance of :data:`BATCH` bound to the law's
    whole-history driver (:func:`rrfrei.laws.specialise.history`)."""
    return instantiate(BATCH, {"law_drive": history(spec)}, spec.name)


def pointwise_from_residuals(resid: np.ndarray, sigma: np.ndarray, rho: np.ndarray | None) -> np.ndarray:
    """(draws, points) log densities of residuals ``resid`` (draws, points)."""
    s = np.asarray(sigma, dtype=float)[:, None]
    if rho is None:
        return -0.5 * (resid / s) ** 2 - np.log(s) - 0.5 * _LOG2PI
    r = np.asarray(rho, dtype=float)[:, None]
    out = np.empty_like(resid)
    var0 = s[:, 0] ** 2 / (1 - r[:, 0] ** 2)
    out[:, 0] = -0.5 * resid[:, 0] ** 2 / var0 - 0.5 * np.log(var0) - 0.5 * _LOG2PI
    innov = resid[:, 1:] - r * resid[:, :-1]
    out[:, 1:] = -0.5 * (innov / s) ** 2 - np.log(s) - 0.5 * _LOG2PI
    return out


@dataclass(eq=False)
class Problem:
    """A law, a test, the fixed values and the priors: everything the sampler needs.

    ``theta`` rows are ``[free law parameters (spec order)..., sigma, (rho)]``.  ``lik_idx``: the
    samples the likelihood uses (:func:`likelihood_points`; None: all of them).
    """

    spec: LawSpec
    test: ShearTest
    free: tuple[str, ...]
    fixed: dict[str, float]
    noise: str
    priors: dict[str, Prior]
    lik_idx: np.ndarray | None = None
    template: np.ndarray = field(init=False)
    free_idx: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        if self.noise not in NOISE_MODELS:
            raise ValueError(f"noise must be one of {NOISE_MODELS}, got {self.noise!r}")
        names = self.spec.param_names
        tmpl = np.zeros(len(names))
        for i, p in enumerate(self.spec.params):
            if p.name in self.fixed:
                tmpl[i] = self.fixed[p.name]
            elif p.name not in self.free:
                tmpl[i] = p.default  # optional parameter at its default
        self.template = tmpl
        self.free_idx = np.array([names.index(n) for n in self.free], dtype=np.int64)
        self._disp = np.ascontiguousarray(self.test.disp)
        self._obs = np.ascontiguousarray(self.test.force)
        n = self._disp.size
        idx = np.arange(n, dtype=np.int64) if self.lik_idx is None else np.asarray(self.lik_idx, np.int64)
        if idx.ndim != 1 or idx.size < 2 or idx.min() < 0 or idx.max() >= n or np.any(np.diff(idx) <= 0):
            raise ValueError(f"lik_idx must be >= 2 increasing sample indices in [0, {n}), got {idx!r}")
        self.lik_idx = np.ascontiguousarray(idx)
        self._obs_l = np.ascontiguousarray(self._obs[idx])
        self._use_time = bool(self.test.has_time)
        self._time = np.ascontiguousarray(self.test.time if self._use_time else np.zeros_like(self._disp))
        self._state0 = np.array(self.spec.initial_state, dtype=float)
        bounds = [self.spec.bounds((n,))[0] for n in self.free]
        self._lower = np.array([b[0] for b in bounds] + [0.0] + ([-1.0] if self.noise == "ar1" else []))
        self._upper = np.array([b[1] for b in bounds] + [np.inf] + ([1.0] if self.noise == "ar1" else []))
        self.n_evals = 0

    # --- layout ---------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return self.free + (("sigma", "rho") if self.noise == "ar1" else ("sigma",))

    @property
    def ndim(self) -> int:
        return len(self.names)

    @property
    def n_points(self) -> int:
        """Samples of the test (the law is driven along all of them)."""
        return int(self._disp.size)

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
        """Rows of full-history model forces ``F`` taken at the likelihood's samples (``F`` itself
        when the likelihood uses every sample)."""
        F = np.atleast_2d(F)
        return F[:, self.lik_idx] if self.subsampled else F

    def residuals_at_points(self, F_points: np.ndarray) -> np.ndarray:
        """Residuals for model forces already taken at the likelihood's samples (rows)."""
        return self._obs_l[None, :] - np.atleast_2d(F_points)

    def residuals(self, F: np.ndarray) -> np.ndarray:
        """Residuals (measured - model) at the likelihood's samples, for full-history forces ``F``."""
        return self._obs_l[None, :] - self.at_points(F)

    def full_params(self, theta: np.ndarray) -> np.ndarray:
        """(nw, n_params) law parameter rows (free + fixed + defaults) for ``theta`` rows."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        P = np.repeat(self.template[None, :], theta.shape[0], axis=0)
        P[:, self.free_idx] = theta[:, : len(self.free)]
        return np.ascontiguousarray(P)

    def noise_params(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        theta = np.atleast_2d(theta)
        k = len(self.free)
        sigma = np.ascontiguousarray(theta[:, k])
        rho = np.ascontiguousarray(theta[:, k + 1]) if self.noise == "ar1" else None
        return sigma, rho

    # --- densities ------------------------------------------------------------------------
    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        lp = np.zeros(theta.shape[0])
        inside = np.all((theta >= self._lower) & (theta <= self._upper), axis=1)
        lp[~inside] = -np.inf
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
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        nw = theta.shape[0]
        P = self.full_params(theta)
        sigma, rho = self.noise_params(theta)
        F = np.empty((nw, self.n_points))
        T = np.empty_like(F)
        out = np.empty(nw)
        batch_kernels(self.spec).loglik_batch(
            P, self._state0, self._disp, self._time, self._use_time, self._obs_l, self.lik_idx,
            sigma, rho if rho is not None else np.zeros(nw), rho is not None, F, T, out)
        self.n_evals += nw
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

    # --- forces and pointwise -------------------------------------------------------------
    def forces(self, P: np.ndarray, test: ShearTest | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(forces (nw, n), status (nw,)) of law parameter rows ``P`` along ``test`` (default: own)."""
        P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
        if test is None:
            disp, time, use_time = self._disp, self._time, self._use_time
        else:
            disp = np.ascontiguousarray(test.disp)
            use_time = bool(test.has_time)
            time = np.ascontiguousarray(test.time if use_time else np.zeros_like(disp))
        F = np.empty((P.shape[0], disp.size))
        T = np.empty_like(F)
        status = np.zeros(P.shape[0], dtype=np.int64)
        batch_kernels(self.spec).forces_batch(P, self._state0, disp, time, use_time, F, T, status)
        F[status != 0] = np.nan
        return F, status

    def profile_noise(self, F: np.ndarray) -> np.ndarray:
        """Maximum-likelihood noise parameters per row of forces ``F``: (nw, 1 or 2)."""
        r = self.residuals(F)
        if self.noise == "iid":
            return np.sqrt(np.mean(r * r, axis=1))[:, None]
        num = np.sum(r[:, 1:] * r[:, :-1], axis=1)
        den = np.sum(r[:, :-1] ** 2, axis=1)
        rho = np.clip(num / np.where(den > 0, den, 1.0), -0.98, 0.98)
        innov = r[:, 1:] - rho[:, None] * r[:, :-1]
        sigma = np.sqrt(np.mean(innov**2, axis=1))
        return np.column_stack([sigma, rho])
