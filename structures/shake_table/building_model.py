"""The shake-table building as a model of the gap engine: output-error calibration (issue 27).

The model is the *building*: the identified superstructure (story masses, stiffness, damping), the
isolation layer's law (possibly augmented by catalogue effects) and optional system effects, driven
by each run's measured table acceleration, the runs one after the other in chronological order
(``pad_s`` seconds of rest between them) so the isolators' state is carried from run to run.  What
is compared is what the sensors measured: the isolator displacement d_0 [m] (relative to the
table, from the start of each run), the isolation-layer force F = -sum_i m_i a_i [kN] and the roof
absolute acceleration [m/s^2] (:data:`FIT_CHANNELS`).  The story-1 shear [kN] is predicted and
reported too.

Free parameters
---------------
* the law's (those :class:`rrfrei.gap.model.IsolatorModel` fits on the isolation loops, with the
  effects' parameters the catalogue names);
* the superstructure: a stiffness scale ``k_scale`` on every identified story stiffness, and its
  damping ratio ``zeta`` (stiffness-proportional story dashpots c_j = 2 zeta k_j / omega_1);
* system effects (:data:`SYSTEM_EFFECTS`, candidates of the diagnosis like the isolator effects):
  ``isolation_damping``, a linear dashpot ``c_iso`` [kN s/m] across the isolation layer (base slab
  to table), and ``softening``, story stiffness falling with the run's amplitude,
  k_j,run = k_scale k_j (A_run / A_ref)^(-soft_exp) with A the run's peak table acceleration and
  A_ref the largest of the calibration runs (each run is simulated with its own stiffness; the
  runs before it are driven with the same building, so the isolators' carried state is kept).

Objective and residual model
----------------------------
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

Search: a global start, then least squares.  The global start is CMA-ES (Hansen 2016, the
``cma`` package) on the sum of squares, in coordinates scaled by each parameter's typical size,
over a box of +-:data:`GLOBAL_BOX` scaled units around its start within the bounds: for a fit from
the isolator loop fit (equation error, force given the measured displacement) over every
parameter (:data:`GLOBAL_EVALS` simulations); for the refit of an added effect from a fitted
building over the effect's parameters and the superstructure's stiffness scale and damping, the
fitted law held (:data:`REFIT_GLOBAL_EVALS`), so the refit is not confined to the basin of the
effect's one start.  Its best point joins the local starts: the loop fit with the identified
superstructure and with a stiffer, more damped one (or the given fits with the effect at the
catalogue's start); each start runs a short screen of least squares
(``scipy.optimize.least_squares``, trust-region reflective, bounded, same scaled coordinates),
the best continues (the multi-start of :class:`rrfrei.gap.model.IsolatorModel`).

Posterior: Laplace, ``N(x*, (J^T W J + I)^-1)`` with the tempered weights W and a unit ridge in
scaled coordinates, checked by importance sampling (weights = tempered likelihood over the
Gaussian proposal; its effective sample size is reported in :attr:`BuildingFit.ess`) and
resampled. Predictive band: every draw's simulation plus N(0, sigma_c^2) per channel.

Every simulation has the robust local solve: where OpenSees' local iteration of the law fails
even at the last subdivision of a step, the law's bracketed, safeguarded Newton solves it (a
deviation from OpenSees, counted in :attr:`BuildingFit.robust_sims` and the fit's note).  A
simulation that fails even so is a bad point of the optimiser (a large constant residual) and a
dropped draw of the posterior, never an exception; the count is reported in the fit's note.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.optimize import least_squares

from rrfrei.budget import TimeBudget
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.gap.catalogue import catalogue
from rrfrei.gap.model import (
    LEVEL,
    MIN_BAND_SAMPLES,
    FitResult,
    GapModel,
    IsolatorModel,
    Prediction,
    test_scales,
)
from rrfrei.io import ShearTest, concat_tests
from rrfrei.laws import LawSpec, get
from structures.dynamics.history import kernel, solver_settings
from structures.dynamics.newmark_records import Chain, Histories, Layer
from structures.shake_table import ShakeTableRun, isolation_test

__all__ = ["FIT_CHANNELS", "REPORT_CHANNELS", "SYSTEM_EFFECTS", "BuildingData", "BuildingFit",
           "BuildingModel", "Superstructure"]

FIT_CHANNELS = ("isolator_disp", "isolator_force", "roof_accel")
"""The channels the output error compares (isolator displacement [m], isolation-layer force
[kN], roof absolute acceleration [m/s^2])."""
REPORT_CHANNELS = ("isolator_disp", "isolator_force", "base_shear", "roof_accel")
"""The channels predicted and reported (the fitted ones and the story-1 shear [kN])."""
SYSTEM_EFFECTS = ("isolation_damping", "softening")
"""System effects the building model adds besides the isolator effects of the catalogue."""
WINDOW_S = 10.0
"""Length of the time windows that are the blocks of the decision rule [s]."""
SCREEN_NFEV = 12
"""Evaluations (x (parameters + 1) with the finite-difference Jacobian) of each start's screen."""
MAX_NFEV = 60
"""Most least-squares iterations of the continued start."""
REFIT_NFEV = 12
"""Most evaluations of a refit that starts from a fitted building (an added effect)."""
REFIT_SCREEN_NFEV = 4
"""Evaluations of each start's screen in such a refit."""
GLOBAL_EVALS = 400
"""Evaluations (simulations) of the CMA-ES global start of a fit from the loop fit."""
REFIT_GLOBAL_EVALS = 100
"""Evaluations of the CMA-ES global start of a refit (over the added effect's parameters and the
superstructure's, the fitted building's other parameters held)."""
GLOBAL_BOX = 2.0
"""Half-width of the global search's box around its start, in scaled coordinates (each parameter
over its typical size: -100 % to +300 % of a parameter that starts at its size)."""
CMA_SIGMA = 0.25
"""Initial step of CMA-ES on the box mapped onto the unit cube."""
K_SCALE_BOX = (0.5, 2.0)
"""Bounds of the superstructure stiffness scale: a factor 2 either way of the identification."""
ZETA_BOX = (0.0, 0.2)
"""Bounds of the superstructure damping ratio (20 %: beyond any reinforced-concrete frame)."""


