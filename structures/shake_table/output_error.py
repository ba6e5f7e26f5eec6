"""The output-error search of a building (:class:`structures.shake_table.building_model.BuildingModel`):
objective, global start, least squares, and the importance-checked Laplace posterior.

Objective: the sum over the fitted channels (:data:`structures.shake_table.simulation.FIT_CHANNELS`)
of the squared residuals, each channel normalised by its RMS on the calibration runs and weighted
by 1 / sigma_c, sigma_c the RMS residual of the previous pass (iteratively reweighted: the MLE);
the residual model is :mod:`structures.shake_table.building_fit`'s.

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

Independent simulations (a CMA-ES generation, the columns of a finite-difference Jacobian, the
importance draws) are evaluated as batches over the processes the caller gives the fit
(:class:`rrfrei.forkmap.ForkMap`, :func:`rrfrei.forkmap.sharing`); the fit is bit for bit the
one-process fit.

Posterior: Laplace, ``N(x*, (J^T W J + I)^-1)`` with the tempered weights W and a unit ridge in
scaled coordinates, checked by importance sampling (weights = tempered likelihood over the
Gaussian proposal; its effective sample size is reported in
:attr:`structures.shake_table.building_fit.BuildingFit.ess`) and resampled.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from rrfrei.blas import one_blas_thread
from rrfrei.budget import TimeBudget
from rrfrei.errors import NumericalFailure
from rrfrei.forkmap import ForkMap
from rrfrei.gap.model import FitResult
from structures.shake_table.building_fit import BuildingFit, ar1, temper
from structures.shake_table.simulation import FIT_CHANNELS, BuildingData

__all__ = ["GLOBAL_EVALS", "MAX_NFEV", "REFIT_GLOBAL_EVALS", "cma_start", "fit_output_error"]

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


def fit_output_error(model, data: BuildingData, *, seed: int = 0, start=None,
                     budget: TimeBudget | None = None) -> BuildingFit:
    """Output-error fit of ``model`` (a :class:`structures.shake_table.building_model.BuildingModel`)
    on ``data`` (module docstring): least squares from several starts, the first a CMA-ES global
    start, then the importance-checked Laplace posterior.

    Raises NumericalFailure when every start fails (the message names the model and data).
    """
    lay = model.layout
    s_vec, lb, ub = model.scaled_bounds()
    y = model.observed(data)
    sizes = [data.measured(o)["isolator_disp"].size for o in data.observed]
    ch_index = np.concatenate([np.full(nn, j) for nn in sizes for j in range(len(FIT_CHANNELS))])
    w = np.ones(len(FIT_CHANNELS))
    big = 10.0
    counter = {"n": 0, "failed": 0}

    kept: dict[bytes, dict] = {}

    def simulate_point(x):
        """One simulation at scaled parameters ``x``: (status, outputs, robust-solve tally)."""
        tally: dict = {}
        st, out = model.simulate(x * s_vec, data, tally=tally)
        return st, out, tally

    def model_outs(X, keep: bool = False) -> list:
        """The stacked outputs at the scaled points ``X`` (None where a simulation fails), the
        batch spread over the fit's processes (:class:`rrfrei.forkmap.ForkMap`)."""
        if budget is not None:
            budget.check()
        outs = []
        for x, (st, out, tally) in zip(X, fmap.map(X)):
            counter["n"] += 1
            for key, val in tally.items():
                counter[key] = counter.get(key, 0) + val
            if st != 0:
                counter["failed"] += 1
                outs.append(None)
                continue
            if keep:
                kept[np.asarray(x * s_vec, dtype=float).tobytes()] = out
            outs.append(model.stack(out, data))
        return outs

    def post(f):
        if f is None:
            return np.full(y.size, big)
        return (f - y) * w[ch_index]

    def resid(x):
        return post(model_outs([x])[0])

    def resids(X) -> list:
        return [post(f) for f in model_outs(list(X))]

    fmap = ForkMap(simulate_point)
    try:
        starts = model.starts(start)
        xs = []
        for s0 in starts:
            x0 = np.array([s0.get(n, lay.law_vector(s0)[lay.idx[n]] if n in lay.idx else 0.0)
                           for n in lay.names])
            x0 = np.clip(x0 / s_vec, lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
            xs.append(x0)

        def search(x0, nfev):
            with one_blas_thread():  # trf's SVD of a thin Jacobian: one thread is far faster on shared cores
                return least_squares(resid, x0, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=nfev,
                                     diff_step=1e-3, workers=lambda _fun, X: resids(X))

        # global start: CMA-ES over every parameter (a fit from the loop fit) or over the parameters
        # the given fits do not hold (an added effect's, with the superstructure's), from the first
        # start; its best point joins the starts of the local search
        fits_given = [] if start is None else [start] if isinstance(start, FitResult) else list(start)
        given = {n for n in lay.names if fits_given and all(n in f_.params for f_ in fits_given)}
        free_g = np.array([n not in given or n in ("k_scale", "zeta") for n in lay.names])
        evals = model.global_evals if start is None else model.refit_global_evals
        if evals > 0 and free_g.any():
            xg = cma_start(resids, xs[0], lb, ub, free_g, evals, seed)
            if xg is not None:
                xs.append(xg)

        screened = []
        for x0 in xs:
            try:
                screened.append(search(x0, SCREEN_NFEV if start is None else REFIT_SCREEN_NFEV))
            except ValueError:
                continue
        if not screened:
            raise NumericalFailure(f"output-error fit of {model.name!r} on {data.name}: every start failed")
        best = min(screened, key=lambda r: r.cost)
        # reweight: each channel by its residual sd (the MLE), then continue; a refit from a given
        # start (an effect added to a fitted building) continues once, shorter
        for _ in range(2 if start is None else 1):
            r = best.fun / w[ch_index]
            sig = np.array([math.sqrt(float(np.mean(r[ch_index == j] ** 2))) or 1.0
                            for j in range(len(FIT_CHANNELS))])
            w = 1.0 / sig
            try:
                best = search(best.x, model.max_nfev if start is None else REFIT_NFEV)
            except ValueError:
                break
        x_opt = best.x * s_vec
        st, out = model.simulate(x_opt, data)
        if st != 0:
            raise NumericalFailure(f"output-error fit of {model.name!r} on {data.name}: the optimum's "
                                   f"simulation fails (status {st})")
        f = model.stack(out, data)
        res = f - y
        sigma_c, rho_c = {}, {}
        for j, c in enumerate(FIT_CHANNELS):
            rc = res[ch_index == j]
            sigma_c[c] = float(np.sqrt(np.mean(rc**2)))
            rho_c[c] = ar1(np.concatenate([(out[o][c] - data.measured(o)[c]) for o in data.observed]))
        # the story-1 shear: not fitted; its residual sd at the optimum gives its band
        rb = np.concatenate([out[o]["base_shear"] - data.measured(o)["base_shear"] for o in data.observed])
        sigma_c["base_shear"] = float(np.sqrt(np.mean(rb**2))) / model.scales["base_shear"]
        # Laplace in scaled coordinates with tempered weights, checked by importance sampling
        tw = np.sqrt(np.array([temper(rho_c[c]) for c in FIT_CHANNELS]))
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
        S = model.draws
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
        logw[0] = 0.0
        for i, fi in enumerate(model_outs(list(Xs[1:]), keep=True), start=1):
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
            note = (f"importance check of the Laplace posterior of {model.name} degenerate (effective "
                    f"sample size {ess:.1f} of {S}): the band holds little parameter uncertainty")
        if counter["failed"]:
            msg = (f"{counter['failed']} of {counter['n']} simulations of {model.name} failed during the fit "
                   "(counted as bad points)")
            note = f"{note}; {msg}" if note else msg
        if counter.get("robust_sims"):
            msg = (f"the robust local solve replaced OpenSees' failed iteration (a deviation) at "
                   f"{counter['robust_steps']} time steps of {counter['robust_sims']} of {counter['n']} "
                   f"simulations of {model.name} during the fit")
            note = f"{note}; {msg}" if note else msg
        kept[np.asarray(best.x * s_vec, dtype=float).tobytes()] = out
        fit = BuildingFit(model=model, x_opt=x_opt, X=X, sigma_c=sigma_c, rho_c=rho_c, ess=ess,
                          nfev=counter["n"], failed=counter["failed"], seed=seed, note=note,
                          robust_sims=int(counter.get("robust_sims", 0)))
        fit._cache[("sims", id(data))] = (data, kept)  # the draws' simulations on the fitted data
        return fit
    finally:
        fmap.close()


def cma_start(resids, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, free: np.ndarray, evals: int,
              seed: int) -> np.ndarray | None:
    """Best point of a CMA-ES search (Hansen 2016, "The CMA evolution strategy: a tutorial",
    arXiv:1604.00772; the ``cma`` package) of the sum of squares of the residuals over the
    coordinates ``free`` (scaled, the others held at ``x0``), in the box ``x0 +- GLOBAL_BOX`` within
    the bounds, mapped onto the unit cube; ``evals`` evaluations at most.  ``resids(X)``: the
    residual vectors at the points ``X`` (a generation at a time, so they can be evaluated in
    parallel).  None when no evaluated point beats ``x0``."""
    import cma

    lo = np.maximum(lb, x0 - GLOBAL_BOX)[free]
    hi = np.minimum(ub, x0 + GLOBAL_BOX)[free]
    span = np.where(hi > lo, hi - lo, 1.0)
    u0 = np.clip((x0[free] - lo) / span, 0.0, 1.0)

    def full(u):
        x = x0.copy()
        x[free] = lo + np.clip(np.asarray(u, float), 0.0, 1.0) * span
        return x

    def fs(U):
        return [float(r @ r) for r in resids([full(u) for u in U])]

    f0 = fs([u0])[0]
    opts = {"bounds": [0.0, 1.0], "seed": 1 + int(seed) % 100_000, "maxfevals": int(evals),
            "verbose": -9, "tolfun": 1e-6 * max(f0, 1e-12)}
    if u0.size == 1:  # cma needs two coordinates: a dummy one
        opts["bounds"] = [[0.0, 0.0], [1.0, 1.0]]
        es = cma.CMAEvolutionStrategy([u0[0], 0.5], CMA_SIGMA, opts)
        _ask_tell(es, lambda U: fs([u[:1] for u in U]))
        ub_ = np.asarray(es.result.xbest[:1]) if es.result.xbest is not None else None
    else:
        es = cma.CMAEvolutionStrategy(u0, CMA_SIGMA, opts)
        _ask_tell(es, fs)
        ub_ = es.result.xbest
    if ub_ is None or not es.result.fbest < f0:
        return None
    return full(ub_)


def _ask_tell(es, fs) -> None:
    """The loop of ``es.optimize`` (ask a generation, evaluate it, tell), the generation evaluated
    as one batch by ``fs``."""
    while not es.stop():
        U = es.ask()
        es.tell(U, fs(U))
