"""Which effect closes the gap: screen, refit, rank, combine (issue 7).

Engine (:func:`diagnose`, generic over :class:`rrfrei.gap.model.GapModel`):

1. fit the baseline on the calibration data; residual segment table ("where") and the signature
   screen of every catalogue effect;
2. refit every effect's augmented model (optimum, then the Laplace posterior) and score it over
   *blocks* (half-cycles, or time windows without two full cycles,
   :func:`rrfrei.gap.decision.blocks`): the leave-one-block-out elpd difference on the
   calibration data (PSIS on block-summed log-likelihoods, Vehtari, Gelman & Gabry 2017,
   ``arviz.psislw``) and, with held-out data, the reduction of each held-out block's squared
   error and the pooled held-out systematic-gap shrink with its block-bootstrap interval.  The
   old summaries (elpd and held-out lpd differences with their paired se over cycles) are kept
   for display.  Once every effect has its fit, each effect's variants
   (:class:`rrfrei.laws.effects.Variant`: a shape parameter more) are fitted; a variant stands
   for its effect when it beats the primary fit by the block rank test on the held-out blocks
   (the calibration blocks without held-out data), so a wider shape is taken when the data ask
   for it, not because it bends further (:func:`_variant_or_primary`);
3. an effect is *significant* by the block rule of :mod:`rrfrei.gap.decision`: sign or
   Wilcoxon signed-rank test over the calibration blocks (and > 4 nats in total) and, with
   held-out data, over the held-out blocks, with the bootstrap lower bound of the held-out shrink
   above 10 % (an effect that wins on the calibration test and does not close the held-out gap is
   rejected); without held-out data the bootstrap bound of the calibration test's own shrink
   must lie above 10 %.  Rank tests do not lose power when a few blocks gain enormously, the failure of the
   former "gain > 2 paired se" rule (issue 12).  The diagnosis is the significant effect with the
   largest held-out lpd gain (calibration gain without held-out data), or ``none``; with
   held-out data, a significant effect with fewer fitted parameters that no higher-ranked one
   predicts better on the held-out blocks by more than one standard error is named instead
   (parsimony, the one-standard-error rule, :func:`rrfrei.gap.scoring._parsimonious`);
4. confounding guard: a protocol whose amplitude only grows moves amplitude, dissipated energy
   and time together, so on the calibration test alone degradation, scragging, rollover and slip
   can stand in for one another.  Every refit starts from the baseline optimum and from the
   baseline fitted to the first half of the test only (before late effects set in).
   Without held-out data on such a protocol the winner must also
   beat every other significant effect in a leave-one-block-out comparison by the same block
   test; else the diagnosis is ``none`` and the report names the tied effects.  With held-out
   data, the effects the held-out blocks cannot tell from the named one are its *alternatives*
   (:func:`_alternatives`): their refits pass the rule's rank tests and the paired block
   bootstrap does not show them to leave more of the baseline's held-out gap than the named
   effect, so the report says the data support them as well (two velocity-dependent forces, say)
   instead of silently naming the one a rounding put first;
5. greedy combination: add the best further effect (refit from the current combination) while
   it stays significant against the current combination by the same rule.  The effects tried are
   the significant ones; for a model whose effects act on each other's evidence
   (:attr:`rrfrei.gap.model.GapModel.interacting_effects`: a building fitted by output error, where
   a missing damping puts the simulated motion out of phase and so hides what a stiffness effect
   would close) also every effect whose refit passes the rule's rank tests (the calibration gain
   and blocks, and the held-out blocks) and misses only its shrink bound: its gains are
   consistent but alone too small, as an effect's are when a missing partner masks them.  For
   such a model an effect with a variant that changes what is simulated (a history effect of the
   building, carried from run to run or recovering between runs) is tried in every form at each
   step, whatever its gains alone (:func:`_forms`): which form stood for it was read against the
   baseline, whose missing effects distort that reading as they distort the gain.  And such a
   model's named effect is also fitted from scratch (the baseline's search): when that fits the
   calibration data better than the refit, which started in the basin of a baseline the missing
   effect had shaped, it stands for the effect's building and the combination starts from it
   (:func:`_from_scratch`; the effect stays named on its refit's evidence);
6. verdict (``GapReport.verdict``, ``GapReport.evidence``): the named effect (evidence: its block
   tests, shrink interval, and what is left after it); else ``"none"`` when what is left of the
   baseline is noise on the calibration and the held-out data (systematic part within the noise or
   below 1 % NRMSE, :class:`rrfrei.gap.decision.Residual`; evidence: the reasons, with the
   residuals' lag-1 autocorrelation); else ``"unexplained"`` (evidence: the top three segments of
   ``where``, the systematic gap's size, the closest candidate with its shrink and why it was
   rejected, tied effects); ``"incomplete"`` when effects were not evaluated.  Evidence keys:
   ``rule``, ``baseline``, ``tied``, ``alternatives``, ``closest``, and ``named``/``left``/``left_is_noise``,
   ``reasons``/``systematic_on``, ``where``/``size``, ``not_evaluated`` by verdict.

Robustness, time and restarts (issue 16.4):

* a numerical failure (:data:`rrfrei.errors.NUMERICAL_ERRORS`) in one effect's refit or scoring
  skips that effect (``GapReport.skipped``: effect -> what failed where) and the diagnosis goes
  on; inside an optimiser a failing evaluation is a bad point, never an exception.  Only a
  failure of the baseline fit ends it, with a :class:`~rrfrei.errors.NumericalFailure` naming
  the step;
* ``time_budget``: effects not started when it runs out (or whose refit it interrupts) are listed
  in ``GapReport.not_evaluated``; the diagnosis is then marked incomplete, and a verdict of no
  effect becomes ``"incomplete"`` (an untried effect might have closed the gap);
* ``checkpoint``: a folder where every finished fit (baseline, early-cycle start, each refit,
  each combination step) is saved as ``.npz``, keyed by a SHA-256 of the test data, the model
  settings, the seed and the step, so that a rerun reuses them (the scores are recomputed).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from rrfrei.blas import one_blas_thread
from rrfrei.budget import BudgetExceeded, TimeBudget
from rrfrei.budget import progress as progress_bar
from rrfrei.errors import NUMERICAL_ERRORS, NumericalFailure
from rrfrei.forkmap import sharing
from rrfrei.gap import decision as dec
from rrfrei.gap.catalogue import ScreenContext, catalogue, screen_all
from rrfrei.gap.checkpoint import Checkpoint, _Checkpoint, _fit_or_restore, effect_step
from rrfrei.gap.isolator import IsolatorModel
from rrfrei.gap.model import FitResult, GapModel, velocity
from rrfrei.gap.parallel import SharedRefits
from rrfrei.gap.residuals import cycle_levels, segment_table
from rrfrei.gap.results import GapReport
from rrfrei.gap.scoring import (
    EffectScore,
    Metrics,
    _beats,
    _gain,
    _parsimonious,
    _score,
    _Scorer,
    loco,
)
from rrfrei.gap.verdict import VERDICTS, _verdict
from rrfrei.io import ShearTest, read_test
from rrfrei.notes import SEVERITIES, Note, ordered

__all__ = ["EffectScore", "Metrics", "GapReport", "diagnose", "diagnose_gap", "CONFOUNDED", "Checkpoint",
           "loco", "VERDICTS"]

CONFOUNDED = ("degradation", "mullins", "rollover", "slip")
"""Effects that a growing-amplitude protocol cannot tell apart on its own."""
MIN_GAIN = dec.MIN_GAIN
VARIANT_TRACE = 0.05
"""Least systematic-gap shrink of an effect's primary fit for its variants to be tried."""


