"""A building fitted by output error (:mod:`structures.shake_table.output_error`): its optimum,
posterior draws and residual model, and what they predict.

Residual model
--------------
Each channel is normalised by its RMS over the calibration runs, so the channels compare.  The
residual of channel c is modelled as a stationary AR(1) process with marginal sd sigma_c and
lag-1 autocorrelation rho_c (the building's errors are smooth: a misfit of the isolation mode
lasts seconds at 50 Hz).  The fit minimises sum_c sum_t (r_ct / sigma_c)^2 (iteratively
reweighted: sigma_c is the RMS residual of the previous pass, the MLE), which is the marginal
Gaussian likelihood; the AR(1) enters through the number of effectively independent samples,
n_c (1 - rho_c) / (1 + rho_c) (the long-run variance of an AR(1), Priestley 1981 sec. 5.3): the
log-likelihood is tempered by (1 - rho_c) / (1 + rho_c) per channel, so the posterior is not made
narrow by thousands of correlated samples.  The whitened (conditional) AR(1) likelihood was not
chosen because it weights the residual's high-frequency differences and so fits the accelerations'
noise rather than the isolation mode that a designer needs.

sigma_c is a *relative* error: the residual RMS over the channel's RMS on the calibration runs.  In
a prediction (band, held-out log-likelihood) a run's residual sd is sigma_c times the RMS of its
own predicted channel, so the band of a run twice as strong as the calibration runs is twice as
wide: the building's errors (a period or damping a few percent off) grow with the response, and a
constant sd measured on the calibration runs would give held-out runs beyond the calibrated range
a band too narrow for them.

Predictive band: every posterior draw's simulation plus N(0, (sigma_c RMS_run)^2) per channel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rrfrei.errors import NumericalFailure
from rrfrei.gap.model import LEVEL, MIN_BAND_SAMPLES, FitResult, GapModel, Prediction
from structures.shake_table.simulation import FIT_CHANNELS, REPORT_CHANNELS, BuildingData

__all__ = ["BuildingFit", "ar1", "temper"]


@dataclass(eq=False)
class BuildingFit(FitResult):
    """A building fitted by output error: optimum, posterior draws, residual model.

    Attributes
    ----------
    model : the :class:`BuildingModel` fitted.
    x_opt : (k,) optimum of the free parameters (:attr:`names`), in their units.
    X : (S, k) posterior draws (importance-resampled Laplace).
    sigma_c, rho_c : channel -> residual sd (in units of the channel's scale) and lag-1
        autocorrelation at the optimum, on the calibration runs.
    ess : effective sample size of the importance weights of the Laplace draws (of S).
    nfev : simulations the search ran; failed : simulations that failed (bad points).
    robust_sims : simulations of the fit in which the robust local solve replaced OpenSees' failed
        iteration (a deviation from OpenSees; the time steps are counted in :attr:`note`).
    """

    model: GapModel
    x_opt: np.ndarray
    X: np.ndarray
    sigma_c: dict
    rho_c: dict
    ess: float
    nfev: int = 0
    failed: int = 0
    seed: int = 0
    note: str = ""
    robust_sims: int = 0
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.model.name

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.layout.names

    @property
    def free(self) -> tuple[str, ...]:
        return self.names

    @property
    def params(self) -> dict[str, float]:  # type: ignore[override]
        return {n: float(v) for n, v in zip(self.names, self.x_opt)}

    @property
    def law_params(self) -> dict[str, float]:
        """The isolator law's parameters at the optimum (fitted and fixed)."""
        lay = self.model.layout
        return lay.spec.as_dict(lay.law_vector(self.params))

    @property
    def sigma(self) -> float:  # type: ignore[override]
        return float(np.sqrt(np.mean([s**2 for s in self.sigma_c.values()])))

    @property
    def noise(self) -> float:  # type: ignore[override]
        return self.sigma

    def simulate(self, x: np.ndarray, data: BuildingData):
        return self.model.simulate(x, data)

    def draws_on(self, data: BuildingData) -> tuple[np.ndarray, list[dict]]:
        """Simulations of every distinct posterior draw on ``data``: (ok mask over draws, outputs)."""
        key = ("draws", id(data))
        if key in self._cache:
            return self._cache[key][1]
        U, inv = np.unique(self.X, axis=0, return_inverse=True)
        inv = np.asarray(inv).reshape(-1)
        outs, st = [], np.zeros(U.shape[0], dtype=int)
        kept = self._cache.get(("sims", id(data)), (None, {}))[1]
        tally: dict = {}
        for j in range(U.shape[0]):
            o = kept.get(np.asarray(U[j], dtype=float).tobytes())
            if o is None:
                st[j], o = self.model.simulate(U[j], data, tally=tally)
            outs.append(o)
        if tally:
            self.add_note(f"the robust local solve replaced OpenSees' failed iteration (a deviation) at "
                           f"{tally['robust_steps']} time steps of {tally['robust_sims']} posterior draws on "
                           f"{data.name}")
        ok = st[inv] == 0
        if not ok.any():
            s0, o0 = self.model.simulate(self.x_opt, data)
            if s0 != 0:
                raise NumericalFailure(f"building {self.name!r} on {data.name}: every posterior draw and the "
                                       f"optimum fail (status {s0})")
            res = (np.array([True]), [o0])
        else:
            res = (ok, [outs[inv[i]] for i in range(inv.size) if ok[i]])
            if not ok.all():
                self.add_note(f"{int((~ok).sum())} of {ok.size} posterior draws failed on {data.name}")
        self._cache[key] = (data, res)
        return res

    def channel_draws(self, data: BuildingData, run: str, channel: str) -> np.ndarray:
        """(S_ok, n) simulated ``channel`` of ``run`` [its unit] over the successful draws."""
        _, outs = self.draws_on(data)
        return np.vstack([o[run][channel] for o in outs])

    def band(self, data: BuildingData, run: str, channel: str, *, level: float = LEVEL
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(median, lower, upper) [channel unit]: the predictive band, draws plus the residual model
        N(0, (sigma_c RMS_run)^2), RMS_run the RMS of the run's predicted (median) channel."""
        D = self.channel_draws(data, run, channel)
        med = np.median(D, axis=0)
        rel = self.sigma_c.get(channel, self.model.extra_sigma(self, channel))
        sd = rel * float(np.sqrt(np.mean(med**2)))
        rng = np.random.default_rng([self.seed, 7, REPORT_CHANNELS.index(channel)])
        reps = -(-MIN_BAND_SAMPLES // D.shape[0])
        Y = np.repeat(D, reps, axis=0)
        Y = Y + rng.normal(size=Y.shape) * sd
        a = (1 - level) / 2
        lo, hi = np.quantile(Y, [a, 1 - a], axis=0)
        return med, lo, hi

    def residual_sd(self, data: BuildingData, mean: np.ndarray) -> np.ndarray:
        """Residual sd of every sample of ``data``'s stacked channels (normalised units): sigma_c
        times the RMS of the predicted ``mean`` over that run and channel (module docstring)."""
        sig = np.empty(mean.size)
        i0 = 0
        for o in data.observed:
            n = data.measured(o)["isolator_disp"].size
            for c in FIT_CHANNELS:
                seg = mean[i0:i0 + n]
                sig[i0:i0 + n] = self.sigma_c[c] * max(float(np.sqrt(np.mean(seg**2))), 1e-12)
                i0 += n
        return sig

    def predict(self, data: BuildingData) -> Prediction:
        key = ("pred", id(data))
        if key in self._cache:
            return self._cache[key][1]
        _, outs = self.draws_on(data)
        F = np.vstack([self.model.stack(o, data) for o in outs])
        sig = self.residual_sd(data, F.mean(axis=0))
        rng = np.random.default_rng(self.seed + 1)
        reps = -(-MIN_BAND_SAMPLES // F.shape[0])
        Y = np.repeat(F, reps, axis=0)
        Y = Y + rng.normal(size=Y.shape) * sig[None, :]
        a = (1 - LEVEL) / 2
        lo, hi = np.quantile(Y, [a, 1 - a], axis=0)
        pred = Prediction(mean=F.mean(axis=0), lower=lo, upper=hi, draws=F,
                          sigma=np.full(F.shape[0], self.sigma))
        self._cache[key] = (data, pred)
        return pred

    def loglik(self, data: BuildingData) -> np.ndarray:
        """Pointwise (S, n) Gaussian log-likelihood per channel (sd :meth:`residual_sd`), tempered by
        the AR(1) factor (1 - rho_c) / (1 + rho_c) (module docstring)."""
        pred = self.predict(data)
        y = self.model.observed(data)
        sig = self.residual_sd(data, pred.mean)
        temp = self.model.sigma_vector({c: temper(self.rho_c[c]) for c in FIT_CHANNELS}, data)
        r = (y[None, :] - pred.draws) / sig[None, :]
        return temp[None, :] * (-0.5 * r**2 - np.log(sig)[None, :] - 0.5 * math.log(2 * math.pi))


def temper(rho: float) -> float:
    rho = min(max(float(rho), 0.0), 0.999)
    return (1.0 - rho) / (1.0 + rho)


def ar1(r: np.ndarray) -> float:
    r = np.asarray(r, float) - np.mean(r)
    d = float(r @ r)
    return float(r[1:] @ r[:-1] / d) if d > 0 else 0.0

