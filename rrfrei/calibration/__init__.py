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
  prior (not identifiable); it becomes identifiable only when the test shows stiffening.  When it
  shows a hardening term with ``mu`` near 1, ``sgn(u)|u|^mu`` is close to ``u`` and the posterior
  has a thin tail toward mu -> 1 in which ``alpha1 k_init`` and ``alpha2 k_init`` grow and cancel
  (the CLT record SPC1: k_init above 10,000 kN/m in 3 of 480 draws, 95 % interval 3,070-4,520
  kN/m); the sampling coordinates of :mod:`.reparam` (``1 / (mu - 1)``) let the chain reach it.
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

from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.calibration.checks import predict
from rrfrei.calibration.compare import compare, elpd_loco  # the function shadows the module name
from rrfrei.calibration.likelihood import HALF_CYCLE_POINTS, Problem
from rrfrei.calibration.likelihood import likelihood_points as _lik_points
from rrfrei.calibration.likelihood import path_points as _path_points
from rrfrei.calibration.noise import NoiseModel, noise_model
from rrfrei.calibration.priors import resolve_priors
from rrfrei.calibration.results import (
    Calibration,
    build_idata,
    loglik_pointwise,
    posterior_draws,
    summary_table,
)
from rrfrei.calibration.sampler import (
    CONVERGENCE_RULE,
    MAX_STEPS,
    check_checkpoint,
    ensemble_size,
    find_map,
    load_optimum,
    polish_map,
    run_chain,
    save_optimum,
)
from rrfrei.io import ShearTest, read_test
from rrfrei.laws import LawSpec, get