def _variant_names(model: GapModel, sc: _Scorer, score: EffectScore) -> tuple[str, ...]:
    """The variants of ``score``'s effect that :func:`_variant_or_primary` tries (its docstring)."""
    names = model.variants(score.effect)
    trace = score.shrink_holdout if sc.holdout else score.shrink_calibration
    if not score.significant and math.isfinite(trace) and trace < VARIANT_TRACE:
        # a wider shape of a kernel that closes nothing is not tried; a variant that changes
        # what the model simulates (the building's runs from the virgin state) still is
        names = tuple(v for v in names if not model.shape_variant(score.effect, v))
    return names


def _variant_or_primary(model: GapModel, sc: _Scorer, effect: str, fit: FitResult, score: EffectScore,
                        budget: TimeBudget, base: FitResult, screen: float, bm, notes: list[str],
                        shared: SharedRefits, workers: int) -> tuple[FitResult, EffectScore]:
    """The fit that stands for ``effect``: the primary one, or a variant of the effect
    (:class:`rrfrei.laws.effects.Variant`) that beats it by the block rule of
    :mod:`rrfrei.gap.decision` (the rank test of the per-block squared-error reductions over the
    held-out blocks; without held-out data, of the leave-one-block-out elpd gains on the
    calibration test), the best such variant when several do (largest held-out lpd gain, or
    calibration elpd gain).  The wider shape is taken when the data ask for it, not because it
    bends further: a variant that fits the calibration test as well and extrapolates worse stays
    out.  A variant whose fit or scoring fails, or that the time budget stops, is left out with
    a note (the primary fit stands).

    Shape variants are tried only for an effect whose primary fit finds a trace of it: a systematic-gap
    shrink of at least ``VARIANT_TRACE`` (held out, or on the calibration test without held-out
    data), or a pass of the decision rule.  An effect whose own kernel closes nothing is not
    refitted in a wider shape (on the 8,257-point timber test this saves the smooth rollover's
    fit, whose primary closes 0.6 %: 2 min 56 s -> 2 min 23 s; the validation table gave the same
    310 verdicts, variants and shrinks with and without the rule, at 3.1 against 4.1 s of CPU per
    case).  A variant that changes what the model simulates rather than the kernel's shape
    (:meth:`rrfrei.gap.model.GapModel.shape_variant` false: the building's runs each from the
    virgin state) is tried whatever the primary fit's trace: the primary fit's failure is what it
    may explain.  ``shared``: where the variants' fits are made (:meth:`SharedRefits.fit`: here, or
    by a second process)."""
    names = _variant_names(model, sc, score)
    if not names:
        return fit, score
    best_fit, best = fit, score
    for v in names:
        if budget.expired():
            notes.append(f"variant {v!r} of {effect} not tried: time budget")
            break
        step = f"refit of {model.name}+{effect} ({v})"
        try:
            vfit = shared.fit(f"{effect_step(effect)}:{v}", model.augment([effect], variants={effect: v}),
                              workers)
            step = f"scoring of {vfit.name} ({v})"
            if not _beats(sc, vfit, fit):
                continue
            vscore = replace(_score(sc, effect, vfit, base, screen, bm), variant=v)
        except BudgetExceeded:
            notes.append(f"variant {v!r} of {effect} not tried: time budget")
            break
        except NUMERICAL_ERRORS as exc:
            notes.append(f"variant {v!r} of {effect} left out: {_failure(step, exc)}")
            continue
        if best is score or _gain(sc, vscore) > _gain(sc, best):
            best_fit, best = vfit, vscore
    if best is not score:
        notes.append(f"{effect} fitted as its variant {best.variant!r}: it beats the primary fit on the "
                     f"{'held-out' if sc.holdout else 'calibration'} blocks")
    return best_fit, best



