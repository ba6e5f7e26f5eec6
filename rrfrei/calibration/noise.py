"""Residual (noise) models of the calibration likelihood: one object per model, decided once.

A :class:`NoiseModel` says everything the calibration needs about the residuals
``e = F_measured - F_model`` [kN] at the likelihood's samples:

* its sampled parameters (``sigma`` [kN]; ``rho`` [-] for AR(1)) with their bounds and priors;
* their maximum-likelihood values given residuals (the optimiser profiles them out);
* the pointwise log density of residuals (stored for LOO/WAIC, used by the optimiser), whose
  sum is the joint log-likelihood the Numba batch of :mod:`.likelihood` computes in one pass
  (a test holds the two equal);
* simulated residual histories (posterior predictive bands).

Models (Box & Jenkins, *Time Series Analysis*, ch. 7):

* ``"iid"``: independent N(0, sigma^2);
* ``"ar1"``: stationary AR(1), ``e_i = rho e_{i-1} + w_i``, ``w_i ~ N(0, sigma^2)``,
  ``e_1 ~ N(0, sigma^2 / (1 - rho^2))``; the pointwise term of sample i is the conditional
  density ``log p(e_i | e_{i-1})`` (the marginal for i = 1).

:func:`noise_model` turns a name into the model (a ``ValueError`` names the allowed ones); the
public functions resolve it once and pass the object down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rrfrei.laws import Prior

__all__ = ["NOISE_MODELS", "NoiseModel", "noise_model", "pointwise_from_residuals", "simulate_noise"]

NOISE_MODELS = ("iid", "ar1")
_LOG2PI = math.log(2.0 * math.pi)
RHO_PRIOR = 0.99
"""``rho`` ~ uniform(-RHO_PRIOR, RHO_PRIOR) (its bounds are the open interval (-1, 1))."""
RHO_MLE = 0.98
"""The profiled ``rho`` is clipped to [-RHO_MLE, RHO_MLE], inside the prior's support."""


@dataclass(frozen=True)
class NoiseModel:
    """A residual model (see the module docstring); build it with :func:`noise_model`.

    Attributes
    ----------
    name : ``"iid"`` or ``"ar1"``.
    """

    name: str

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or self.name not in NOISE_MODELS:
            raise ValueError(f"noise = {self.name!r}: expected one of {', '.join(NOISE_MODELS)}")

    def __str__(self) -> str:
        return self.name

    @property
    def ar1(self) -> bool:
        return self.name == "ar1"

    @property
    def params(self) -> tuple[str, ...]:
        """Sampled noise parameters, in the order they follow the law parameters in ``theta``."""
        return ("sigma", "rho") if self.ar1 else ("sigma",)

    @property
    def units(self) -> tuple[str, ...]:
        return ("kN", "-") if self.ar1 else ("kN",)

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds of :attr:`params` (sigma >= 0 [kN], rho >= -1)."""
        return np.array([0.0, -1.0] if self.ar1 else [0.0])

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds of :attr:`params` (sigma unbounded, rho <= 1)."""
        return np.array([np.inf, 1.0] if self.ar1 else [np.inf])

    def priors(self, force: np.ndarray) -> dict[str, Prior]:
        """Default priors: sigma [kN] ~ halfnormal(RMS(force)); rho ~ uniform(-0.99, 0.99)."""
        rms = float(np.sqrt(np.mean(np.square(force))))
        out = {"sigma": Prior("halfnormal", max(rms, 1e-12))}
        if self.ar1:
            out["rho"] = Prior("uniform", -RHO_PRIOR, RHO_PRIOR)
        return out

    def split(self, theta_noise: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(sigma, rho or None) columns of noise-parameter rows (nw, len(params))."""
        t = np.atleast_2d(np.asarray(theta_noise, dtype=float))
        return np.ascontiguousarray(t[:, 0]), (np.ascontiguousarray(t[:, 1]) if self.ar1 else None)

    def mle(self, resid: np.ndarray) -> np.ndarray:
        """Maximum-likelihood noise parameters (nw, len(params)) per row of residuals [kN].

        iid: ``sigma = RMS(e)``; AR(1): the least-squares ``rho`` of ``e_i`` on ``e_{i-1}``
        (clipped to :data:`RHO_MLE`) and ``sigma`` the RMS of the innovations.
        """
        r = np.atleast_2d(resid)
        if not self.ar1:
            return np.sqrt(np.mean(r * r, axis=1))[:, None]
        num = np.sum(r[:, 1:] * r[:, :-1], axis=1)
        den = np.sum(r[:, :-1] ** 2, axis=1)
        rho = np.clip(num / np.where(den > 0, den, 1.0), -RHO_MLE, RHO_MLE)
        innov = r[:, 1:] - rho[:, None] * r[:, :-1]
        return np.column_stack([np.sqrt(np.mean(innov**2, axis=1)), rho])

    def pointwise(self, resid: np.ndarray, theta_noise: np.ndarray) -> np.ndarray:
        """(nw, points) log densities of residual rows given noise-parameter rows."""
        sigma, rho = self.split(theta_noise)
        return pointwise_from_residuals(np.atleast_2d(resid), sigma, rho)

    def whiten(self, J: np.ndarray, theta_noise: np.ndarray) -> np.ndarray:
        """Rows of ``J`` (points, k) mapped as residuals to their standardised innovations.

        iid: ``J / sigma``; AR(1): ``sqrt(1 - rho^2) J_0 / sigma`` then
        ``(J_i - rho J_{i-1}) / sigma`` (the densities of :meth:`pointwise`).
        """
        sigma, rho = self.split(theta_noise)
        s = float(sigma[0])
        if rho is None:
            return J / s
        r = float(rho[0])
        return np.vstack([J[:1] * math.sqrt(max(1.0 - r * r, 0.0)), J[1:] - r * J[:-1]]) / s

    def simulate(self, rng: np.random.Generator, theta_noise: np.ndarray, n: int) -> np.ndarray:
        """Residual histories (rows, n) drawn from the model for noise-parameter rows."""
        sigma, rho = self.split(theta_noise)
        return simulate_noise(rng, sigma, rho, n)


def noise_model(noise: str | NoiseModel) -> NoiseModel:
    """The :class:`NoiseModel` named ``noise`` (a model is returned as it is)."""
    return noise if isinstance(noise, NoiseModel) else NoiseModel(noise)  # which validates it


def pointwise_from_residuals(resid: np.ndarray, sigma: np.ndarray, rho: np.ndarray | None) -> np.ndarray:
    """(draws, points) log densities of residuals ``resid`` (draws, points) [kN]; ``rho`` None: iid."""
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


def simulate_noise(rng: np.random.Generator, sigma: np.ndarray, rho: np.ndarray | None, n: int) -> np.ndarray:
    """Residual histories (..., n) [kN] from the noise model with per-draw sigma (, rho)."""
    sigma = np.asarray(sigma, dtype=float)
    w = rng.standard_normal(sigma.shape + (n,)) * sigma[..., None]
    if rho is None:
        return w
    r = np.asarray(rho, dtype=float)
    e = np.empty_like(w)
    e[..., 0] = w[..., 0] / np.sqrt(1.0 - r**2)
    for i in range(1, n):
        e[..., i] = r * e[..., i - 1] + w[..., i]
    return e