__all__ = [
    "Calibration",
    "BoundWarning",
    "CONVERGENCE_RULE",
    "ConvergenceWarning",
    "PATH_TOLERANCE",
    "advice",
    "path_error",
    "run_stats",
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


class BoundWarning(UserWarning):
    """Sampled parameters sit at a bound of their admissible range at the MAP."""


def setup_problem(test: ShearTest, law: str | LawSpec, *, priors=None,
                  noise: str | NoiseModel = "iid", fixed: Mapping[str, float] | None = None,
                  likelihood_points: int | str | None = "auto",
                  half_cycle_points: int | str | None = "all") -> Problem:
    """The :class:`Problem` (free/fixed split, priors, likelihood samples, the law's input path)
    that :func:`calibrate` samples; ``likelihood_points`` as in
    :func:`.likelihood.likelihood_points`, ``half_cycle_points`` as in
    :func:`.likelihood.path_points` (default here ``"all"``: the law runs along every sample;
    :func:`calibrate` defaults to ``"auto"``).  A law with rate-dependent terms on a test with a
    time column always runs along every sample (decimation would change its velocities).

    ``law`` and ``noise`` may be names or the resolved :class:`~rrfrei.laws.LawSpec` and
    :class:`~.noise.NoiseModel` (used as they are: a caller that resolved them passes them down).
    """
    spec = get(law)
    noise = noise_model(noise)
    override_names = {str(k) for k in priors} if isinstance(priors, Mapping) else set()
    free, all_fixed = spec.resolve_fixed(
        test.geometry, fixed, frozenset(override_names),
        source=str(test.source or "the test file"),
    )
    pri = resolve_priors(spec, free, np.asarray(test.force), np.asarray(test.disp), noise, priors)
    points = "auto" if likelihood_points is None else likelihood_points
    idx = _lik_points(int(np.asarray(test.disp).size), points)
    if spec.uses_velocity and test.has_time:
        _path_points(np.asarray(test.disp), half_cycle_points)  # validates the option
        path = None
    else:
        path = _path_points(np.asarray(test.disp), half_cycle_points, keep=idx)
    return Problem(spec, test, free, all_fixed, noise, dict(pri), lik_idx=idx, path_idx=path)


PATH_TOLERANCE = 0.1
"""Largest RMS difference, in units of the noise sd sigma, between the model force along the
decimated input path and along the whole record at the likelihood's samples at the optimum;
above it :func:`calibrate` doubles ``half_cycle_points`` (and polishes the optimum again)."""


def path_error(problem: Problem, theta: np.ndarray) -> dict:
    """Model force along ``problem``'s (decimated) input path against the whole record, at the
    likelihood's samples, for one parameter row ``theta``: ``{"rms_kN", "max_kN", "rms_sigma"}``
    (RMS and largest |difference| [kN], the RMS over the noise sd sigma of ``theta``); zeros when
    the law runs along every sample, nan when either run fails."""
    theta = np.asarray(theta, dtype=float)
    if not problem.decimated:
        return {"rms_kN": 0.0, "max_kN": 0.0, "rms_sigma": 0.0}
    P = problem.full_params(theta[None, :])
    Fp, sp = problem.forces(P)
    Ff, sf = problem.forces(P, problem.test)
    if sp[0] != 0 or sf[0] != 0:
        return {"rms_kN": math.nan, "max_kN": math.nan, "rms_sigma": math.nan}
    d = problem.at_points(Fp)[0] - Ff[0, problem.lik_idx]
    rms = float(np.sqrt(np.mean(d * d)))
    sigma = float(problem.noise_params(theta[None, :])[0][0])
    return {"rms_kN": rms, "max_kN": float(np.max(np.abs(d))),
            "rms_sigma": rms / sigma if sigma > 0 else math.inf}


def _fingerprint(problem: Problem, nw: int, seed: int) -> str:
    """Hash of what a checkpoint's chain depends on: data, law, sampled names, noise, priors,
    likelihood samples, ensemble size and seed."""
    import hashlib

    h = hashlib.sha256()
    for arr in (problem.test.disp, problem.test.force, problem.lik_idx, problem.path_idx):
        h.update(np.ascontiguousarray(arr).tobytes())
    h.update(repr((problem.spec.name, problem.names, problem.noise.name, nw, int(seed),
                   sorted(problem.fixed.items()),
                   sorted((k, p.kind, p.a, p.b) for k, p in problem.priors.items()))).encode())
    return h.hexdigest()[:16]


def run_stats(diagnostics: Mapping) -> str:
    """``tau ≈ 62 steps, R-hat 1.012, ESS 455`` from a calibration's diagnostics."""
    d = diagnostics
    taus = [v for v in dict(d.get("tau", {})).values() if v == v]
    tau = f"tau ≈ {max(taus):.0f} steps" if taus else "tau not estimable"
    return f"{tau}, R-hat {d.get('rhat_max', float('nan')):.3f}, ESS {d.get('ess_min', float('nan')):.0f}"


def _path_advice(d: Mapping, opt) -> str:
    """The decimation hint of :func:`advice`: only for a dense record whose law ran along every
    sample although it could have been decimated (``half_cycle_points="all"``)."""
    path = d.get("path") or {}
    if path.get("decimated", True) or d.get("points", 0) <= 5000 or not path.get("decimable", False):
        return ""
    return (f", or let the law run along a decimated path "
            f"({opt('half_cycle_points=', '--half-cycle-points')} auto)")


def advice(diagnostics: Mapping, *, cli: bool = False) -> str:
    """One sentence: why the chain stopped unconverged and what to do, matching what happened.

    ``cli`` names the command-line options (``--max-steps``) instead of the API's arguments.
    """
    d = diagnostics
    opt = (lambda api, flag: flag) if cli else (lambda api, flag: api)
    stats = run_stats(d)
    why = d.get("stopped_by")
    steps = int(d.get("steps", 0))
    if why == "time_budget":
        return (f"stopped by the time budget of {d.get('time_budget', float('nan')):.0f} s after "
                f"{steps} steps ({stats}); all {steps} steps are kept. Rerun with the same "
                f"{opt('checkpoint=', '--checkpoint')} to continue the chain, or raise "
                f"{opt('time_budget=', '--time-budget')}{_path_advice(d, opt)}")
    if why == "max_steps":
        extra = ("" if d.get("likelihood_stride", 1) > 1 or d.get("points", 0) <= 5000 else
                 f", or use fewer likelihood points ({opt('likelihood_points=', '--likelihood-points')})")
        extra += _path_advice(d, opt)
        return (f"stopped at the step cap of {int(d.get('max_steps', steps))} steps ({stats}): raise "
                f"{opt('max_steps=', '--max-steps')} (a rerun with the same "
                f"{opt('checkpoint=', '--checkpoint')} continues the chain){extra}")
    if why == "steps":
        return (f"the {steps} fixed steps were too few ({stats}): leave out "
                f"{opt('steps=', '--steps')} to run to convergence (up to "
                f"{opt('max_steps=', '--max-steps')}), or ask for more steps")
    return (f"{stats}: the convergence rule ({CONVERGENCE_RULE}) does not hold; run longer: ask "
            f"for more steps than the {steps} sampled ({opt('steps=', '--steps')} {2 * steps}; the "
            f"same {opt('checkpoint=', '--checkpoint')} continues the chain)")


def calibrate(
    test: ShearTest | str | Path,
    law: str | LawSpec,
    *,
    priors=None,
    noise: str | NoiseModel = "iid",
    walkers: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    checkpoint: str | Path | None = None,
    progress: bool = True,
    fixed: Mapping[str, float] | None = None,
    max_steps: int = MAX_STEPS,
    time_budget: float | TimeBudget | None = None,
    likelihood_points: int | str | None = "auto",
    checkpoint_mismatch: str = "error",
    half_cycle_points: int | str | None = "auto",
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
    steps : MCMC steps; None runs until the convergence rule of :mod:`.sampler` holds
        (:data:`CONVERGENCE_RULE`: bulk and tail ESS >= 400 and R-hat < 1.05 on the stored draws,
        from a chain >= 10 stable autocorrelation times long), up to ``max_steps``.
    seed : seed of the optimiser, the initial ball and the sampler.
    checkpoint : HDF5 file (emcee layout); an existing one is resumed (the optimum is not searched
        again and the chain continues from its last stored step).
    progress : show progress bars (tqdm, stderr; one at a time, removed when done).
    fixed : values for law parameters to hold fixed (geometry defaults come from ``test.geometry``).
    max_steps : step cap of a run to convergence (``steps=None``), default 20,000.
    time_budget : wall-clock limit [s] of the optimum search plus the sampling (None: no limit),
        or a :class:`~rrfrei.budget.TimeBudget` already running.  When it runs out, sampling
        stops, the chain so far is kept (and checkpointed) and returned with
        ``cal.stopped_by == "time_budget"``; a rerun with the same ``checkpoint`` continues it.
        If it runs out before any step was sampled, :class:`~rrfrei.budget.BudgetExceeded` is
        raised (the optimum, once found, is saved in the checkpoint).
    likelihood_points : samples the likelihood uses: ``"auto"`` (all up to 5,000 samples, else a
        regular subsample of at most 2,000), ``"all"`` or an integer; the law always runs along the
        whole history (see :mod:`.likelihood`).  Reported in ``diagnostics``.
    checkpoint_mismatch : ``"error"`` (default): a checkpoint made for other data, law, priors,
        noise, likelihood points or walkers is a ValueError; ``"restart"``: it is overwritten.
    half_cycle_points : decimation of the law's input path (:func:`.likelihood.path_points`):
        ``"auto"`` (default): on a dense record (more than 5,000 samples) the law runs along every
        k-th sample of each half-cycle, k chosen so that every half-cycle keeps >= 100 samples,
        plus the reversals and the likelihood's samples; ``"all"``: along every sample; an integer
        N: >= N samples per half-cycle.  At the optimum the model force along the decimated path
        is compared with the whole record's at the likelihood's samples; while the RMS difference
        exceeds :data:`PATH_TOLERANCE` sigma, N is doubled (the optimum polished again).  The
        final N, the path's samples and the difference are in ``diagnostics`` (``"path"``).
        Laws with rate-dependent terms on a test with a time column are never decimated.

    Returns
    -------
    Calibration
        ``cal.stopped_by`` is ``"converged"``, ``"steps"`` (the fixed steps were run),
        ``"max_steps"`` or ``"time_budget"``; ``cal.diagnostics`` holds the numbers.

    Warns
    -----
    ConvergenceWarning
        the chain did not meet the convergence rule (:data:`CONVERGENCE_RULE`, the same check that
        stops a run); the message says why it stopped and what to do (:func:`advice`).
    BoundWarning
        sampled parameters sit at (within 1 % of the range from) a bound of their admissible
        range at the MAP (:func:`.quality.at_bounds`); also in ``diagnostics["at_bounds"]``.
    """
    import json
    import time

    t0 = time.perf_counter()
    budget = TimeBudget.of(time_budget, "calibrate")
    if isinstance(test, (str, Path)):
        test = read_test(test)
    if not isinstance(test, ShearTest):
        raise ValueError(f"test must be a ShearTest or a CSV path, got {type(test).__name__}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 2:
        raise ValueError(f"max_steps = {max_steps!r}: expected an integer >= 2")
    if checkpoint_mismatch not in ("error", "restart"):
        raise ValueError(f"checkpoint_mismatch = {checkpoint_mismatch!r}: expected 'error' or 'restart'")
    if checkpoint is not None:
        check_checkpoint(checkpoint)
    spec = get(law)  # the law and the noise model are resolved here, once, and passed down
    problem = setup_problem(test, spec, priors=priors, noise=noise_model(noise), fixed=fixed,
                            likelihood_points=likelihood_points, half_cycle_points=half_cycle_points)
    hcp = half_cycle_points
    if problem.decimated and not isinstance(hcp, (int, np.integer)):
        hcp = HALF_CYCLE_POINTS

    def refined(n_half: int | str) -> Problem:
        return setup_problem(test, spec, priors=priors, noise=problem.noise, fixed=fixed,
                             likelihood_points=likelihood_points, half_cycle_points=n_half)

    if spec.uses_velocity and not test.has_time:
        warnings.warn(
            f"test {test.name!r} has no time column: law {spec.name!r} has rate-dependent terms, "
            "which are evaluated quasi-statically (velocity 0); rate effects cannot be judged",
            UserWarning, stacklevel=2,
        )
    nw = ensemble_size(walkers, problem.ndim)  # the one rule (run_chain applies the same)
    if steps is not None and (not isinstance(steps, (int, np.integer)) or steps < 2):
        raise ValueError(f"steps must be an integer >= 2 or None (run to convergence), got {steps!r}")
    fingerprint = _fingerprint(problem, nw, seed)
    stored = load_optimum(checkpoint) if checkpoint is not None else None
    if stored is not None and (stored.get("fingerprint", fingerprint) != fingerprint
                               or stored.get("names") != list(problem.names)
                               or stored.get("law") != spec.name):
        if checkpoint_mismatch == "restart":
            Path(checkpoint).unlink()
            stored = None
        else:
            raise ValueError(
                f"checkpoint {checkpoint} belongs to another run (law {stored.get('law')!r}, parameters "
                f"{stored.get('names')}, or other data, priors, noise, walkers or likelihood points) "
                f"than this one ({spec.name!r} {list(problem.names)}); use another path"
            )
    refinements = 0
    if stored is not None:
        theta0 = np.asarray(stored["theta"], dtype=float)
        refinements = int(stored.get("refinements", 0))
        if problem.decimated and stored.get("half_cycle_points", hcp) != hcp:  # refined before
            kept = stored["half_cycle_points"]  # None: refined up to every sample
            problem = refined("all" if kept is None else int(kept))
            hcp = hcp if kept is None else int(kept)
        perr = path_error(problem, theta0)
    else:
        try:
            theta0, _ = find_map(problem, seed, budget=budget, progress=progress)
            perr = path_error(problem, theta0)
            while problem.decimated and not perr["rms_sigma"] <= PATH_TOLERANCE:
                hcp, refinements = 2 * int(hcp), refinements + 1
                problem = refined(int(hcp))
                theta0, _ = polish_map(problem, theta0, budget=budget, progress=progress)
                perr = path_error(problem, theta0)
        except BudgetExceeded:
            raise BudgetExceeded(budget.message(
                "it ran out during the search for the optimum, nothing was sampled")) from None
        if checkpoint is not None:
            Path(checkpoint).parent.mkdir(parents=True, exist_ok=True)
            save_optimum(checkpoint, {"law": spec.name, "names": list(problem.names),
                                      "theta": [float(x) for x in theta0], "fingerprint": fingerprint,
                                      "half_cycle_points": None if not problem.decimated else int(hcp),
                                      "refinements": refinements})
    t_opt = time.perf_counter() - t0
    from rrfrei.calibration.results import draws_cap

    cap = draws_cap(problem.n_like, problem.subsampled, nw)
    res = run_chain(problem, theta0, walkers=walkers, steps=steps, seed=seed, checkpoint=checkpoint,
                    progress=progress, max_steps=max_steps, budget=budget, max_draws=cap)
    chain, logp = res.chain, res.log_prob
    n_steps, nw, _ = chain.shape
    if n_steps < 4:
        kept = "the optimum is saved in the checkpoint" if checkpoint is not None else "nothing kept"
        raise BudgetExceeded(budget.message(
            f"it ran out after the optimum search with {n_steps} MCMC steps, too few for a "
            f"posterior ({kept})"))
    burn, thin = res.burn, res.thin  # the draws the convergence rule checked
    # MAP: the best of the optimum and every sample
    lp0 = float(problem.log_prob(theta0[None, :])[0])
    j = np.unravel_index(int(np.argmax(logp)), logp.shape)
    theta_map = chain[j] if logp[j] > lp0 else theta0
    diagnostics = {
        "acceptance": res.acceptance, "tau": {n: float(t) for n, t in zip(problem.names, res.tau)},
        "steps": int(n_steps), "walkers": int(nw), "burn": int(burn), "thin": int(thin),
        "evaluations": int(res.evals), "seconds_sampling": res.seconds, "seconds_optimum": t_opt,
        "note": res.tau_note, "converged": False, "stopped_by": res.stopped_by,
        "max_steps": int(max_steps), "time_budget": budget.seconds,
        "resumed_steps": int(res.resumed_steps), "points": problem.n_points,
        "restarted_walkers": int(res.restarted),
        "sampling_coordinates": res.coordinates,
        "path": {"decimated": bool(problem.decimated), "samples": problem.n_path,
                 "decimable": not (spec.uses_velocity and test.has_time),
                 "half_cycle_points": int(hcp) if problem.decimated else None,
                 "refinements": refinements, "tolerance_sigma": PATH_TOLERANCE,
                 **{f"error_{k}": v for k, v in perr.items()}},
        "likelihood_points": problem.n_like,
        "likelihood_stride": int(problem.lik_idx[1] - problem.lik_idx[0]) if problem.n_like > 1 else 1,
        "ess_bulk": res.ess_bulk, "ess_tail": res.ess_tail, "rhat": res.rhat,
        "rule": CONVERGENCE_RULE,
        "stored_draws": int(((n_steps - burn + thin - 1) // thin) * nw), "max_draws": int(cap),
    }
    idata = build_idata(problem, chain, logp, burn=burn, thin=thin, theta_map=theta_map,
                        fixed=problem.fixed, diagnostics=diagnostics, seed=seed)
    summary = summary_table(idata, spec, dict(zip(problem.names, map(float, theta_map))),
                            problem.free, problem.noise)
    # the summary's arviz R-hat and bulk ESS are the rule's numbers on the same stored draws
    rhat = float(summary["R-hat"].max())
    ess = float(summary["ESS"].min())
    converged = bool(res.converged)  # the rule that stopped the run: one check, not two
    note = res.tau_note
    from rrfrei.calibration.quality import at_bounds, bounds_text

    hits = at_bounds(spec, problem.priors, problem.free,
                     [float(theta_map[problem.names.index(n)]) for n in problem.free],
                     problem.lower, problem.upper)
    diagnostics.update({"converged": converged, "rhat_max": rhat, "ess_min": ess, "note": note,
                        "ess_tail_min": float(res.ess_tail), "at_bounds": hits,
                        "seconds": time.perf_counter() - t0})
    idata.posterior.attrs["diagnostics"] = json.dumps(diagnostics)
    idata.posterior.attrs["converged"] = int(converged)
    cal = Calibration.from_idata(idata, spec=spec, summary=summary)
    if not converged:
        warnings.warn(
            f"calibration of {spec.name!r} on {test.name!r} has NOT converged: {advice(diagnostics)}"
            f" ({note}). Do not trust the intervals yet.",
            ConvergenceWarning, stacklevel=2,
        )
    elif res.stopped_by == "time_budget":
        warnings.warn(budget.message(f"the chain of {n_steps} steps had already converged"),
                      UserWarning, stacklevel=2)
    if hits:
        warnings.warn(
            f"calibration of {spec.name!r} on {test.name!r}: {bounds_text(hits)} at the MAP: the "
            "best fit lies at an edge of what the law (or its prior) allows; the law may not "
            "suit this test, or a prior is too narrow", BoundWarning, stacklevel=2)
    return cal