def _monotone_amplitude(data) -> bool:
    if not hasattr(data, "disp"):
        return False
    seg = cycle_levels(data.disp)
    levels = [int(x) for x in seg.level[seg.cycle >= 0]]
    return len(set(levels)) > 1 and all(b >= a for a, b in zip(levels, levels[1:]))


def _screen_context(model: GapModel, data, fit: FitResult) -> ScreenContext | None:
    if not isinstance(data, ShearTest):
        return None
    from rrfrei.energy import dissipated_energy

    pr = fit.predict(data)
    seg = cycle_levels(data.disp)
    return ScreenContext(disp=np.asarray(data.disp), vel=velocity(data), force_pred=pr.mean,
                         resid=np.asarray(data.force) - pr.mean,
                         energy=dissipated_energy(data.disp, data.force), first_cycle=seg.first,
                         has_time=bool(data.has_time))



def _failure(step: str, exc: BaseException) -> str:
    return f"{step}: {type(exc).__name__}: {exc}"


def diagnose(model: GapModel, data, holdout: Sequence = (), *, effects: Sequence[str] | None = None,
             seed: int = 0, combine: bool = True, max_combination: int = 3, progress: bool = False,
             time_budget: float | TimeBudget | None = None, checkpoint: str | os.PathLike | None = None,
             workers: int = 1) -> GapReport:
    """Diagnose the gap of ``model`` on ``data`` (see the module docstring).

    Parameters
    ----------
    model : the baseline model (a :class:`GapModel`).
    data : calibration data; ``holdout`` : held-out data sets (the stronger evidence).
    effects : catalogue effects to try (default all).
    seed : seed of every fit and posterior draw.
    combine : add further effects greedily after the first.
    max_combination : most effects in the final combination.
    progress : a tqdm bar on stderr over the steps (baseline, each effect's refit and scoring,
        combination steps) with its remaining-time estimate.
    time_budget : wall-clock limit [s] (``None``: no limit) or a :class:`rrfrei.budget.TimeBudget`;
        when it runs out the diagnosis ends with what it has (see :class:`GapReport`).
    checkpoint : folder for finished fits (``None``: none); a rerun with the same folder, data,
        model and seed reuses them.
    workers : processes for the candidates' refits (:class:`rrfrei.gap.parallel.SharedRefits`;
        needs ``checkpoint``); the report is the same for any number.

    Returns
    -------
    GapReport
        ``complete`` is False when an effect was skipped (numerical failure) or not evaluated
        (time budget); if no evaluated effect is significant the diagnosis is then
        ``"incomplete"``, never ``"none"``.  ``verdict`` and ``evidence``: step 6 of the module
        docstring.

    Raises
    ------
    NumericalFailure
        the baseline cannot be fitted or scored (the message names the step and the failure).
    BudgetExceeded
        the time budget ran out before the baseline fit finished (nothing to diagnose).
    """
    with one_blas_thread():
        return _diagnose(model, data, holdout, effects=effects, seed=seed, combine=combine,
                         max_combination=max_combination, progress=progress, time_budget=time_budget,
                         checkpoint=checkpoint, workers=workers)