def concatenate_runs(runs: Sequence[ShakeTableRun], pad_s: float,
                     dt: float) -> tuple[np.ndarray, dict[str, slice]]:
    """The runs' table accelerations [m/s^2] one after the other, ``pad_s`` [s] of rest between
    two, and each run's slice of the result (the runs share the sample interval ``dt`` [s])."""
    npad = int(round(pad_s / dt))
    parts: list[np.ndarray] = []
    slices: dict[str, slice] = {}
    i0 = 0
    for r in runs:
        if parts:
            parts.append(np.zeros(npad))
            i0 += npad
        a = np.asarray(r.table_accel, dtype=float)
        parts.append(a)
        slices[r.name] = slice(i0, i0 + a.size)
        i0 += a.size
    return np.concatenate(parts), slices


def measured_channels(run: ShakeTableRun) -> dict[str, np.ndarray]:
    """The :data:`REPORT_CHANNELS` of ``run`` as measured."""
    return {"isolator_disp": np.asarray(run.isolator_disp, dtype=float),
            "isolator_force": np.asarray(run.isolator_force, dtype=float),
            "base_shear": np.asarray(run.story_shear()[:, 0], dtype=float),
            "roof_accel": np.asarray(run.accel[:, -1], dtype=float)}


@dataclass(frozen=True, eq=False)
class Superstructure:
    """The building above the isolators: masses [t] (base slab first), story stiffness [kN/m]
    (story 1 first), damping ratio zeta (stiffness-proportional), story heights [m], and where it
    comes from."""

    masses: np.ndarray
    stiffness: np.ndarray
    zeta: float
    heights: np.ndarray
    source: str = ""

    @classmethod
    def of(cls, sup, source: str = "") -> Superstructure:
        """From a :class:`structures.shake_table.identify.SuperstructureIdentification` or a
        :class:`structures.ShearBuilding`."""
        from structures.building.shear_building import ShearBuilding

        if isinstance(sup, Superstructure):
            return sup
        if isinstance(sup, ShearBuilding):
            return cls(np.concatenate([[sup.base_mass], sup.story_masses]),
                       np.asarray(sup.story_stiffness, float),
                       float(sup.damping_ratio), np.asarray(sup.story_heights, float), source or sup.name)
        b = sup.building(_placeholder_isolator())
        return cls(np.asarray(sup.masses, float), np.asarray(sup.stiffness, float), float(b.damping_ratio),
                   np.asarray(b.story_heights, float), source or f"identified from {sup.run}")

    def omega1(self, k: np.ndarray) -> float:
        """First fixed-base circular frequency [rad/s] with story stiffness ``k``."""
        K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
        return float(math.sqrt(scipy.linalg.eigh(K, np.diag(self.masses[1:]), eigvals_only=True)[0]))


def _placeholder_isolator():
    from structures.building.shear_building import Isolator

    return Isolator("plasticity", {"k_init": 1.0, "qd": 0.0, "alpha1": 0.5, "alpha2": 0.0, "mu": 2.0})


