"""Sampling coordinates: the ensemble moves in coordinates that remove a law's worst ridges, and
every result is reported in the law's own parameters.

Nonlinear hardening (``plasticity``, ``bouc_wen`` and the laws augmented from them): the force
carries ``alpha2 k_init sgn(u) |u|^mu`` (OpenSees ``ElastomericBearingPlasticity2d.cpp`` /
``ElastomericBearingBoucWen2d.cpp``: ``qTrial = k2 ub + k3 sgn(ub) |ub|^mu + qYield z`` with
``k3 = alpha2 k_init``).  A test that shows hardening (or softening) fixes this term's size near
its peak displacement ``d = max|u|`` far better than its exponent, so in law parameters the
posterior is a funnel: with d = 85 mm, ``d^mu`` falls by 2e4 from mu = 1 to 5, and the alpha2
compatible with the data shrinks with mu as ``1 / d^mu``.  The ensemble therefore samples the
hardening force at the peak displacement

    h = alpha2 k_init d^mu   [kN]

in place of alpha2 (k_init, mu and the rest as they are) when the data show a hardening term
(:func:`sampling_coordinates`), and maps back exactly: ``alpha2 = h / (k_init d^mu)``.  The
target density in the sampling coordinates is the law posterior times the Jacobian
``|det d theta / d phi| = |d alpha2 / d h| = 1 / (k_init d^mu)`` (the map is triangular: only
alpha2 depends on h), so the chain, mapped back, samples the same posterior with the same priors
and bounds (the prior and the bounds are evaluated on the mapped-back parameters).  The stored
chain, checkpoints, diagnostics and every result are in law parameters.

Post-yield stiffness (every law with ``k_init`` and ``alpha1``: ``plasticity``, ``bouc_wen`` and
their augmentations): the force's linear hardening term is ``k2 u`` with ``k2 = alpha1 k_init``
(OpenSees' ``k2``), and the hysteretic part's elastic stiffness is ``k0 = (1 - alpha1) k_init``.
A test fixes ``k2`` (the slope of the loop's branches) and ``k0`` (the stiffness after each
reversal) directly; in (k_init, alpha1) both are products, a curved ridge, while (k_init, k2) are
linear in (k0, k2), which an affine-invariant ensemble samples as well as independent ones.  So
alpha1 is sampled as ``k2 = alpha1 k_init`` [kN/m] (:class:`PostYieldStiffness`, on top of the
hardening coordinates when they apply), Jacobian ``|d alpha1 / d k2| = 1 / k_init``.  Measured on
SPC1 (every 50 per half-cycle, 4,000 steps of 32 walkers, same seed): largest tau 130 -> 95
(qd, eta, gamma 90 -> 48), acceptance 0.10 -> 0.14, R-hat 1.062 -> 1.038.

Hardening exponent (with :class:`Hardening` and ``mu`` sampled): ``mu`` is sampled as
``s = 1 / (mu - 1)`` (:class:`HardeningExponent`), Jacobian ``|d mu / d s| = 1 / s^2``.  Why: the
hardening terms at ``x = u / d`` are ``k2 d x + h sgn(x)|x|^mu``, and with
``sgn(x)|x|^mu = x + (mu - 1) x ln|x| + ...`` near mu = 1 the data fix the linear part and the
curvature ``~ h (mu - 1)``, so along the posterior's ridge h and k2 are close to linear in
``1 / (mu - 1)``, not in mu.  On the SPC1 chain (law run along 7,808 samples), the share of
mu's variance explained linearly by the other sampling coordinates is 0.918 for mu and 0.988 for
``1 / (mu - 1)``; 4,000 steps, N = 50 per half-cycle, same seed: largest tau 95 -> 48 (every
parameter 35-48), R-hat 1.038 -> 1.019.  Only with a hardening term shown by the data: without
one, mu's posterior is its prior, whose image in s has a heavy tail.

Measured (32 walkers, to the unchanged convergence rule): SPC1 (a CLT connection, every 8th
sample) after 4,000 steps: tau 145 -> 104, R-hat 1.11 -> 1.07; the 2,401-sample test of
``bench_calibration`` (alpha2 = -0.7): 1,800 -> 1,300-1,500 steps.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Coordinates", "Hardening", "HardeningExponent", "PostYieldStiffness", "sampling_coordinates",
           "HARDENING_Z"]


class Coordinates:
    """Identity sampling coordinates (the law parameters themselves)."""

    name = "law parameters"

    def to_sampling(self, theta: np.ndarray) -> np.ndarray:
        return np.array(theta, dtype=float, copy=True)

    def to_law(self, phi: np.ndarray) -> np.ndarray:
        return np.array(phi, dtype=float, copy=True)

    def log_jacobian(self, phi: np.ndarray) -> np.ndarray:
        """``log |det d theta / d phi|`` per row of sampling coordinates."""
        return np.zeros(np.atleast_2d(phi).shape[0])


class Hardening(Coordinates):
    """``alpha2`` -> ``h = alpha2 k_init d^mu`` [kN] (see the module docstring).

    ``ia`` is alpha2's column in theta; ``ik`` / ``imu`` are the columns of k_init / mu when they
    are sampled (None: held at ``k_fixed`` / ``mu_fixed``).
    """

    def __init__(self, d: float, ia: int, ik: int | None, imu: int | None, k_fixed: float,
                 mu_fixed: float) -> None:
        if not (d > 0 and math.isfinite(d)):
            raise ValueError(f"peak displacement d = {d!r}: expected a positive finite value [m]")
        self.log_d = math.log(d)
        self.ia, self.ik, self.imu = ia, ik, imu
        self.k_fixed, self.mu_fixed = float(k_fixed), float(mu_fixed)
        self.name = f"hardening force h = alpha2 k_init d^mu at the peak displacement d = {d:.6g} m"

    def _log_scale(self, x: np.ndarray) -> np.ndarray:
        """``log(k_init d^mu)`` per row (k_init and mu are the same in both coordinates)."""
        k = x[:, self.ik] if self.ik is not None else np.full(x.shape[0], self.k_fixed)
        mu = x[:, self.imu] if self.imu is not None else np.full(x.shape[0], self.mu_fixed)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.log(np.where(k > 0, k, np.nan)) + mu * self.log_d

    def to_sampling(self, theta: np.ndarray) -> np.ndarray:
        phi = np.array(np.atleast_2d(theta), dtype=float, copy=True)
        with np.errstate(over="ignore", invalid="ignore"):  # a huge mu: outside the prior anyway
            phi[:, self.ia] = phi[:, self.ia] * np.exp(self._log_scale(phi))
        return phi

    def to_law(self, phi: np.ndarray) -> np.ndarray:
        theta = np.array(np.atleast_2d(phi), dtype=float, copy=True)
        with np.errstate(over="ignore", invalid="ignore"):
            theta[:, self.ia] = theta[:, self.ia] * np.exp(-self._log_scale(theta))
        return theta

    def log_jacobian(self, phi: np.ndarray) -> np.ndarray:
        return -self._log_scale(np.atleast_2d(phi))


class HardeningExponent(Coordinates):
    """``mu`` -> ``s = 1 / (mu - 1)`` on top of ``inner`` coordinates (module docstring); ``imu``
    is mu's column, which ``inner`` leaves as it is.  ``mu <= 1`` maps to ``s <= 0`` or inf and
    back to mu outside (1, inf), where the prior is zero."""

    def __init__(self, inner: Coordinates, imu: int) -> None:
        self.inner, self.imu = inner, imu
        self.name = f"{inner.name}; hardening exponent as s = 1/(mu - 1)"

    def to_sampling(self, theta: np.ndarray) -> np.ndarray:
        phi = self.inner.to_sampling(theta)
        with np.errstate(divide="ignore"):
            phi[:, self.imu] = 1.0 / (phi[:, self.imu] - 1.0)
        return phi

    def _inner_phi(self, phi: np.ndarray) -> np.ndarray:
        x = np.array(np.atleast_2d(phi), dtype=float, copy=True)
        with np.errstate(divide="ignore"):
            x[:, self.imu] = 1.0 + 1.0 / x[:, self.imu]
        return x

    def to_law(self, phi: np.ndarray) -> np.ndarray:
        return self.inner.to_law(self._inner_phi(phi))

    def log_jacobian(self, phi: np.ndarray) -> np.ndarray:
        phi = np.atleast_2d(phi)
        with np.errstate(divide="ignore"):
            return self.inner.log_jacobian(self._inner_phi(phi)) - 2.0 * np.log(np.abs(phi[:, self.imu]))


class PostYieldStiffness(Coordinates):
    """``alpha1`` -> ``k2 = alpha1 k_init`` [kN/m] on top of ``inner`` coordinates (module
    docstring); ``ik`` / ``ia1`` are the columns of k_init and alpha1 (both sampled), which
    ``inner`` leaves as they are."""

    def __init__(self, inner: Coordinates, ik: int, ia1: int) -> None:
        self.inner, self.ik, self.ia1 = inner, ik, ia1
        own = "post-yield stiffness k2 = alpha1 k_init"
        self.name = own if type(inner) is Coordinates else f"{inner.name}; {own}"

    def to_sampling(self, theta: np.ndarray) -> np.ndarray:
        phi = self.inner.to_sampling(theta)
        phi[:, self.ia1] = phi[:, self.ia1] * phi[:, self.ik]
        return phi

    def _inner_phi(self, phi: np.ndarray) -> np.ndarray:
        x = np.array(np.atleast_2d(phi), dtype=float, copy=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            x[:, self.ia1] = x[:, self.ia1] / x[:, self.ik]
        return x

    def to_law(self, phi: np.ndarray) -> np.ndarray:
        return self.inner.to_law(self._inner_phi(phi))

    def log_jacobian(self, phi: np.ndarray) -> np.ndarray:
        phi = np.atleast_2d(phi)
        k = phi[:, self.ik]
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.inner.log_jacobian(self._inner_phi(phi)) - np.log(np.where(k > 0, k, np.nan))


HARDENING_Z = 3.0
"""The data show a hardening term when the optimum's alpha2 is at least this many Laplace
standard deviations from 0; only then is alpha2 sampled as the hardening force ``h``."""


def sampling_coordinates(problem, theta0: np.ndarray | None = None,
                         alpha2_sd: float | None = None) -> Coordinates:
    """The sampling coordinates of a :class:`~.likelihood.Problem` (module docstring):
    :func:`hardening_coordinates` (with mu sampled as ``1 / (mu - 1)``,
    :class:`HardeningExponent`, when alpha2 is sampled as h and mu is sampled), with alpha1
    sampled as ``k2 = alpha1 k_init`` (:class:`PostYieldStiffness`) when both k_init and alpha1
    are sampled."""
    inner = hardening_coordinates(problem, theta0, alpha2_sd)
    if isinstance(inner, Hardening) and inner.imu is not None:
        inner = HardeningExponent(inner, inner.imu)
    free = list(problem.free)
    if {"k_init", "alpha1"} <= set(free):
        return PostYieldStiffness(inner, free.index("k_init"), free.index("alpha1"))
    return inner


def hardening_coordinates(problem, theta0: np.ndarray | None = None,
                          alpha2_sd: float | None = None) -> Coordinates:
    """The hardening part of :func:`sampling_coordinates`.

    :class:`Hardening` for a law with the term ``alpha2 k_init sgn(u)|u|^mu`` when the optimum
    ``theta0`` has ``|alpha2| >= HARDENING_Z alpha2_sd`` (its Laplace sd): the data show a
    hardening term.  Without one alpha2 stays: its posterior is then its prior at large mu and
    pinned near 0 at small mu, which the law coordinates sample well (1,300 steps on a synthetic
    plasticity test with alpha2 = 0) and ``h`` badly (its prior width ``0.1 k_init d^mu``
    vanishes at large mu: 6,000 steps, unconverged).  Otherwise the identity.
    """
    names = problem.spec.param_names
    free = list(problem.free)
    if not {"k_init", "alpha2", "mu"} <= set(names) or "alpha2" not in free:
        return Coordinates()
    d = float(np.max(np.abs(problem.test.disp)))
    ia = free.index("alpha2")
    shows = (theta0 is not None and alpha2_sd is not None and alpha2_sd > 0
             and abs(float(theta0[ia])) >= HARDENING_Z * alpha2_sd)
    if not shows or not d > 0:
        return Coordinates()
    return Hardening(d, ia, free.index("k_init") if "k_init" in free else None,
                     free.index("mu") if "mu" in free else None,
                     problem.template[names.index("k_init")], problem.template[names.index("mu")])