def _too_few_blocks(sc: _Scorer) -> str:
    """The note saying that the block rule cannot name any effect because the calibration data or
    the held-out data give fewer blocks than its rank tests need (:func:`rrfrei.gap.decision.min_blocks`);
    "" when both give enough."""
    need = dec.min_blocks()
    n_cal = int(np.unique(sc.g_cal).size)
    n_ho = sum(int(np.unique(g).size) for g in sc.g_ho)
    short = [f"the calibration data give {n_cal}"] if n_cal < need else []
    if sc.holdout and n_ho < need:
        short.append(f"the held-out data give {n_ho}")
    if not short:
        return ""
    return (f"no effect can be named: {' and '.join(short)} blocks, and the block rule's rank tests "
            f"need at least {need} (every block gaining gives p = 2^-blocks, against p < {dec.ALPHA / 2:g}); "
            "a verdict of none or unexplained here does not mean that no effect closes the gap: give "
            "longer or more runs")


def _weak_calibration(sc: _Scorer) -> str:
    """The note saying that the calibration data give too few blocks for the rank test to weigh an
    effect (:func:`rrfrei.gap.decision.underpowered`), so that the held-out blocks decide; "" when
    they give enough, or there are no held-out data, or too few for any test (:func:`_too_few_blocks`)."""
    n_cal = int(np.unique(sc.g_cal).size)
    if not sc.holdout or n_cal < dec.min_blocks() or not dec.underpowered(n_cal):
        return ""
    return (f"the calibration data give {n_cal} blocks, too few for the block rule's rank test to weigh an "
            f"effect (it passes only when {dec.needed_gains(n_cal)} of {n_cal} gain): an effect whose "
            f"calibration gain totals more than {dec.MIN_GAIN:g} nats with a majority of its blocks "
            "gaining is judged on the held-out blocks; longer or more calibration runs make the "
            "calibration evidence count")