@dataclass(frozen=True, eq=False)
class BuildingData:
    """Runs driven one after the other (chronological order) and the ones that are observed.

    ``runs``: every run simulated, in order (the state they leave is carried into the next);
    ``observed``: names of the runs whose channels are compared (by default all).  A held-out run
    is ``BuildingData(all runs up to it, observed=(it,))``.
    """

    runs: tuple[ShakeTableRun, ...]
    observed: tuple[str, ...] = ()
    pad_s: float = 10.0

    def __post_init__(self) -> None:
        runs = tuple(self.runs)
        if not runs:
            raise ValueError("BuildingData needs at least one run")
        names = [r.name for r in runs]
        obs = tuple(self.observed) or tuple(names)
        for o in obs:
            if o not in names:
                raise ValueError(f"observed run {o!r} is not among the runs ({', '.join(names)})")
        dt = runs[0].dt
        for r in runs[1:]:
            if abs(r.dt - dt) > 1e-9 * dt:
                raise ValueError(f"runs {runs[0].name!r} ({1 / dt:g} Hz) and {r.name!r} ({r.rate_hz:g} Hz) "
                                 "have different sampling rates; give runs at one rate")
        # simulate only up to the last observed run
        last = max(names.index(o) for o in obs)
        object.__setattr__(self, "runs", runs[: last + 1])
        object.__setattr__(self, "observed", tuple(n for n in names if n in obs))
        acc, slices = concatenate_runs(self.runs, self.pad_s, dt)
        # the record starts at rest: one leading zero sample, every slice shifted by it
        object.__setattr__(self, "_ag", np.concatenate([[0.0], acc]))
        object.__setattr__(self, "_slices", {k: slice(v.start + 1, v.stop + 1) for k, v in slices.items()})
        object.__setattr__(self, "_meas", {r.name: measured_channels(r) for r in self.runs
                                           if r.name in self.observed})

    @property
    def name(self) -> str:
        pre = [r.name for r in self.runs if r.name not in self.observed]
        obs = "+".join(self.observed)
        return obs if not pre else f"{obs} (after {', '.join(pre)})"

    @property
    def dt(self) -> float:
        return self.runs[0].dt

    def run(self, name: str) -> ShakeTableRun:
        return next(r for r in self.runs if r.name == name)

    def measured(self, run: str) -> dict[str, np.ndarray]:
        return self._meas[run]

    def time(self, run: str) -> np.ndarray:
        r = self.run(run)
        return np.asarray(r.time, float) - float(r.time[0])

    def peak_table_accel(self, run: str) -> float:
        return float(np.max(np.abs(self.run(run).table_accel)))

    def __len__(self) -> int:
        return sum(self._meas[o]["isolator_disp"].size for o in self.observed) * len(FIT_CHANNELS)


# ---------------------------------------------------------------------------------------------
# simulation
# ---------------------------------------------------------------------------------------------
class _Layout:
    """Where each parameter goes: law vector, k_scale, zeta, c_iso, soft_exp."""

    def __init__(self, spec: LawSpec, law_free: Sequence[str], law_fixed: Mapping[str, float],
                 system: Sequence[str]) -> None:
        self.spec = spec
        self.law_free = tuple(law_free)
        self.law_fixed = dict(law_fixed)
        self.system = tuple(system)
        self.names = self.law_free + self.system
        self.idx = {n: i for i, n in enumerate(spec.param_names)}

    def law_vector(self, values: Mapping[str, float]) -> np.ndarray:
        p = np.zeros(len(self.spec.param_names))
        for q in self.spec.params:
            if q.name in values:
                p[self.idx[q.name]] = values[q.name]
            elif q.name in self.law_fixed:
                p[self.idx[q.name]] = self.law_fixed[q.name]
            elif q.optional:
                p[self.idx[q.name]] = q.default
        return p


def simulate(spec: LawSpec, law_p: np.ndarray, sup: Superstructure, data: BuildingData, *,
             k_scale: float = 1.0, zeta: float | None = None, c_iso: float = 0.0, soft_exp: float = 0.0,
             a_ref: float | None = None, tally: dict | None = None
             ) -> tuple[int, dict[str, dict[str, np.ndarray]]]:
    """Simulate the building through ``data``'s runs; (status, run -> channel -> (n,) arrays).

    The Newmark step is OpenSees' (Newton, then subdivision of a failing step); at the last
    subdivision level the law's robust local solve (bracketed, safeguarded Newton) replaces a
    failed local iteration, a deviation from OpenSees counted in ``tally`` (when given: its
    ``"robust_steps"`` grows by the output steps where it acted, ``"robust_sims"`` by one when it
    acted at all).  Status 0 on success; otherwise the kernel's status (Newton failed even so) or
    -3 (non-finite output).  Displacements are measured from each run's start, as the records are.
    """
    zeta = sup.zeta if zeta is None else zeta
    out: dict[str, dict[str, np.ndarray]] = {}
    m = sup.masses
    K = kernel(spec)
    solver = solver_settings(0.5, 0.25, 1e-12, 50, 6, True)
    dev = 0
    lay = Layer(np.ascontiguousarray(law_p, dtype=float), 1.0, 1.0, np.array(spec.initial_state, dtype=float))
    groups: list[tuple[float, list[str]]]
    if soft_exp == 0.0:
        groups = [(1.0, list(data.observed))]
    else:
        ref = a_ref or max(data.peak_table_accel(o) for o in data.observed)
        groups = [((data.peak_table_accel(o) / ref) ** (-soft_exp), [o]) for o in data.observed]
    for factor, obs in groups:
        k = sup.stiffness * k_scale * factor
        cg = np.zeros(m.size)
        cg[0] = c_iso
        chain = Chain(m, k, 2.0 * zeta / sup.omega1(k) * k, cg, np.asarray(sup.heights, dtype=float))
        last = max(data._slices[o].stop for o in obs)
        ag = data._ag[:last]
        hist = Histories.allocate(ag.size, m.size)
        try:
            res = K.integrate(chain, lay, ag, data.dt, solver, hist)
        except NUMERICAL_ERRORS:
            return -98, {}
        dev += int(np.count_nonzero(hist.robust))
        if res.status != 0:
            _tally(tally, dev)
            return int(res.status), {}
        for o in obs:
            s = data._slices[o]
            u = hist.disp[s, 0] - hist.disp[s.start - 1, 0]
            ch = {"isolator_disp": u, "isolator_force": -(hist.accel[s] @ m),
                  "base_shear": -(hist.accel[s, 1:] @ m[1:]), "roof_accel": hist.accel[s, -1].copy()}
            if not all(np.all(np.isfinite(v)) for v in ch.values()):
                return -3, {}
            out[o] = ch
    _tally(tally, dev)
    return 0, out


