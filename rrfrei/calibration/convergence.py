"""The convergence rule of a chain: burn-in, integrated autocorrelation time, thinning, and the
stored draws' bulk and tail ESS and rank-normalised split R-hat (Vehtari et al. 2021), computed for
all parameters at once by FFT.  :func:`check` is both the stopping rule of
:func:`rrfrei.calibration.sampler.run_chain` and the final check of :func:`rrfrei.calibrate`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CHECK", "CONVERGENCE_RULE", "ESS_TARGET", "MIN_TAU", "RHAT_LIMIT", "TAU_CHANGE", "Check",
           "burn_in", "check", "thinning"]


def _autocov(x: np.ndarray) -> np.ndarray:
    """Sum_t (x_t - mean)(x_{t+lag} - mean) for lags 0..n-1 of chains ``x`` (draws, chains, k), by
    one zero-padded FFT along the draws (unnormalised: divide by n for the biased autocovariance)."""
    n = x.shape[0]
    xc = np.moveaxis(x - x.mean(axis=0), 0, -1).copy()  # draws contiguous: 2-3x faster FFTs
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(xc, n=nfft, axis=-1)
    acov = np.fft.irfft(f * np.conj(f), n=nfft, axis=-1)[..., :n]
    return np.ascontiguousarray(np.moveaxis(acov, -1, 0))  # (n, m, k) as the callers sum over it


def _tau(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """Integrated autocorrelation time per parameter of a chain (steps, walkers, k).

    ``emcee.autocorr.integrated_time(chain, tol=0)`` (the walkers' normalised autocorrelation
    functions averaged, Sokal's automatic window with c = 5), computed for all walkers and
    parameters in one FFT; nan for chains too short to estimate.
    """
    n, m, k = chain.shape
    if n < 4:
        return np.full(k, np.nan)
    acf = _autocov(chain)  # (n, m, k)
    with np.errstate(divide="ignore", invalid="ignore"):
        acf = np.nanmean(acf / acf[0], axis=1)  # (n, k); a stuck walker (zero variance) is skipped
    taus = 2.0 * np.cumsum(acf, axis=0) - 1.0
    out = np.full(k, np.nan)
    for j in range(k):
        if not np.all(np.isfinite(taus[:, j])):
            continue
        ok = np.arange(n) < c * taus[:, j]
        w = int(np.argmin(ok)) if not ok.all() else n - 1
        out[j] = taus[w, j]
    return out


RHAT_LIMIT = 1.05
"""Largest rank-normalised split R-hat (walkers as chains) of the stored draws of a converged run."""
ESS_TARGET = 400.0
"""Bulk and tail effective sample size every sampled quantity must reach (Vehtari et al. 2021,
"Rank-normalization, folding, and localization: an improved R-hat", recommend > 400 in total):
enough for the mean to ~5 % of a posterior sd and for the 2.5 % / 97.5 % quantiles reported."""
MIN_TAU = 10.0
"""The kept (post burn-in) chain must also be at least this many autocorrelation times long and
the estimate of tau must have changed by less than :data:`TAU_CHANGE` since the last check, so
that a short chain whose tau is still growing (its ESS over-estimated) does not stop early."""
TAU_CHANGE = 0.10
CONVERGENCE_RULE = (f"bulk and tail ESS >= {ESS_TARGET:.0f} and R-hat < {RHAT_LIMIT:g} on the "
                    f"stored (thinned) draws, from a chain >= {MIN_TAU:.0f} stable "
                    "autocorrelation times long")
"""The convergence rule in words: the one text the CLI's help, warnings and reports quote."""
CHECK = 100
"""Steps between convergence checks (and checkpoint writes) of a run to convergence."""


def burn_in(n_steps: int, tau_max: float) -> int:
    """Steps discarded as burn-in: a quarter of the chain, at least 2 tau, at most a half."""
    if not math.isfinite(tau_max):
        return n_steps // 2
    return min(n_steps // 2, max(n_steps // 4, int(math.ceil(2 * tau_max))))


def thinning(n_steps: int, burn: int, tau_max: float, walkers: int, max_draws: int) -> int:
    """Thinning of the stored draws: every ``max(tau / 2, 1)``-th step after burn-in, more when
    that would store more than ``max_draws`` draws (walkers x draws per walker)."""
    thin = max(1, int(tau_max / 2)) if math.isfinite(tau_max) else 1
    per_walker = max(int(max_draws) // max(int(walkers), 1), 1)
    need = -(-(n_steps - burn) // per_walker)  # ceil: the smallest thin storing <= per_walker each
    return int(min(max(thin, need), max(n_steps, 1)))


def _diagnose(kept: np.ndarray) -> tuple[float, float, float]:
    """(min bulk ESS, min tail ESS, max R-hat) of a chain (steps, walkers, k), walkers as chains.

    The rank-normalised split-chain bulk ESS, the tail ESS (5 % and 95 % quantile indicators)
    and the rank-normalised, folded split R-hat of Vehtari et al. (2021), the quantities of
    ``arviz.ess(method="bulk"|"tail")`` and ``arviz.rhat``, computed for all parameters at once
    (one FFT): arviz' per-parameter calls cost ~1 s per check, more than the sampling between
    two checks of a short run.
    """
    from scipy.stats import norm, rankdata

    n, m, k = kept.shape
    if n < 4:
        return float("nan"), float("nan"), float("nan")
    half = n // 2
    x = np.concatenate([kept[:half], kept[n - half:]], axis=1)  # split chains: (half, 2m, k)
    flat = x.reshape(-1, k)
    z = norm.ppf((rankdata(flat, axis=0) - 0.375) / (flat.shape[0] + 0.25)).reshape(x.shape)
    med = np.median(flat, axis=0)
    fold = np.abs(flat - med)
    zf = norm.ppf((rankdata(fold, axis=0) - 0.375) / (fold.shape[0] + 0.25)).reshape(x.shape)
    rhat = np.maximum(_split_rhat(z), _split_rhat(zf))
    bulk = _ess(z)
    q05, q95 = np.quantile(kept.reshape(-1, k), [0.05, 0.95], axis=0)  # of every draw, as arviz
    tail = np.minimum(_ess((x <= q05).astype(float)), _ess((x <= q95).astype(float)))
    return float(np.nanmin(bulk)), float(np.nanmin(tail)), float(np.nanmax(rhat))


def _split_rhat(x: np.ndarray) -> np.ndarray:
    """Potential scale reduction of chains ``x`` (draws, chains, k) (Gelman et al., BDA3 11.4)."""
    n = x.shape[0]
    w = np.mean(np.var(x, axis=0, ddof=1), axis=0)
    b = n * np.var(np.mean(x, axis=0), axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(((n - 1) / n * w + b / n) / w)


def _ess(x: np.ndarray) -> np.ndarray:
    """Effective sample size of chains ``x`` (draws, chains, k): Geyer's initial positive then
    monotone sequence on the multi-chain autocorrelation, step for step arviz' ``_ess`` (Stan's
    estimator, with its end-of-sequence correction), so that the convergence check and the
    summary's ESS are the same number on the same draws."""
    n, m, k = x.shape
    acov = (_autocov(x) / n).mean(axis=1)  # (n, k): biased autocovariance, mean over chains
    mean_var = acov[0] * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n + (np.var(x.mean(axis=0), axis=0, ddof=1) if m > 1 else 0.0)
    out = np.full(k, np.nan)
    resolution = np.finfo(float).resolution
    for j in range(k):
        xj = x[:, :, j]
        if not np.all(np.isfinite(xj)):
            continue
        if np.max(xj) - np.min(xj) < resolution:
            out[j] = float(xj.size)
            continue
        rho = 1.0 - (mean_var[j] - acov[:, j]) / var_plus[j]
        rt = np.zeros(n)
        even, odd = 1.0, float(rho[1])
        rt[0], rt[1] = even, odd
        t = 1
        while t < n - 3 and even + odd > 0.0:
            even, odd = float(rho[t + 1]), float(rho[t + 2])
            if even + odd >= 0:
                rt[t + 1], rt[t + 2] = even, odd
            t += 2
        max_t = t - 2
        if even > 0:
            rt[max_t + 1] = even
        t = 1
        while t <= max_t - 2:
            if rt[t + 1] + rt[t + 2] > rt[t - 1] + rt[t]:
                rt[t + 1] = rt[t + 2] = (rt[t - 1] + rt[t]) / 2.0
            t += 2
        tau = -1.0 + 2.0 * float(np.sum(rt[: max_t + 1])) + float(np.sum(rt[max_t + 1: max_t + 2]))
        tau = max(tau, 1.0 / math.log10(m * n))
        out[j] = np.nan if np.isnan(rt).any() else m * n / tau
    return out


@dataclass
class Check:
    """One evaluation of the convergence rule (:data:`CONVERGENCE_RULE`) on a chain of ``n`` steps:
    burn-in, tau, the thinning of the stored draws and their ESS and R-hat."""

    burn: int
    tau: np.ndarray
    tmax: float
    ess_bulk: float
    ess_tail: float
    rhat: float
    n: int = 0  # chain length checked
    diagnosed: bool = False  # ESS and R-hat computed
    thin: int = 1
    draws: int = 0  # stored draws (walkers x draws per walker)

    def tau_ok(self, n_steps: int, previous_tmax: float) -> bool:
        """The tau part of the rule: tau finite, >= MIN_TAU tau kept, tau stable since the last check."""
        return bool(
            np.all(np.isfinite(self.tau)) and n_steps - self.burn >= MIN_TAU * self.tmax
            and abs(previous_tmax - self.tmax) <= TAU_CHANGE * self.tmax
        )

    def converged(self, n_steps: int, previous_tmax: float) -> bool:
        """The whole rule: :meth:`tau_ok` and ESS and R-hat of the stored draws."""
        return bool(self.tau_ok(n_steps, previous_tmax) and self.draws_ok)

    @property
    def draws_ok(self) -> bool:
        """ESS >= :data:`ESS_TARGET` (bulk and tail) and R-hat < :data:`RHAT_LIMIT` of the stored draws."""
        return bool(self.ess_bulk >= ESS_TARGET and self.ess_tail >= ESS_TARGET
                    and self.rhat < RHAT_LIMIT)

    def text(self) -> str:
        if not self.diagnosed:
            return f"tau≈{self.tmax:.0f} (ESS, R-hat once tau is stable)"
        return (f"tau≈{self.tmax:.0f} ESS {self.ess_bulk:.0f}/{self.ess_tail:.0f} "
                f"R-hat {self.rhat:.3f}")


def check(chain: np.ndarray, max_draws: int, previous_tmax: float | None = None, start: int = 0) -> Check:
    """Burn-in, tau, thinning and the stored draws' ESS and R-hat of a chain (steps, walkers, k):
    the convergence rule of :func:`run_chain` and the final check of :func:`rrfrei.calibrate`.

    With ``previous_tmax`` (the last check's tau) the ESS and R-hat are computed only when the
    tau part of the rule (:meth:`Check.tau_ok`) holds, the only case in which they can decide it
    (nan otherwise).  ``start``: steps before it are never kept (walkers were restarted there,
    :func:`rrfrei.calibration.sampler.stuck_walkers`): the rule is the rule of the chain from
    ``start`` on, and the returned burn-in counts from step 0.
    """
    n_all, nw = chain.shape[0], chain.shape[1]
    start = min(max(int(start), 0), n_all)
    chain = chain[start:]
    n = chain.shape[0]
    t0 = _tau(chain[n // 4:])
    burn = burn_in(n, float(np.max(t0)) if np.all(np.isfinite(t0)) else math.nan)
    kept = chain[burn:]
    tau = t0 if burn == n // 4 else _tau(kept)  # same samples: same tau
    tmax = float(np.max(tau)) if np.all(np.isfinite(tau)) else math.nan
    thin = thinning(n, burn, tmax, nw, max_draws)
    stored = kept[::thin]
    chk = Check(start + burn, tau, tmax, math.nan, math.nan, math.nan, n=n_all, thin=thin,
                draws=int(stored.shape[0] * nw))
    if previous_tmax is None or chk.tau_ok(n_all, previous_tmax):
        chk.ess_bulk, chk.ess_tail, chk.rhat = _diagnose(stored)
        chk.diagnosed = True
    return chk