def _diagnose(model: GapModel, data, holdout: Sequence, *, effects, seed, combine, max_combination,
              progress, time_budget, checkpoint, workers=1) -> GapReport:
    # a model may offer candidates of its own besides the catalogue's (the building's system effects)
    known = list(getattr(model, "candidate_effects", None) or catalogue())
    effects = list(known) if effects is None else list(effects)
    for e in effects:
        if e not in known:
            raise ValueError(f"unknown effect {e!r}; available: {', '.join(known)}")
    budget = TimeBudget.of(time_budget, "gap diagnosis")
    ck = _Checkpoint(checkpoint, model, data, seed)
    name = getattr(data, "name", "data")
    notes: list[str] = []
    skipped: dict[str, str] = {}
    untried: dict[str, str] = {}
    sc = _Scorer(model, data, holdout, seed)
    few = _too_few_blocks(sc)
    if few and effects:
        notes.append(Note(few, "critical"))
    weak = _weak_calibration(sc)
    if weak and effects:
        notes.append(Note(weak, "warning"))
    bar = progress_bar(1 + len(effects), f"gap {model.name}", enabled=progress, unit="step")
    # one fit at a time may spread its evaluations over the processes; while a second process
    # fits candidates of its own, each fit keeps to one (rrfrei.forkmap)
    with bar, sharing(workers):
        bar.set_postfix_str("baseline")
        try:
            base = _fit_or_restore(ck, "baseline", model, data, budget, seed=seed)
        except BudgetExceeded:
            raise BudgetExceeded(budget.message(f"the baseline fit of {model.name!r} on {name!r} did not "
                                                "finish: nothing to diagnose")) from None
        except NUMERICAL_ERRORS as exc:
            raise NumericalFailure(f"gap diagnosis: baseline fit of {model.name!r} on {name!r} failed: "
                                   f"{type(exc).__name__}: {exc}") from exc
        try:
            sc.set_noise(base)
            bm = (sc.metrics(base, [data]), sc.metrics(base, sc.holdout))
            pr = base.predict(data)
        except NUMERICAL_ERRORS as exc:
            raise NumericalFailure(f"gap diagnosis: scoring the baseline {model.name!r} on {name!r} failed: "
                                   f"{type(exc).__name__}: {exc}") from exc
        where = pd.DataFrame()
        if isinstance(data, ShearTest):
            try:
                where = segment_table(data, pr.mean, pr.lower, pr.upper, sc.noise[id(data)])
            except NUMERICAL_ERRORS as exc:
                notes.append(Note(f"residual segment table skipped: {_failure('segment_table', exc)}",
                                  "warning"))
        ctx = _screen_context(model, data, base)
        screens = screen_all(ctx) if ctx is not None else {e: float("nan") for e in known}
        bar.update()
        fits: dict[str, FitResult] = {base.name: base}
        starts: list[FitResult] | None = None
        scores: list[EffectScore] = []
        shared = None
        for e in effects:
            why = model.cannot_judge(e, data)
            if why:
                notes.append(why)
                bar.update()
                continue
            if budget.expired():
                untried[e] = "time budget"
                bar.update()
                continue
            bar.set_postfix_str(f"refit +{e}")
            step = f"refit of {model.name}+{e}"
            try:
                if starts is None:
                    starts = [base]
                    early = model.early(data) if hasattr(model, "early") else None
                    if early is not None:
                        try:  # the baseline on the small early cycles: a start untouched by late effects
                            starts.append(_fit_or_restore(ck, "early", model, early, budget, seed=seed,
                                                          start=base))
                        except BudgetExceeded:
                            starts = None
                            raise
                        except ValueError as exc:  # NumericalFailure, LinAlgError are ValueErrors
                            notes.append(f"early-cycle start of the refits skipped: "
                                         f"{_failure('baseline fit on the first half', exc)}")
                    rest = effects[effects.index(e):]
                    shared = SharedRefits(ck, [(effect_step(r), model.augment([r])) for r in rest
                                               if not model.cannot_judge(r, data)],
                                          data, starts, seed, budget, workers)
                fit = shared.fit(effect_step(e), model.augment([e]), workers)
                bar.set_postfix_str(f"score +{e}")
                step = f"scoring of {fit.name}"
                score = _score(sc, e, fit, base, screens.get(e, float("nan")), bm)
            except BudgetExceeded:
                untried[e] = "time budget"
            except NUMERICAL_ERRORS as exc:
                skipped[e] = _failure(step, exc)
            else:
                fits[fit.name] = fit
                scores.append(score)
            bar.update()
        if shared is not None:
            if shared.helped:
                notes.append(f"{len(shared.helped)} of the candidates' refits ran in a second process")
            shared.close()
        # the variants once every effect has its primary fit, so that a time budget spent on them
        # never leaves an effect unevaluated; their fits are independent, so a second process
        # makes them from the end of the list
        vjobs = [(f"{effect_step(s.effect)}:{v}", model.augment([s.effect], variants={s.effect: v}))
                 for s in scores for v in _variant_names(model, sc, s)]
        vshared = SharedRefits(ck, vjobs, data, starts, seed, budget, workers)
        try:
            for i, score in enumerate(scores):
                if not model.variants(score.effect):
                    continue
                bar.set_postfix_str(f"variants of {score.effect}")
                fit, scores[i] = _variant_or_primary(model, sc, score.effect, fits[score.law], score,
                                                     budget, base, screens.get(score.effect, float("nan")),
                                                     bm, notes, vshared, workers)
                fits[fit.name] = fit
        finally:
            if vshared.helped:
                notes.append(f"{len(vshared.helped)} of the variants' fits ran in a second process")
            vshared.close()
        chosen = {s.effect: s.variant for s in scores if s.variant}  # effect -> the variant standing for it
        ranking = tuple(sorted(scores, key=lambda s: -_gain(sc, s) if math.isfinite(_gain(sc, s))
                               else math.inf))
        sig = [s for s in ranking if s.significant]
        diagnosis, tied = _name(sc, fits, sig, data, notes)
        combination: list[str] = []
        steps: list[EffectScore] = []
        alternatives: list = []
        final, current, stopped = bm, base, False
        if diagnosis != "none":
            first = next(s for s in ranking if s.effect == diagnosis)
            refit = fits.get(first.law)
            scratch = (_from_scratch(model, sc, ck, data, budget, seed, first, fits, notes)
                       if model.interacting_effects else None)
            combination, steps, final, current, stopped = _combine(
                model, sc, ck, data, budget, seed, bar, notes, first=first, sig=sig, chosen=chosen, fits=fits,
                screens=screens, combine=combine, max_combination=max_combination, ranking=ranking,
                workers=workers, scratch=scratch)
            # the alternatives weigh the evidence the effect was named on: its refit's
            alternatives = _alternatives(sc, {**fits, first.law: refit}, ranking, first, base, combination)
    diagnosis, missing, budget_message = _closing_notes(diagnosis, effects, skipped, untried, stopped,
                                                        ranking, budget, fits, ck, notes)
    try:
        verdict, evidence = _verdict(sc, diagnosis, combination, base, current, ranking, steps, where,
                                     tied, missing, alternatives)
    except NUMERICAL_ERRORS as exc:  # the verdict's numbers come from fits already scored
        verdict, evidence = diagnosis, {"error": _failure("verdict", exc)}
    return GapReport(law=model.name, diagnosis=diagnosis, combination=tuple(combination), where=where,
                     screens=screens, ranking=ranking, steps=tuple(steps), baseline=bm, final=final,
                     notes=tuple(ordered(notes)), fits=fits, calibration_data=data,
                     holdout_data=tuple(holdout),
                     skipped=skipped, not_evaluated=untried, budget_message=budget_message,
                     elapsed=budget.elapsed, reused=tuple(ck.reused), verdict=verdict, evidence=evidence)