def _tally(tally: dict | None, steps: int) -> None:
    if tally is not None and steps:
        tally["robust_steps"] = tally.get("robust_steps", 0) + steps
        tally["robust_sims"] = tally.get("robust_sims", 0) + 1


# ---------------------------------------------------------------------------------------------
# the fit
# ---------------------------------------------------------------------------------------------
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

    model: BuildingModel
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
            self._add_note(f"the robust local solve replaced OpenSees' failed iteration (a deviation) at "
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
                self._add_note(f"{int((~ok).sum())} of {ok.size} posterior draws failed on {data.name}")
        self._cache[key] = (data, res)
        return res

    def _add_note(self, text: str) -> None:
        if text not in self.note:
            self.note = f"{self.note}; {text}" if self.note else text

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
        temp = self.model.sigma_vector({c: _temper(self.rho_c[c]) for c in FIT_CHANNELS}, data)
        r = (y[None, :] - pred.draws) / sig[None, :]
        return temp[None, :] * (-0.5 * r**2 - np.log(sig)[None, :] - 0.5 * math.log(2 * math.pi))


def _cma_start(resid, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, free: np.ndarray, evals: int,
               seed: int) -> np.ndarray | None:
    """Best point of a CMA-ES search (Hansen 2016, "The CMA evolution strategy: a tutorial",
    arXiv:1604.00772; the ``cma`` package) of the sum of squares of ``resid`` over the coordinates
    ``free`` (scaled, the others held at ``x0``), in the box ``x0 +- GLOBAL_BOX`` within the
    bounds, mapped onto the unit cube; ``evals`` evaluations at most.  None when no evaluated
    point beats ``x0``."""
    import cma

    lo = np.maximum(lb, x0 - GLOBAL_BOX)[free]
    hi = np.minimum(ub, x0 + GLOBAL_BOX)[free]
    span = np.where(hi > lo, hi - lo, 1.0)
    u0 = np.clip((x0[free] - lo) / span, 0.0, 1.0)

    def full(u):
        x = x0.copy()
        x[free] = lo + np.clip(np.asarray(u, float), 0.0, 1.0) * span
        return x

    def f(u):
        r = resid(full(u))
        return float(r @ r)

    f0 = f(u0)
    opts = {"bounds": [0.0, 1.0], "seed": 1 + int(seed) % 100_000, "maxfevals": int(evals),
            "verbose": -9, "tolfun": 1e-6 * max(f0, 1e-12)}
    if u0.size == 1:  # cma needs two coordinates: a dummy one
        opts["bounds"] = [[0.0, 0.0], [1.0, 1.0]]
        es = cma.CMAEvolutionStrategy([u0[0], 0.5], CMA_SIGMA, opts)
        es.optimize(lambda u: f(u[:1]))
        ub_ = np.asarray(es.result.xbest[:1]) if es.result.xbest is not None else None
    else:
        es = cma.CMAEvolutionStrategy(u0, CMA_SIGMA, opts)
        es.optimize(f)
        ub_ = es.result.xbest
    if ub_ is None or not es.result.fbest < f0:
        return None
    return full(ub_)


def _temper(rho: float) -> float:
    rho = min(max(float(rho), 0.0), 0.999)
    return (1.0 - rho) / (1.0 + rho)


def _ar1(r: np.ndarray) -> float:
    r = np.asarray(r, float) - np.mean(r)
    d = float(r @ r)
    return float(r[1:] @ r[:-1] / d) if d > 0 else 0.0


# ---------------------------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------------------------
class BuildingModel(GapModel):
    """The building on shake-table runs as a model of :mod:`rrfrei.gap` (module docstring).

    Parameters
    ----------
    law : isolator law name, possibly augmented (``"bouc_wen+rate"``).
    superstructure : :class:`Superstructure` (or an identification / a ShearBuilding).
    start_test : the calibration runs' isolation tests joined in order (a
        :class:`rrfrei.io.ShearTest`: d_0 against F); gives the isolator loop fit that starts the
        search and the effects' scales.
    scales : channel -> normalising scale (RMS of the channel over the calibration runs).
    system : system effects included (subset of :data:`SYSTEM_EFFECTS`).
    draws : posterior draws per fit.
    loop_fit : the isolator loop fit of the base law on ``start_test`` (an
        :class:`rrfrei.gap.model.IsolatorFit`), computed once and shared by augmented models.
    a_ref : reference peak table acceleration of ``softening`` [m/s^2].
    """

    def __init__(self, law: str | LawSpec, superstructure, start_test: ShearTest, scales: Mapping[str, float],
                 *, system: Sequence[str] = (), draws: int = 30, loop_fit=None, a_ref: float = 1.0,
                 max_nfev: int = MAX_NFEV, global_evals: int = GLOBAL_EVALS,
                 refit_global_evals: int = REFIT_GLOBAL_EVALS) -> None:
        self.spec = get(law)
        self.sup = Superstructure.of(superstructure)
        self.start_test = start_test
        self.scales = {c: float(scales[c]) for c in REPORT_CHANNELS}
        for s in system:
            if s not in SYSTEM_EFFECTS:
                raise ValueError(f"unknown system effect {s!r}; available: {', '.join(SYSTEM_EFFECTS)}")
        self.system = tuple(s for s in SYSTEM_EFFECTS if s in system)
        if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 4:
            raise ValueError(f"draws must be an integer >= 4, got {draws!r}")
        self.draws = int(draws)
        self.loop_fit = loop_fit
        self.a_ref = float(a_ref)
        self.max_nfev = int(max_nfev)
        self.global_evals = int(global_evals)
        self.refit_global_evals = int(refit_global_evals)
        iso = IsolatorModel(self.spec, draws=10)
        free, fixed = iso.free_parameters(start_test)
        sysp = ["k_scale", "zeta"]
        if "isolation_damping" in self.system:
            sysp.append("c_iso")
        if "softening" in self.system:
            sysp.append("soft_exp")
        self.layout = _Layout(self.spec, free, fixed, sysp)
        self._iso = iso

    # --- identity -------------------------------------------------------------------------
    @property
    def name(self) -> str:  # type: ignore[override]
        return "+".join([self.spec.name, *self.system])

    @property
    def effects(self) -> tuple[str, ...]:
        return tuple(self.spec.effects) + self.system

    def augment(self, effects: Sequence[str], variants: Mapping[str, str] | None = None) -> BuildingModel:
        iso = [e for e in effects if e not in SYSTEM_EFFECTS]
        sysx = [e for e in effects if e in SYSTEM_EFFECTS]
        base = self.spec.name.split("+")[0]
        law = "+".join([base, *self.spec.effects, *iso])
        return BuildingModel(law, self.sup, self.start_test, self.scales, system=[*self.system, *sysx],
                             draws=self.draws, loop_fit=self.loop_fit, a_ref=self.a_ref,
                             max_nfev=self.max_nfev, global_evals=self.global_evals,
                             refit_global_evals=self.refit_global_evals)

    @property
    def candidate_effects(self) -> tuple[str, ...]:
        """Every catalogue effect and every system effect."""
        return tuple(catalogue()) + SYSTEM_EFFECTS

    # --- data -----------------------------------------------------------------------------
    def stack(self, out: Mapping[str, Mapping[str, np.ndarray]], data: BuildingData) -> np.ndarray:
        """The fitted channels of the observed runs, normalised, as one vector (run-major)."""
        return np.concatenate([out[o][c] / self.scales[c] for o in data.observed for c in FIT_CHANNELS])

    def observed(self, data: BuildingData) -> np.ndarray:
        return self.stack({o: data.measured(o) for o in data.observed}, data)

    def sigma_vector(self, per_channel: Mapping[str, float], data: BuildingData) -> np.ndarray:
        return np.concatenate([np.full(data.measured(o)["isolator_disp"].size, float(per_channel[c]))
                               for o in data.observed for c in FIT_CHANNELS])

    def groups(self, data: BuildingData) -> np.ndarray:
        """Blocks: ``WINDOW_S`` time windows of each observed run, all fitted channels together."""
        labels, g0 = [], 0
        for o in data.observed:
            t = data.time(o)
            w = np.minimum((t // WINDOW_S).astype(np.int64), max(int(t[-1] // WINDOW_S) - 1, 0))
            nb = int(w.max()) + 1
            for _ in FIT_CHANNELS:
                labels.append(w + g0)
            g0 += nb
        return np.concatenate(labels)

    def extra_sigma(self, fit: BuildingFit, channel: str) -> float:
        """Residual sd of a channel that is not fitted (story-1 shear): from the optimum on the
        calibration runs."""
        return fit.sigma_c.get(channel, float("nan"))

    # --- parameters -------------------------------------------------------------------------
    def _bounds_scales(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sc = test_scales(self.start_test)
        lay = self.layout
        scale, box = {}, {}
        base = self._base_values()
        for n in lay.law_free:
            scale[n] = max(abs(base.get(n, 0.0)), 1e-3)
        for eff in self.spec.effects:
            info = self._iso.effect_hints(eff)
            scale.update({k: v for k, v in info.scales(sc).items() if k in lay.law_free})
            box.update(info.box(sc))
        for n in ("alpha1", "alpha2", "eta", "beta", "gamma", "mu"):
            if n in scale:
                scale[n] = max(scale[n], 0.3)
        sys_scale = {"k_scale": 1.0, "zeta": 0.05, "c_iso": 0.05 * sc.force / sc.vel, "soft_exp": 0.1}
        sys_box = {"k_scale": K_SCALE_BOX, "zeta": ZETA_BOX, "c_iso": (0.0, 2.0 * sc.force / sc.vel),
                   "soft_exp": (0.0, 1.0)}
        s, lb, ub = [], [], []
        for n in lay.law_free:
            q = self.spec.param(n)
            lo, hi = q.lower, q.upper
            if n in box:
                lo, hi = max(lo, box[n][0]), min(hi, box[n][1])
            s.append(scale.get(n, 1.0))
            lb.append(lo)
            ub.append(hi)
        for n in lay.system:
            s.append(sys_scale[n])
            lb.append(sys_box[n][0])
            ub.append(sys_box[n][1])
        s = np.array(s)
        return s, np.array(lb) / s, np.array(ub) / s

    def _base_values(self) -> dict[str, float]:
        return dict(self.loop_fit.params) if self.loop_fit is not None else {}

    def simulate(self, x: np.ndarray, data: BuildingData, tally: dict | None = None):
        """(status, run -> channel -> (n,)) at parameters ``x`` (:attr:`layout` names, units);
        ``tally``: counts of the robust local solve's deviations (:func:`simulate`)."""
        lay = self.layout
        vals = dict(zip(lay.names, np.asarray(x, float)))
        p = lay.law_vector(vals)
        if self.spec.check is not None:
            try:
                self.spec.check(p)
            except ValueError:
                return -97, {}
        return simulate(self.spec, p, self.sup, data, k_scale=vals["k_scale"], zeta=vals["zeta"],
                        c_iso=vals.get("c_iso", 0.0), soft_exp=vals.get("soft_exp", 0.0), a_ref=self.a_ref,
                        tally=tally)

    def _starts(self, start) -> list[dict[str, float]]:
        """Start points (dicts of parameter values): from fits given (their parameters, with each
        added effect at the catalogue's start and, when no global search follows, also at its
        neutral value: the global search's box holds both), else from the loop fit."""
        sc = test_scales(self.start_test)
        bases: list[dict[str, float]] = []
        for s in ([start] if isinstance(start, FitResult) else list(start or [])):
            bases.append(dict(s.params) if isinstance(s, BuildingFit) else dict(s.params))
        if not bases:
            b = dict(self._base_values())
            b.update({"k_scale": 1.0, "zeta": self.sup.zeta})
            bases = [b, dict(b, k_scale=1.2, zeta=min(3 * self.sup.zeta, 0.25))]
        alternatives = start is None or self.refit_global_evals <= 0
        c_iso_new = not all("c_iso" in b for b in bases)
        out = []
        for b in bases:
            b = dict(b)
            b.setdefault("k_scale", 1.0)
            b.setdefault("zeta", self.sup.zeta)
            b.setdefault("c_iso", 0.0)
            b.setdefault("soft_exp", 0.0)
            opts = [{}]
            for eff in self.spec.effects:
                info = self._iso.effect_hints(eff)
                es = info.scales(sc)
                if any(k not in b for k in es):
                    neutral = dict(zip([q.name for q in info.spec.params], info.spec.neutral))
                    alts = [*info.starts(sc)[:1], neutral] if alternatives else info.starts(sc)[:1]
                    opts = [dict(o, **e) for o in opts for e in alts]
            if "c_iso" in self.layout.system and c_iso_new:
                c0 = 0.02 * sc.force / sc.vel
                opts = [dict(o, c_iso=v) for o in opts for v in ((0.0, c0) if alternatives else (c0,))]
            out.extend(dict(b, **o) for o in opts)
        return out

    # --- fitting -------------------------------------------------------------------------------
    def fit(self, data: BuildingData, *, seed: int = 0, start=None,
            budget: TimeBudget | None = None) -> BuildingFit:
        """Output-error fit on ``data`` (module docstring): least squares from several starts,
        then the importance-checked Laplace posterior.

        Raises NumericalFailure when every start fails (the message names the model and data).
        """
        if not isinstance(data, BuildingData):
            raise ValueError(f"data must be a BuildingData, got {type(data).__name__}")
        lay = self.layout
        s_vec, lb, ub = self._bounds_scales()
        y = self.observed(data)
        n_obs = {c: data.measured(data.observed[0])["isolator_disp"].size for c in FIT_CHANNELS}
        sizes = [data.measured(o)["isolator_disp"].size for o in data.observed]
        ch_index = np.concatenate([np.full(nn, j) for nn in sizes for j in range(len(FIT_CHANNELS))])
        del n_obs
        w = np.ones(len(FIT_CHANNELS))
        big = 10.0
        counter = {"n": 0, "failed": 0}

        kept: dict[bytes, dict] = {}

        def model_out(x, keep: bool = False):
            counter["n"] += 1
            if budget is not None:
                budget.check()
            st, out = self.simulate(x * s_vec, data, tally=counter)
            if st != 0:
                counter["failed"] += 1
                return None
            if keep:
                kept[np.asarray(x * s_vec, dtype=float).tobytes()] = out
            return self.stack(out, data)

        def resid(x):
            f = model_out(x)
            if f is None:
                return np.full(y.size, big)
            return (f - y) * w[ch_index]

        starts = self._starts(start)
        xs = []
        for s0 in starts:
            x0 = np.array([s0.get(n, lay.law_vector(s0)[lay.idx[n]] if n in lay.idx else 0.0)
                           for n in lay.names])
            x0 = np.clip(x0 / s_vec, lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
            xs.append(x0)

        def search(x0, nfev):
            return least_squares(resid, x0, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=nfev,
                                 diff_step=1e-3)

        # global start: CMA-ES over every parameter (a fit from the loop fit) or over the parameters
        # the given fits do not hold (an added effect's, with the superstructure's), from the first
        # start; its best point joins the starts of the local search
        fits_given = [] if start is None else [start] if isinstance(start, FitResult) else list(start)
        given = {n for n in lay.names if fits_given and all(n in f_.params for f_ in fits_given)}
        free_g = np.array([n not in given or n in ("k_scale", "zeta") for n in lay.names])
        evals = self.global_evals if start is None else self.refit_global_evals
        if evals > 0 and free_g.any():
            xg = _cma_start(resid, xs[0], lb, ub, free_g, evals, seed)
            if xg is not None:
                xs.append(xg)

        screened = []
        for x0 in xs:
            try:
                screened.append(search(x0, SCREEN_NFEV if start is None else REFIT_SCREEN_NFEV))
            except ValueError:
                continue
        if not screened:
            raise NumericalFailure(f"output-error fit of {self.name!r} on {data.name}: every start failed")
        best = min(screened, key=lambda r: r.cost)
        # reweight: each channel by its residual sd (the MLE), then continue; a refit from a given
        # start (an effect added to a fitted building) continues once, shorter
        for _ in range(2 if start is None else 1):
            r = best.fun / w[ch_index]
            sig = np.array([math.sqrt(float(np.mean(r[ch_index == j] ** 2))) or 1.0
                            for j in range(len(FIT_CHANNELS))])
            w = 1.0 / sig
            try:
                best = search(best.x, self.max_nfev if start is None else REFIT_NFEV)
            except ValueError:
                break
        x_opt = best.x * s_vec
        st, out = self.simulate(x_opt, data)
        if st != 0:
            raise NumericalFailure(f"output-error fit of {self.name!r} on {data.name}: the optimum's "
                                   f"simulation fails (status {st})")
        f = self.stack(out, data)
        res = f - y
        sigma_c, rho_c = {}, {}
        for j, c in enumerate(FIT_CHANNELS):
            rc = res[ch_index == j]
            sigma_c[c] = float(np.sqrt(np.mean(rc**2)))
            rho_c[c] = _ar1(np.concatenate([(out[o][c] - data.measured(o)[c]) for o in data.observed]))
        # the story-1 shear: not fitted; its residual sd at the optimum gives its band
        rb = np.concatenate([out[o]["base_shear"] - data.measured(o)["base_shear"] for o in data.observed])
        sigma_c["base_shear"] = float(np.sqrt(np.mean(rb**2))) / self.scales["base_shear"]
        # Laplace in scaled coordinates with tempered weights, checked by importance sampling
        tw = np.sqrt(np.array([_temper(rho_c[c]) for c in FIT_CHANNELS]))
        sg = np.array([sigma_c[c] for c in FIT_CHANNELS])
        J = best.jac / w[ch_index][:, None] * (tw / sg)[ch_index][:, None]
        k = J.shape[1]
        A = J.T @ J + np.eye(k)
        try:
            cov = np.linalg.inv(A)
        except np.linalg.LinAlgError:
            wv, V = np.linalg.eigh(0.5 * (A + A.T))
            cov = (V / np.maximum(wv, 1.0)) @ V.T
        note = ""
        S = self.draws
        rng = np.random.default_rng([seed, 31])
        Z = rng.normal(size=(S, k))
        try:
            L = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            wv, V = np.linalg.eigh(cov)
            L = V * np.sqrt(np.clip(wv, 0, None))
        Xs = np.clip(best.x[None, :] + Z @ L.T, lb, ub)
        Xs[0] = best.x
        tw_vec = (tw**2)[ch_index]
        sg_vec = sg[ch_index]

        def tempered_ll(fv):
            rr = (fv - y) / sg_vec
            return float(-0.5 * np.sum(tw_vec * rr**2))

        ll0 = tempered_ll(f)
        logw = np.full(S, -np.inf)
        for i in range(S):
            if i == 0:
                logw[i] = 0.0
                continue
            fi = model_out(Xs[i], keep=True)
            if fi is None:
                continue
            # target: tempered likelihood times the unit ridge prior around the optimum (the prior of
            # the Laplace precision), over the Gaussian proposal
            dx = Xs[i] - best.x
            logw[i] = tempered_ll(fi) - ll0 - 0.5 * float(dx @ dx) + 0.5 * float(Z[i] @ Z[i])
        ok = np.isfinite(logw)
        wts = np.exp(logw - logw[ok].max())
        wts[~ok] = 0.0
        wts /= wts.sum()
        ess = float(1.0 / np.sum(wts**2))
        u0 = np.random.default_rng([seed, 998]).uniform()
        pick = np.minimum(np.searchsorted(np.cumsum(wts), (u0 + np.arange(S)) / S), S - 1)
        X = Xs[pick] * s_vec[None, :]
        if ess < 5.0:
            note = (f"importance check of the Laplace posterior of {self.name} degenerate (effective "
                    f"sample size {ess:.1f} of {S}): the band holds little parameter uncertainty")
        if counter["failed"]:
            msg = (f"{counter['failed']} of {counter['n']} simulations of {self.name} failed during the fit "
                   "(counted as bad points)")
            note = f"{note}; {msg}" if note else msg
        if counter.get("robust_sims"):
            msg = (f"the robust local solve replaced OpenSees' failed iteration (a deviation) at "
                   f"{counter['robust_steps']} time steps of {counter['robust_sims']} of {counter['n']} "
                   f"simulations of {self.name} during the fit")
            note = f"{note}; {msg}" if note else msg
        kept[np.asarray(best.x * s_vec, dtype=float).tobytes()] = out
        fit = BuildingFit(model=self, x_opt=x_opt, X=X, sigma_c=sigma_c, rho_c=rho_c, ess=ess,
                          nfev=counter["n"], failed=counter["failed"], seed=seed, note=note,
                          robust_sims=int(counter.get("robust_sims", 0)))
        fit._cache[("sims", id(data))] = (data, kept)  # the draws' simulations on the fitted data
        return fit

    # --- checkpoints -----------------------------------------------------------------------------
    def checkpoint_key(self, data: BuildingData) -> str:
        h = hashlib.sha256()
        for r in data.runs:
            for a in (r.table_accel, r.accel, r.disp):
                h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
        settings = {"law": self.spec.name, "system": list(self.system), "draws": self.draws,
                    "observed": list(data.observed), "pad": data.pad_s, "format": 1,
                    "sup": [self.sup.masses.tolist(), self.sup.stiffness.tolist(), self.sup.zeta],
                    "scales": self.scales, "max_nfev": self.max_nfev, "format_fit": 2,
                    "global": [self.global_evals, self.refit_global_evals],
                    "start": None if self.loop_fit is None else sorted(self.loop_fit.params.items())}
        h.update(json.dumps(settings, sort_keys=True, default=str).encode())
        return h.hexdigest()

    def fit_state(self, fit: BuildingFit) -> dict[str, np.ndarray]:
        return {"x_opt": fit.x_opt, "X": fit.X, "names": np.array(fit.names, dtype=str),
                "sigma": np.array([fit.sigma_c[c] for c in REPORT_CHANNELS]),
                "rho": np.array([fit.rho_c[c] for c in FIT_CHANNELS]), "ess": np.array(fit.ess),
                "nfev": np.array(fit.nfev), "failed": np.array(fit.failed), "seed": np.array(fit.seed),
                "note": np.array(fit.note), "robust_sims": np.array(fit.robust_sims)}

    def restore(self, state: Mapping[str, np.ndarray]) -> BuildingFit:
        names = tuple(str(x) for x in state["names"])
        if names != self.layout.names:
            raise ValueError("checkpoint of another parameter layout")
        return BuildingFit(model=self, x_opt=np.asarray(state["x_opt"], float),
                           X=np.asarray(state["X"], float),
                           sigma_c=dict(zip(REPORT_CHANNELS, map(float, state["sigma"]))),
                           rho_c=dict(zip(FIT_CHANNELS, map(float, state["rho"]))), ess=float(state["ess"]),
                           nfev=int(state["nfev"]), failed=int(state["failed"]), seed=int(state["seed"]),
                           note=str(state["note"]),
                           robust_sims=int(state["robust_sims"]) if "robust_sims" in state else 0)


def calibration_test(runs: Sequence[ShakeTableRun], rate_hz: float) -> ShearTest:
    """The isolation tests (d_0 against F) of ``runs``, decimated to ``rate_hz``, joined in order."""
    return concat_tests([isolation_test(r.decimate(rate_hz)) for r in runs],
                        name="+".join(r.name for r in runs))
