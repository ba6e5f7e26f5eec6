"""Lognormal fragility curves fitted by maximum likelihood across intensity stripes.

Baker, J. W. (2015). Efficient analytical fragility function fitting using dynamic structural
analysis. *Earthquake Spectra* 31(1), 579-599, eqs. (1), (11)-(12):

    P(D > limit | IM = x) = Phi( ln(x / theta) / beta )

At stripe ``j`` (intensity ``x_j``) ``z_j`` of ``n_j`` analyses exceed the limit; the counts are
binomial, so (theta, beta) maximise

    sum_j [ z_j ln p_j + (n_j - z_j) ln(1 - p_j) ],   p_j = Phi( ln(x_j / theta) / beta ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special, stats


@dataclass(frozen=True)
class Fragility:
    """A fitted lognormal fragility curve.

    ``theta`` is the median intensity (units of the IM), ``beta`` the log standard deviation;
    ``im``/``n``/``z`` the stripes it was fitted on; ``loglik`` the maximised binomial
    log-likelihood (with its ln C(n, z) terms); ``note`` says why a fit is not finite (all
    or no analyses exceeding, or one stripe only).
    """

    demand: str
    limit: float
    theta: float
    beta: float
    im: tuple[float, ...]
    n: tuple[int, ...]
    z: tuple[int, ...]
    loglik: float
    note: str = ""

    def probability(self, im) -> np.ndarray:
        """P(D > limit | IM = im) of the fitted curve."""
        x = np.asarray(im, dtype=float)
        if not (math.isfinite(self.theta) and math.isfinite(self.beta)):
            return np.full(x.shape, np.nan)
        with np.errstate(divide="ignore"):
            return stats.norm.cdf(np.log(x / self.theta) / self.beta)


def _loglik(log_theta: float, log_beta: float, lx: np.ndarray, n: np.ndarray, z: np.ndarray) -> float:
    t = (lx - log_theta) / math.exp(log_beta)
    # log Phi(t) and log(1 - Phi(t)) = log Phi(-t), both stable in the tails
    return float(np.sum(z * special.log_ndtr(t) + (n - z) * special.log_ndtr(-t)))


def fit_fragility(im, n, z, *, demand: str = "", limit: float = float("nan")) -> Fragility:
    """Maximum-likelihood lognormal fragility (Baker 2015) from stripe counts.

    Parameters
    ----------
    im : intensities of the stripes (> 0, at least two distinct values).
    n : number of analyses per stripe (> 0).
    z : number of them exceeding the limit (0 <= z <= n).

    Returns
    -------
    Fragility
        NaN ``theta``/``beta`` with a ``note`` when the data hold no finite maximum (no analysis
        or every analysis exceeds the limit).
    """
    x = np.asarray(im, dtype=float).ravel()
    n_ = np.asarray(n, dtype=float).ravel()
    z_ = np.asarray(z, dtype=float).ravel()
    if not (x.size == n_.size == z_.size):
        raise ValueError(f"im, n and z must have the same length, got {x.size}, {n_.size}, {z_.size}")
    if x.size == 0 or np.any(~np.isfinite(x)) or np.any(x <= 0):
        raise ValueError(f"im must hold finite intensities > 0, got {x.tolist()}")
    if np.any(n_ <= 0) or np.any(z_ < 0) or np.any(z_ > n_):
        raise ValueError(f"need n > 0 and 0 <= z <= n per stripe, got n={n_.tolist()}, z={z_.tolist()}")
    base = dict(demand=demand, limit=float(limit), im=tuple(x.tolist()), n=tuple(int(v) for v in n_),
                z=tuple(int(v) for v in z_))
    note = ""
    if np.unique(x).size < 2:
        note = "one intensity only: a fragility curve needs at least two scales"
    elif z_.sum() == 0:
        note = "no analysis exceeds the limit at any scale"
    elif np.all(z_ == n_):
        note = "every analysis exceeds the limit at every scale"
    if note:
        return Fragility(theta=float("nan"), beta=float("nan"), loglik=float("nan"), note=note, **base)
    lx = np.log(x)
    lo, hi = lx.min() - math.log(100.0), lx.max() + math.log(100.0)
    bounds = [(lo, hi), (math.log(1e-3), math.log(5.0))]

    def neg(v):
        return -_loglik(v[0], v[1], lx, n_, z_)

    # a vectorised grid locates the basin (the likelihood is flat far from the data), then
    # L-BFGS-B polishes the best grid point
    gt = np.linspace(lx.min() - 1.0, lx.max() + 1.0, 61)
    gb = np.linspace(math.log(0.01), math.log(3.0), 40)
    tt = (lx[None, None, :] - gt[:, None, None]) / np.exp(gb)[None, :, None]
    ll = np.sum(z_ * special.log_ndtr(tt) + (n_ - z_) * special.log_ndtr(-tt), axis=-1)
    i, j = np.unravel_index(int(np.argmax(ll)), ll.shape)
    best = optimize.minimize(neg, x0=[gt[i], gb[j]], method="L-BFGS-B", bounds=bounds)
    theta, beta = math.exp(best.x[0]), math.exp(best.x[1])
    # the full binomial log-likelihood, with the ln C(n, z) terms the optimisation drops
    log_comb = float(np.sum(special.gammaln(n_ + 1) - special.gammaln(z_ + 1) - special.gammaln(n_ - z_ + 1)))
    order = np.argsort(x)
    frac = (z_ / n_)[order]
    interior = int(np.sum((frac > 0.0) & (frac < 1.0)))
    if interior <= 1 and np.all(np.diff(frac) >= 0):
        # the stripes below are all none, those above all all: theta can put the one stripe in
        # between (if any) at its share for every beta, so the likelihood grows as beta -> 0
        note = ("stripes perfectly separated (each all or none): beta is not identified (-> 0)"
                if interior == 0 else
                "only one stripe has a share strictly between none and all: beta is not identified "
                f"(the fit's {beta:.2g} is where the optimiser stopped, the likelihood grows as beta -> 0); "
                "place stripes closer around the median")
    return Fragility(theta=theta, beta=beta, loglik=log_comb - float(best.fun), note=note, **base)