def _name(sc: _Scorer, fits: dict, sig: list[EffectScore], data, notes: list) -> tuple[str, list[str]]:
    """The effect to name among the significant ones ``sig`` (ranking order), and the effects tied
    with it: the parsimony rule with held-out data (step 3 of the module docstring) and the
    confounding guard without (step 4)."""
    diagnosis = "none"
    tied: list[str] = []
    if sig:
        diagnosis = sig[0].effect
        if sc.holdout:
            diagnosis, why = _parsimonious(sc, fits, sig)
            if why:
                notes.append(why)
        if not sc.holdout and _monotone_amplitude(data):
            win = fits[sig[0].law]
            for other in sig[1:]:
                if other.effect in CONFOUNDED or diagnosis in CONFOUNDED:
                    if not _beats(sc, win, fits[other.law]):
                        tied.append(other.effect)
            if tied:
                notes.append(Note(
                    f"the calibration protocol's amplitude only grows, so {diagnosis} cannot be told "
                    f"apart from {', '.join(tied)} on it alone: give held-out tests (--holdout)",
                    "critical"))
                tied.insert(0, diagnosis)
                diagnosis = "none"
    return diagnosis, tied


def _consistent(s: EffectScore) -> bool:
    """The effect's refit passes the decision rule's rank tests: the calibration gain above
    ``MIN_GAIN`` nats with the calibration blocks' test, and the held-out blocks' test when there
    are held-out data (whatever its shrink)."""
    ev, ho = s.blocks_calibration, s.blocks_holdout
    return (ev is not None and ev.total > MIN_GAIN and dec.calibration_support(ev, ho)[0]
            and (ho is None or ho.passes()))


def _alternatives(sc: _Scorer, fits: dict, ranking: Sequence[EffectScore], first: EffectScore,
                  base: FitResult, combination: Sequence[str] = ()
                  ) -> list[tuple[EffectScore, dec.GapDifference]]:
    """The effects the held-out data cannot tell from the named one ``first`` (ranking order), each with
    how much more of the baseline's held-out systematic gap it leaves than the named effect's refit
    (:func:`rrfrei.gap.decision.gap_difference_ci`, paired block bootstrap): an effect is listed
    when its refit passes the rule's rank tests (:func:`_consistent`), it is not in the
    ``combination``, and the interval of that difference reaches zero or below (the held-out
    blocks do not show the named effect to predict better).  Sizes, not signs: between two effects
    that both pass against the baseline, the strong-motion windows carry the difference while the
    quiet ones flip coins, so a rank test would call a 48 % and a 13 % shrink a tie (the reading of
    :func:`rrfrei.gap.scoring._parsimonious`).  Empty without held-out data (the confounding guard
    of :func:`_name` reads ties there) or without a named effect.
    """
    if not sc.holdout or first.law not in fits:
        return []
    named = sc.parts(fits[first.law], base)  # the named effect's blocks, shared by every comparison
    out = []
    for s in ranking:
        if s.effect == first.effect or s.effect in combination or s.law not in fits or not _consistent(s):
            continue
        try:
            ev = dec.gap_difference_ci(named, sc.parts(fits[s.law], base), seed=sc.seed)
        except NUMERICAL_ERRORS:
            continue
        if ev.lower <= 0.0:
            out.append((s, ev))
    return out


def _augmented(model: GapModel, effects: Sequence[str], variants: Mapping[str, str]) -> GapModel:
    """``model`` with ``effects``, each in its variant of ``variants`` where it has one; without
    variants the plain ``augment(effects)``, the signature every model takes (only a model with
    variants takes ``variants=``)."""
    return model.augment(effects, variants=variants) if variants else model.augment(effects)


def _from_scratch(model: GapModel, sc: _Scorer, ck: _Checkpoint, data, budget: TimeBudget, seed: int,
                  first: EffectScore, fits: dict, notes: list) -> FitResult | None:
    """The named effect's model fitted from scratch (the search the baseline had, ``start=None``),
    when it fits the calibration data better than the effect's refit (total leave-one-block-out
    elpd); else None.  For a model whose effects interact, that fit then stands for the named
    effect's building: the combination starts from it and is judged against it, and it is the
    final model when nothing is added (:func:`_combine`).

    The refit started from the baseline's optimum, which the missing effect shaped: on the BNCS
    building a baseline without the isolation layer's damping can end in a basin of the Bouc-Wen
    parameters from which the damped building's refits do not leave, and every combination step
    would inherit it.  The effect is named on its refit's evidence (the rule passed on it, and
    ``steps[0]`` and the alternatives keep it); which parameters stand for it is the calibration
    data's choice, the held-out data not consulted.  A fit that fails or that the time budget
    stops is left out, with a note.
    """
    fit = fits.get(first.law)
    if fit is None:
        return None
    step = f"scratch-{effect_step(first.effect)}" + (f":{first.variant}" if first.variant else "")
    try:
        named = _augmented(model, [first.effect], {first.effect: first.variant} if first.variant else {})
        alt = _fit_or_restore(ck, step, named, data, budget, seed=seed)
        gain = float(np.sum(sc.loco(alt, blocks=False)) - np.sum(sc.loco(fit, blocks=False)))
    except BudgetExceeded:
        notes.append(f"{first.law} was not fitted from scratch: time budget (the combination starts "
                     "from its refit alone)")
        return None
    except NUMERICAL_ERRORS as exc:
        notes.append(f"{first.law} was not fitted from scratch: {_failure(f'fit of {first.law}', exc)}")
        return None
    if not gain > 0.0:
        return None
    notes.append(f"{first.law} fitted from scratch (the baseline's search) fits the calibration data "
                 f"better than its refit from the baseline (+{gain:.1f} nats leave-one-block-out): it "
                 f"stands for {first.effect}'s building (the combination starts from it; the effect was "
                 "named on its refit's evidence)")
    return alt


