"""Bayesian calibration of isolator laws on shear tests (issue 4).

Layers: Numba batched likelihoods (:mod:`.likelihood`) -> optimiser and ensemble sampler
(:mod:`.sampler`) -> labelled results (:mod:`.results`: InferenceData, :class:`Calibration`) ->
checks and model comparison (:mod:`.checks`, :mod:`.compare`) -> this public API.

>>> import rrfrei
>>> cal = rrfrei.calibrate(rrfrei.load_test("protocol1"), "plasticity", steps=400)  # doctest: +SKIP
>>> cal.summary  # doctest: +SKIP

Identifiability (what the data of one cyclic test can and cannot fix):

* ``plasticity`` / ``bouc_wen``: with ``alpha2`` near 0 the exponent ``mu`` of the nonlinear
  hardening term ``alpha2 k_init sgn(u)|u|^mu`` has no effect on the force, so its posterior is its
  prior (not identifiable); it becomes identifiable only when the test shows stiffening.
  ``k_init`` is identifiable only when the elastic branch is sampled by several points; a sharp
  yield at a displacement smaller than the sampling step leaves only a lower bound.
* ``bouc_wen`` (A = 1): the force is exactly invariant under (qd, beta, gamma) ->
  (c qd, c^eta beta, c^eta gamma), so the three can never be identified together (an unbounded
  ridge).  The registry holds ``beta`` at 0.5 in calibration (``ParamSpec.hold``); the recovery
  tests hold gamma at its true value instead (``fixed=``), which breaks the same ridge.
* ``elastomeric_x``: geometry (``d2``, ``tr``, ``n``, ``d1``, ``tc``) is fixed from the test's
  geometry; ``cd`` (viscous damping) is not sampled by default (optional, 0).
* ``hdr``: the damage parameters ``c1``, ``c2``, ``c4`` and the residual fraction ``c3`` are
  identifiable only when the test repeats cycles at growing amplitudes (scragging, Mullins); on
  a single-amplitude test they trade off with ``a1`` and ``b1``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rrfrei.calibration.checks import predict
from rrfrei.calibration.compare import compare, elpd_loco  # the function shadows the module name
from rrfrei.calibration.likelihood import NOISE_MODELS, Problem
from rrfrei.calibration.priors import resolve_priors
from rrfrei.calibration.results import Calibration, build_idata, loglik_pointwise, posterior_draws
from rrfrei.calibration.sampler import MAX_STEPS, find_map, load_optimum, run_chain, save_optimum
from rrfrei.io import ShearTest, read_test
from rrfrei.laws import LawSpec, get

__all__ = [
    "Calibration",
    "ConvergenceWarning",
    "calibrate",
    "compare",
    "elpd_loco",
    "loglik_pointwise",
    "posterior_draws",
    "predict",
    "setup_problem",
]


class ConvergenceWarning(UserWarning):
    """The chain did not meet the convergence rule; the posterior may be unreliable."""


def setup_problem(test: ShearTest, law: str | LawSpec, *, priors=None, noise: str = "iid",
                  fixed: Mapping[str, float] | None = None) -> Problem:
    """The :class:`Problem` (free/fixed split, priors) that :func:`calibrate` samples."""
    spec = get(law)
    if noise not in NOISE_MODELS:
        raise ValueError(f"noise must be one of {', '.join(NOISE_MODELS)}, got {noise!r}")
    override_names = {str(k) for k in priors} if isinstance(priors, Mapping) else set()
    free, all_fixed = spec.resolve_fixed(
        test.geometry, fixed, frozenset(override_names),
        source=str(test.source or "the test file"),
    )
    pri = resolve_priors(spec, free, np.asarray(test.force), np.asarray(test.disp), noise, priors)
    return Problem(spec, test, free, all_fixed, noise, dict(pri))


def calibrate(
    test: ShearTest | str | Path,
    law: str | LawSpec,
    *,
    priors=None,
    noise: str = "iid",
    walkers: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    checkpoint: str | Path | None = None,
    progress: bool = True,
    fixed: Mapping[str, float] | None = None,
    max_steps: int = MAX_STEPS,
) -> Calibration:
    """Posterior of ``law``'s parameters given ``test``.

    Parameters
    ----------
    test : a :class:`~rrfrei.io.ShearTest` or a CSV path (read with :func:`rrfrei.read_test`).
    law : registered law name (``rrfrei.laws.names()``) or augmented law (``"bouc_wen+rate"``).
    priors : None (registry priors rescaled to the test, see :mod:`.priors`), ``"registry"`` (raw
        registry priors), or a mapping / TOML file ``{name: Prior | {kind, a, b}}`` overriding any
        sampled quantity (law parameter, ``sigma``, ``rho``); naming an optional parameter (e.g.
        ``cd``) samples it instead of fixing it at its default.
    noise : ``"iid"`` Gaussian residuals or ``"ar1"`` (AR(1), unknown rho), see :mod:`.likelihood`.
    walkers : ensemble size (default max(32, 4 x sampled dimensions)).
    steps : MCMC steps; None runs until the chain is >= 50 autocorrelation times long and tau is
        stable, up to ``max_steps``.
    seed : seed of the optimiser, the initial ball and the sampler.
    checkpoint : HDF5 file (emcee backend); an existing one is resumed.
    progress : show progress bars (tqdm).
    fixed : values for law parameters to hold fixed (geometry defaults come from ``test.geometry``).

    Returns
    -------
    Calibration

    Warns
    -----
    ConvergenceWarning
        the chain is shorter than 50 tau, tau is unstable or R-hat >= 1.05.
    """
    import time

    t0 = time.perf_counter()
    if isinstance(test, (str, Path)):
        test = read_test(test)
    if not isinstance(test, ShearTest):
        raise ValueError(f"test must be a ShearTest or a CSV path, got {type(test).__name__}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    spec = get(law)
    problem = setup_problem(test, spec, priors=priors, noise=noise, fixed=fixed)
    if spec.uses_velocity and not test.has_time:
        warnings.warn(
            f"test {test.name!r} has no time column: law {spec.name!r} has rate-dependent terms, "
            "which are evaluated quasi-statically (velocity 0); rate effects cannot be judged",
            UserWarning, stacklevel=2,
        )
    nw = walkers if walkers is not None else max(32, 4 * problem.ndim)
    if not isinstance(nw, (int, np.integer)) or nw < 2 * problem.ndim:
        raise ValueError(
            f"walkers = {walkers!r} is too few for {problem.ndim} sampled quantities; "
            f"use >= {2 * problem.ndim}"
        )
    if steps is not None and (not isinstance(steps, (int, np.integer)) or steps < 2):
        raise ValueError(f"steps must be an integer >= 2 or None (run to convergence), got {steps!r}")
    stored = load_optimum(checkpoint) if checkpoint is not None else None
    if stored is not None and stored.get("names") == list(problem.names) and stored.get("law") == spec.name:
        theta0 = np.asarray(stored["theta"], dtype=float)
    else:
        if stored is not None:
            raise ValueError(
                f"checkpoint {checkpoint} belongs to law {stored.get('law')!r} with parameters "
                f"{stored.get('names')}; this run samples {spec.name!r} {list(problem.names)}"
            )
        theta0, _ = find_map(problem, seed)
        if checkpoint is not None:
            Path(checkpoint).parent.mkdir(parents=True, exist_ok=True)
            save_optimum(checkpoint, {"law": spec.name, "names": list(problem.names),
                                      "theta": [float(x) for x in theta0]})
    t_opt = time.perf_counter() - t0
    res = run_chain(problem, theta0, walkers=walkers, steps=steps, seed=seed, checkpoint=checkpoint,
                    progress=progress, max_steps=max_steps)
    chain, logp = res.chain, res.log_prob
    n_steps, nw, _ = chain.shape
    tmax = float(np.nanmax(res.tau)) if np.any(np.isfinite(res.tau)) else float("nan")
    if math.isfinite(tmax):
        burn = min(n_steps // 2, max(n_steps // 4, int(2 * tmax)))
        thin = max(1, int(tmax / 2))
    else:
        burn, thin = n_steps // 2, 1
    from rrfrei.calibration.results import MAX_DRAWS

    while ((n_steps - burn + thin - 1) // thin) * nw > MAX_DRAWS and thin < n_steps:
        thin += 1
    # MAP: the best of the optimum and every sample
    lp0 = float(problem.log_prob(theta0[None, :])[0])
    j = np.unravel_index(int(np.argmax(logp)), logp.shape)
    theta_map = chain[j] if logp[j] > lp0 else theta0
    diagnostics = {
        "acceptance": res.acceptance, "tau": {n: float(t) for n, t in zip(problem.names, res.tau)},
        "steps": int(n_steps), "walkers": int(nw), "burn": int(burn), "thin": int(thin),
        "evaluations": int(res.evals), "seconds_sampling": res.seconds, "seconds_optimum": t_opt,
        "note": res.tau_note, "converged": False,
    }
    idata = build_idata(problem, chain, logp, burn=burn, thin=thin, theta_map=theta_map,
                        fixed=problem.fixed, diagnostics=diagnostics, seed=seed)
    cal = Calibration.from_idata(idata)
    rhat = float(cal.summary["R-hat"].max())
    ess = float(cal.summary["ESS"].min())
    converged = bool(res.converged_tau and rhat < 1.05)
    note = res.tau_note
    if rhat >= 1.05:
        note = (note + "; " if note else "") + f"R-hat up to {rhat:.3f} (>= 1.05)"
    diagnostics.update({"converged": converged, "rhat_max": rhat, "ess_min": ess, "note": note,
                        "seconds": time.perf_counter() - t0})
    import json

    idata.posterior.attrs["diagnostics"] = json.dumps(diagnostics)
    idata.posterior.attrs["converged"] = int(converged)
    cal = Calibration.from_idata(idata)
    if not converged:
        warnings.warn(
            f"calibration of {spec.name!r} on {test.name!r} has NOT converged: {note}. Run longer "
            f"(steps=None runs to convergence) before trusting the intervals.",
            ConvergenceWarning, stacklevel=2,
        )
    return cal