def _forms(model: GapModel, pool: Sequence[str], chosen: Mapping[str, str]) -> list[tuple[str, str]]:
    """The (effect, variant) refits of a combination step: each pooled effect in the form that stood
    for it alone (``chosen``; "" the primary form); for a model whose effects interact
    (:attr:`rrfrei.gap.model.GapModel.interacting_effects`), an effect with variants that change what
    is simulated (the building's runs from the virgin state) also in its other forms.  Which form
    stands for a history effect was decided against the baseline, whose missing effects distort the
    simulated motion as they distort the effect's gain (the reason the pool holds such effects):
    the recovery between runs is read again against the combination it would join."""
    out = []
    for e in pool:
        alone = chosen.get(e, "")
        out.append((e, alone))
        if model.interacting_effects:
            out += [(e, v) for v in ("", *model.variants(e))
                    if v != alone and (not v or not model.shape_variant(e, v))]
    return out


def _combine(model: GapModel, sc: _Scorer, ck: _Checkpoint, data, budget: TimeBudget, seed: int, bar,
             notes: list, *, first: EffectScore, sig: list[EffectScore], chosen: dict, fits: dict,
             screens: dict, combine: bool, max_combination: int, ranking: Sequence[EffectScore] = (),
             workers: int = 1, scratch: FitResult | None = None):
    """Greedy combination from the named effect ``first`` (step 5 of the module docstring): add the
    best further significant effect, refitted from the current combination, while it stays
    significant against it.  A step's refits are independent (each from the current combination),
    so a forked second process makes them from the end of the pool while this one works from the
    front (:class:`rrfrei.gap.parallel.SharedRefits`, ``workers``).  ``scratch``: the named effect's
    model fitted from scratch (:func:`_from_scratch`), which then stands for it (the first step's
    start and reference, ``fits`` holding it under the model's name) while ``steps[0]`` keeps the
    refit's evidence.  Returns (combination, steps, final metrics, current fit, stopped by the
    time budget)."""
    diagnosis = first.effect
    combination: list[str] = [diagnosis]
    steps: list[EffectScore] = [first]
    final = (first.calibration, first.holdout)
    current = fits[first.law]
    if scratch is not None:
        try:
            final = (sc.metrics(scratch, [sc.cal]), sc.metrics(scratch, sc.holdout))
            current = fits[first.law] = scratch
        except NUMERICAL_ERRORS as exc:
            notes.append(f"{first.law} fitted from scratch left out: {_failure('its scoring', exc)}")
    stopped = False  # the budget cut the combination search short
    chosen = dict(chosen)
    pool = [s.effect for s in sig if s.effect != diagnosis]
    if model.interacting_effects:
        pool += [s.effect for s in ranking if s.effect != diagnosis and s.effect not in pool
                 and (_consistent(s) or model.variants(s.effect))]
    while combine and pool and len(combination) < max_combination and not stopped:
        cand = []
        forms = _forms(model, pool, chosen)
        bar.total = (getattr(bar, "total", 0) or 0) + len(forms)
        jobs = {}
        for e, v in forms:
            picked = {k: w for k, w in chosen.items() if k in combination}
            if v:
                picked[e] = v
            tag = "".join(f"|{k}:{w}" for k, w in sorted(picked.items()))
            step_model = _augmented(model, combination + [e], picked)
            jobs[e, v] = (f"combination-{'+'.join(combination + [e])}{tag}"
                          f"{'|scratch' if current is scratch else ''}", step_model)
        shared = SharedRefits(ck, list(jobs.values()), data, current, seed, budget, workers)
        try:
            for e, v in forms:
                if budget.expired():
                    stopped = True
                    break
                bar.set_postfix_str(f"combine +{e}" + (f" ({v})" if v else ""))
                key, step_model = jobs[e, v]
                try:
                    fit = shared.fit(key, step_model, workers)
                    cand.append((replace(_score(sc, e, fit, current, screens.get(e, float("nan")),
                                                final), variant=v), fit))
                    fits[fit.name] = fit
                except BudgetExceeded:
                    stopped = True
                    break
                except NUMERICAL_ERRORS as exc:
                    notes.append(f"combination step +{e} skipped: "
                                 f"{_failure(f'refit of {step_model.name}', exc)}")
                bar.update()
        finally:
            if shared.helped:
                notes.append(f"{len(shared.helped)} of the combination step's refits ran in a second process")
            shared.close()
        if stopped:
            notes.append(f"combination search stopped by the time budget after "
                         f"{'+'.join(combination)}: further effects were not tried")
            break
        cand = [c for c in cand if c[0].significant]
        if not cand:
            break
        best, fit = max(cand, key=lambda c: _gain(sc, c[0]))
        combination.append(best.effect)
        if best.variant:
            chosen[best.effect] = best.variant
        else:
            chosen.pop(best.effect, None)
        steps.append(best)
        final = (best.calibration, best.holdout)
        current = fit
        pool.remove(best.effect)
    return combination, steps, final, current, stopped


def _closing_notes(diagnosis: str, effects: list[str], skipped: dict, untried: dict, stopped: bool,
                   ranking, budget: TimeBudget, fits: dict, ck: _Checkpoint, notes: list
                   ) -> tuple[str, dict[str, str], str]:
    """The notes on what was not evaluated, the time budget, the fits' own notes and the
    checkpoint; a diagnosis of none becomes "incomplete" when effects are missing.  Returns
    (diagnosis, missing effects, the budget message)."""
    missing = {**skipped, **untried}
    if missing:
        listed = "; ".join(f"{e}: {why}" for e, why in missing.items())
        if diagnosis == "none":
            diagnosis = "incomplete"
            notes.append(Note(f"incomplete diagnosis: no evaluated effect is significant, but "
                              f"{len(missing)} of {len(effects)} effects were not evaluated ({listed})",
                              "critical"))
        else:
            notes.append(Note(f"provisional diagnosis: {len(missing)} of {len(effects)} effects were "
                              f"not evaluated ({listed}); one of them might score higher", "critical"))
    for e, why in skipped.items():
        notes.append(Note(f"effect {e} skipped: {why}", "warning"))
    budget_message = ""
    if untried or stopped:
        done = [s.effect for s in ranking]
        budget_message = budget.message(
            f"evaluated: {', '.join(done) or 'baseline only'}"
            + (f"; not evaluated: {', '.join(untried)}" if untried else "")
            + ("; combination search cut short" if stopped else ""))
        notes.append(Note(budget_message, "warning"))
    for f in fits.values():
        if getattr(f, "note", ""):  # the fit's own notes, at the most severe of their severities
            sev = min((n.severity for n in getattr(f, "notes", ())), key=SEVERITIES.index, default="info")
            notes.append(Note(f.note, sev))
    if ck.reused:
        notes.append(f"reused {len(ck.reused)} finished fits from the checkpoint folder "
                     f"({', '.join(ck.reused)})")
    if ck.error:
        notes.append(Note(ck.error, "warning"))
    return diagnosis, missing, budget_message


def _as_test(t, what: str) -> ShearTest:
    if isinstance(t, ShearTest):
        return t
    if isinstance(t, str) and t in ("protocol1", "protocol2", "protocol3", "protocol4"):
        from rrfrei.io import load_test

        return load_test(t)
    try:
        return read_test(t)
    except TypeError:
        raise ValueError(f"{what} must be a ShearTest or a CSV path, got {type(t).__name__}") from None


def diagnose_gap(test, law: str = "bouc_wen", *, holdout: Sequence = (), effects: Sequence[str] | None = None,
                 fixed: dict | None = None, draws: int = 200, seed: int = 0, combine: bool = True,
                 progress: bool = False, time_budget: float | TimeBudget | None = None,
                 checkpoint: str | os.PathLike | None = None, workers: int = 1) -> GapReport:
    """Sim-to-real gap diagnosis of ``law`` calibrated on ``test`` (isolator laws).

    Parameters
    ----------
    test : calibration test (:class:`~rrfrei.io.ShearTest`, CSV path, or a bundled name
        ``"protocol1"``).
    law : base law name (``rrfrei.laws.names()``).
    holdout : held-out tests (same kinds).
    effects : catalogue effects to try (default all six).
    fixed : base-law parameters held fixed (e.g. ``{"alpha2": 0.0}``).
    draws : Laplace posterior draws per fit.
    seed : seed of all fits and draws.
    progress : tqdm progress bar on stderr over the steps, with a remaining-time estimate (off by
        default so that callers with their own bars, e.g. ``rrfrei demo``, show one at a time;
        ``rrfrei gap`` turns it on unless ``--no-progress``).
    time_budget : wall-clock limit [s] (``None``: no limit); when reached, the diagnosis ends
        with the effects evaluated so far and lists the others (see :func:`diagnose`).
    checkpoint : folder where finished fits are saved and reused by a rerun (``None``: none).
    workers : processes for the candidates' refits (needs ``checkpoint``; :func:`diagnose`).

    Returns
    -------
    GapReport
    """
    from rrfrei.laws import get

    spec = get(law)
    if spec.effects:
        raise ValueError(f"law must be a base law, got the augmented law {spec.name!r}")
    budget = TimeBudget.of(time_budget, "gap diagnosis")  # starts before the tests are read
    cal = _as_test(test, "test")
    hos = [_as_test(h, "holdout") for h in holdout]
    return diagnose(IsolatorModel(spec, fixed=fixed, draws=draws), cal, hos, effects=effects, seed=seed,
                    combine=combine, progress=progress, time_budget=budget, checkpoint=checkpoint,
                    workers=workers)
