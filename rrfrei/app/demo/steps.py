"""The demo's steps: each runs one workflow on the bundled data and fills its page section.

A step is ``step(ctx, section)``: it computes, adds its tables (with captions), its figures
(:mod:`rrfrei.app.demo.figures`) and its reading (:mod:`rrfrei.app.demo.prose`).  :data:`STEPS`
lists them in page order; see :mod:`rrfrei.app.demo` for what each one shows.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from ground_motions import available, load, load_pair
from rrfrei.app.demo import figures, prose
from rrfrei.app.demo.context import EXPECTED_FAILURES, SYNTHETIC, TESTS, DemoContext, Step
from rrfrei.app.report import Section, fmt
from rrfrei.calibration import calibrate, compare
from rrfrei.calibration.checks import predict
from rrfrei.energy import cycle_metrics
from rrfrei.gap import diagnose_gap
from rrfrei.gap.report import figures as gap_figures
from rrfrei.io import load_test
from rubber import PRESETS, fit, objective
from rubber.fit import combinations
from rubber.io import load_vhb4910
from rubber.study import synthetic_test
from structures import Isolator, load_building, time_history_batch
from structures.propagation.plan_design import DEFAULT_LAMBDAS, plan_design_answers, plot_orbit
from structures.propagation.propagate import propagate
from structures.propagation.stripes import StripeAnalysis, multiple_stripe_analysis
from structures.shake_table.gap import shake_table_gap
from structures.shake_table.report import figures as shake_table_figures
from structures.shake_table.report import gap_table as shake_table_gap_table
from structures.shake_table.sequence import CHANNELS as CHANNELS_ST

__all__ = ["STEPS", "step_calibrate", "step_compare", "step_gap", "step_propagate", "step_rubber",
           "step_shake_table", "step_tests", "step_validate"]

ORBIT_PAIR = "santamonica"
"""The bundled record pair of the propagation step's orbit plot (the shortest: 60 s at 0.02 s)."""

FIT_PANELS = 4
"""Laws calibrated in step 2: one panel each of its 2 x 2 figure (the first of ``settings.laws``)."""


# ---------------------------------------------------------------------------------------------
# step 1: the tests
# ---------------------------------------------------------------------------------------------
def step_tests(ctx: DemoContext, sec: Section) -> None:
    rows, cyc = [], []
    for name in TESTS:
        t = load_test(name)
        ctx.tests[name] = t
        d_mm = 1e3 * np.asarray(t.disp)
        f = np.asarray(t.force)
        m = cycle_metrics(t.disp, t.force)
        m.insert(0, "test", name)
        cyc.append(m)
        rows.append(
            {
                "test": name,
                "points": int(d_mm.size),
                "duration_s": float(t.time[-1] - t.time[0]) if t.has_time else float("nan"),
                "disp_max_mm": float(d_mm.max()),
                "disp_min_mm": float(d_mm.min()),
                "force_max_kN": float(f.max()),
                "force_min_kN": float(f.min()),
                "full_cycles": len(m),
                "energy_total_kNm": float(m["energy"].sum()) if len(m) else 0.0,
            }
        )
    summary = pd.DataFrame(rows)
    cycles = pd.concat(cyc, ignore_index=True)
    sec.add_table("tests", summary, "One row per bundled SYNTHETIC test.")
    sec.add_table("cycles", cycles, "Per full cycle: dissipated energy [kN m], k_eff [kN/m], beta_eff.")
    sec.add_figure("loops", figures.isolator_loops(ctx.tests),
                   "Force-displacement loops of the four SYNTHETIC tests.")
    sec.reading = prose.tests_reading(summary, cycles)


# ---------------------------------------------------------------------------------------------
# step 2: calibration
# ---------------------------------------------------------------------------------------------
def step_calibrate(ctx: DemoContext, sec: Section) -> None:
    tests = ctx.need("tests", "tests")
    s = ctx.settings
    test = tests["protocol1"]
    summaries, fit_rows, panels = [], [], []
    failed: dict[str, str] = {}
    for law in s.laws[:FIT_PANELS]:
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # convergence is reported in the table instead
                cal = calibrate(test, law, walkers=s.walkers, steps=s.steps, max_steps=s.max_steps,
                                seed=s.seed, progress=ctx.progress)
        except EXPECTED_FAILURES as exc:  # one law failing must not hide the others (bugs do show)
            failed[law] = f"{type(exc).__name__}: {exc}"
            panels.append((law, None))
            continue
        ctx.calibrations[law] = cal
        summ = cal.summary.reset_index()
        summ.insert(0, "law", law)
        summaries.append(summ)
        pred = predict(cal, test, n=s.predict_draws, seed=s.seed)
        fit_rows.append({"law": law, "nrmse": float(pred.nrmse), "nrmse_map": float(pred.nrmse_map),
                         "coverage": float(pred.coverage), "sigma_kN": float(cal.sigma),
                         "converged": bool(cal.converged),
                         "acceptance": float(np.mean(cal.diagnostics.get("acceptance", np.nan))),
                         "max_rhat": float(cal.summary["R-hat"].max()),
                         "min_ess": float(cal.summary["ESS"].min()),
                         "seconds": time.perf_counter() - t0})
        panels.append((law, pred))
    if not fit_rows:
        raise RuntimeError("every calibration failed: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    fits = pd.DataFrame(fit_rows)
    ctx.results["calibration_nrmse"] = dict(zip(fits["law"], fits["nrmse"]))
    sec.add_table("fit", fits, "Fit on protocol 1 per law: NRMSE of the posterior mean and of the MAP, "
                  "coverage of the 95 % band with noise, noise sd, convergence diagnostics.")
    sec.add_table("posteriors", pd.concat(summaries, ignore_index=True),
                  "Posterior summaries (mean, MAP, sd, 95 % interval, ESS, R-hat) per law.")
    sec.add_figure("fits", figures.calibration_fits(test, panels),
                   "Measured loop (grey), posterior mean and 95 % band (with noise) per law.")
    sec.reading = prose.calibration_reading(fits, failed, s.quick)
    if failed:
        raise RuntimeError("calibration failed for " + "; ".join(f"{k}: {v}" for k, v in failed.items()))


# ---------------------------------------------------------------------------------------------
# step 3: comparison
# ---------------------------------------------------------------------------------------------
def step_compare(ctx: DemoContext, sec: Section) -> None:
    cals = ctx.need("calibrations", "calibration")
    res = compare(dict(cals))
    table = res.table.reset_index()
    ctx.best_law = res.best
    ctx.results["comparison"] = res
    sec.add_table("criteria", table, "elpd (higher is better), effective parameters p, standard error se, "
                  "se of the difference to the best dse and stacking weights, for PSIS-LOO, WAIC and "
                  "leave-one-cycle-out (LOCO); k_max_loo and k_max_loco: largest Pareto k of PSIS-LOO and of "
                  "LOCO (above 0.7 the PSIS estimate is unreliable).")
    sec.add_table("pareto_k", res.pareto_k.reset_index(), "Pareto k counts of PSIS-LOO per law.")
    sec.add_table("loco_cycles", res.loco_cycles, "Leave-one-cycle-out elpd per cycle and law.")
    sec.add_figure("elpd", res.figure(), "elpd +- se per law and criterion.")
    sec.reading = prose.comparison_reading(res.table)


def _best_law(ctx: DemoContext) -> str:
    if ctx.best_law is None:
        raise RuntimeError("this step needs the best law from the 'comparison' step, which did not finish")
    return ctx.best_law


# ---------------------------------------------------------------------------------------------
# step 4: validation
# ---------------------------------------------------------------------------------------------
def step_validate(ctx: DemoContext, sec: Section) -> None:
    tests = ctx.need("tests", "tests")
    best = _best_law(ctx)
    cal = ctx.calibrations[best]
    s = ctx.settings
    rows, cycles, preds = [], [], {}
    for name in TESTS[1:]:
        pred = predict(cal, tests[name], n=s.predict_draws, seed=s.seed)
        preds[name] = pred
        d = pred.as_dict()
        rows.append({"test": name, "nrmse": float(pred.nrmse), "nrmse_map": float(pred.nrmse_map),
                     "coverage": float(pred.coverage), "coverage_param": float(pred.coverage_param),
                     "energy_test_kNm": d["energy_test"] if len(pred.cycles) else 0.0,
                     "energy_map_kNm": d["energy_map"] if len(pred.cycles) else 0.0,
                     "cycles": len(pred.cycles)})
        if len(pred.cycles):
            cycles.append(pred.cycles.assign(test=name))
    table = pd.DataFrame(rows)
    sec.add_table("holdout", table, f"Held-out predictions of {best} calibrated on protocol 1 "
                  f"({SYNTHETIC} tests): NRMSE, coverage of the 95 % band with noise (and of the "
                  "parameter-only band), energy dissipated over full cycles (test, MAP).")
    if cycles:
        sec.add_table("holdout_cycles", pd.concat(cycles, ignore_index=True),
                      "Per held-out cycle: energy, k_eff and beta_eff of the test, the MAP and the band.")
    sec.add_figure("holdout", figures.holdout_fits(tests, preds, best),
                   "Held-out tests (grey) against the posterior mean and 95 % band.")
    sec.reading = prose.validation_reading(best, table, ctx.results.get("calibration_nrmse", {}).get(best))


# ---------------------------------------------------------------------------------------------
# step 5: gap
# ---------------------------------------------------------------------------------------------
def step_gap(ctx: DemoContext, sec: Section) -> None:
    tests = ctx.need("tests", "tests")
    best = _best_law(ctx)
    s = ctx.settings
    holdout = [tests[n] for n in TESTS[1:]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = diagnose_gap(tests["protocol1"], best, holdout=holdout, draws=s.gap_draws, seed=s.seed,
                           effects=None if s.gap_effects is None else list(s.gap_effects),
                           progress=ctx.progress)
    ctx.results["gap"] = rep
    rows = []
    for e in rep.ranking:
        rows.append({"effect": e.effect, "variant": e.variant or "-", "law": e.law, "screen": e.screen,
                     "delta_elpd": e.delta_elpd, "se": e.se, "delta_holdout": e.delta_holdout,
                     "se_holdout": e.se_holdout,
                     "gap_calibration": e.calibration.gap, "systematic_calibration": e.calibration.systematic,
                     "gap_holdout": e.holdout.gap if e.holdout is not None else float("nan"),
                     "shrink_calibration": e.shrink_calibration, "shrink_holdout": e.shrink_holdout,
                     "significant": bool(e.significant), "note": e.note or "-"})
    ranking = _na_as_text(pd.DataFrame(rows), ("screen", "delta_holdout", "se_holdout", "gap_holdout",
                                                "shrink_calibration", "shrink_holdout"))
    metrics = []
    for label, (m_cal, m_hold) in (("baseline " + best, rep.baseline),
                                   ("final " + "+".join([best, *rep.combination]), rep.final)):
        for on, m in (("calibration (protocol1)", m_cal), ("held out (protocols 2-4)", m_hold)):
            if m is not None:
                metrics.append({"model": label, "on": on, **m.as_dict()})
    metrics_df = _na_as_text(pd.DataFrame(metrics), ("energy_error",))
    where = _na_as_text(rep.where.reset_index(drop=True), ("energy_error", "coverage", "bias"))
    sec.add_table("gap", metrics_df, "Gap = NRMSE, its systematic part sqrt(max(MSE - sigma^2, 0)) / "
                  "RMS(measured), energy-per-cycle error and band coverage, before and after the effects.")
    sec.add_table("ranking", ranking, "Each catalogue effect added to the baseline: residual screen, "
                  "leave-one-cycle-out elpd gain (se), held-out score gain, gaps and shrink of the "
                  "systematic gap.")
    sec.add_table("where", where, "Where the baseline misses: segments of protocol 1 ranked by excess "
                  "error over the noise.")
    for name, fig in gap_figures(rep).items():
        sec.add_figure(name.removesuffix(".png"), fig)
    sec.reading = prose.gap_reading(rep, best)
    for note in rep.notes:
        sec.notes.append(note)


def _na_as_text(df: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """Write 'n/a' (not applicable) instead of NaN in the given columns, leaving them as text.

    Used only where a NaN means 'not defined' (e.g. the energy error of a segment without a full
    cycle, a held-out score without held-out tests); every other column must hold finite numbers.
    """
    out = df.copy()
    for c in columns:
        if c in out.columns and out[c].isna().any():
            out[c] = [fmt(v) for v in out[c]]
    return out


# ---------------------------------------------------------------------------------------------
# step 6: propagation
# ---------------------------------------------------------------------------------------------
def step_propagate(ctx: DemoContext, sec: Section) -> None:
    best = _best_law(ctx)
    cal = ctx.calibrations[best]
    s = ctx.settings
    example = load_building(s.building)
    iso = example.isolator
    # the example building's bearings (count, similitude scale), now following the best law
    building = replace(example, isolator=Isolator(best, cal.map_params(), count=iso.count,
                                                  length_scale=iso.length_scale))
    records = tuple(s.records) if s.records is not None else tuple(available())
    rs = propagate(cal, building, records, n_samples=s.n_samples, scales=(1.0,), seed=s.seed,
                   progress=ctx.progress)
    summary = rs.summary()
    split = rs.variance_split()
    exceed = rs.exceedance()
    sec.add_table("runs", rs.table, f"One row per analysis: {s.n_samples} posterior draws of {best} x "
                  f"{len(records)} records as recorded (scale 1); prototype units (m, m/s^2, kN, kN m).")
    sec.add_table("percentiles", summary, "Median, 16/84 and 2.5/97.5 percentiles per record and over all "
                  "records, records as recorded (converged runs).")
    split_ok = split.dropna(subset=["share_params"])
    sec.add_table("variance_split", split_ok, "Share of Var(ln demand) explained by the isolator parameters "
                  "vs. the records (law of total variance); demands that are zero in some run have no "
                  "logarithm and are left out.")
    sec.add_table("exceedance", exceed, f"P(demand > limit) with the records as recorded: per record "
                  f"over its {s.n_samples} posterior draws, and over all {len(records)} records x draws.")
    sec.add_figure("distributions", rs.plot_distributions("iso_disp_peak_m", scale=1.0),
                   "Peak isolator displacement per record over the posterior draws, records as recorded.")
    sec.add_figure("exceedance", rs.plot_exceedance("iso_disp_peak_m", scale=1.0),
                   f"Exceedance curves of the peak isolator displacement with the records AS RECORDED: each "
                   f"thin curve over the {s.n_samples} posterior draws on one record, the thick one over all "
                   f"records x draws. Not the fragility below, which is over records scaled to common "
                   f"intensities.")
    sec.reading = prose.propagation_reading(rs, summary, exceed, split, building=s.building,
                                            count=iso.count, law=best, scale=1.0)
    # fragility: multiple stripe analysis at Sa(T_iso, 5 %) [g]
    stripe_records = tuple(s.stripe_records) if s.stripe_records is not None else tuple(available())
    msa = multiple_stripe_analysis(cal, building, stripe_records, n_levels=s.stripes,
                                   n_samples=s.stripe_samples, seed=s.seed, progress=ctx.progress)
    ctx.results["stripes"] = msa
    frs = msa.fragility()
    sec.add_table("fragility", fragility_table(msa, frs),
                  f"Lognormal fragility P(D > limit | IM) = Phi(ln(IM / median) / beta) against "
                  f"{msa.im.label}: maximum likelihood over the {len(msa.levels)} stripes (binomial counts, "
                  f"Baker 2015); at each stripe every one of the {len(stripe_records)} records is scaled to "
                  f"that intensity and runs {s.stripe_samples} posterior draws of {best}. T_iso: first "
                  "period of the building with the posterior-median isolator at its secant stiffness at "
                  "the displacement limit.")
    sec.add_table("stripes", stripe_table(msa),
                  f"The stripes: intensity {msa.im.name} [g], runs, and the share beyond each limit.")
    sec.add_table("record_intensity", pd.DataFrame(
        [{"record": r, f"{msa.im.name}_as_recorded_g": v,
          "scale_factor_at_lowest_stripe": min(msa.levels) / v,
          "scale_factor_at_highest_stripe": max(msa.levels) / v} for r, v in msa.record_im.items()]),
                  f"Each record's own {msa.im.label} and the factors that bring it to the lowest and highest "
                  "stripe.")
    sec.add_figure("fragility", msa.plot_fragility(),
                   f"Fragility curves against {msa.im.label}, with the share of each stripe's runs beyond "
                   "the limit (points).")
    # both horizontal components at once: one bundled pair on the plan building (coupled isolator
    # law), nominal and ASCE 7-22 bound properties, the orbit against the design displacement
    pair = load_pair(ORBIT_PAIR)
    ans = plan_design_answers(building, [pair], bounds=DEFAULT_LAMBDAS)
    ctx.results["plan_answers"] = ans
    sec.add_table("plan_answers", ans.table().drop(columns="lambda"),
                  f"ASCE 7-22 Chapter 17 answers of the {ORBIT_PAIR} pair (both components at once) on the "
                  f"plan building with the MAP {best} isolator, nominal and lambda = "
                  f"{DEFAULT_LAMBDAS[0]:g} / {DEFAULT_LAMBDAS[1]:g} bounds: maximum plan (vector-sum) "
                  "isolator displacement [m], per direction [m], total maximum displacement (no torsion: "
                  "the plan displacement) [m], base shear per direction [kN]; one pair, so the design "
                  "value is the maximum.")
    others = {f"{b} bound (lambda {ans.lambdas[b]:g})": ans.orbits[(b, pair.name)]
              for b in ("lower", "upper")}
    sec.add_figure("orbit", plot_orbit(ans.orbits[("nominal", pair.name)], ans.design_displacement,
                                       others=others, title=f"{pair.name}: isolator orbit in plan"),
                   "Isolator displacement y against x [m] under both components of the pair, with the "
                   "circle at the governing design displacement.")
    sec.reading += " " + prose.orbit_reading(ans, pair.name)
    sec.reading += "\n\n" + prose.fragility_reading(msa, frs)


def warm_building_kernels(ctx: DemoContext) -> None:
    """Compile ahead what :func:`step_propagate` runs on the example building's own isolator law:
    one analysis of the 1-D batch kernel (the propagation's and the stripes' kernel) and the plan
    answers of the orbit pair, with the building's parameters (the same argument types, so the
    per-user kernel cache then holds what the step needs).  Run by the demo's second process
    while this one calibrates; the results are thrown away."""
    s = ctx.settings
    building = load_building(s.building)
    records = tuple(s.records) if s.records is not None else tuple(available())
    time_history_batch(building, load(records[0]), building.isolator.packed()[None, :])
    plan_design_answers(building, [load_pair(ORBIT_PAIR)], bounds=DEFAULT_LAMBDAS)


def fragility_table(msa: StripeAnalysis, frs) -> pd.DataFrame:
    """One row per demand limit: the fitted median [g] and beta, and the observed share beyond the
    limit at the lowest and highest stripe (does the set of stripes span the curve?)."""
    rows = []
    for f in frs:
        share = np.divide(f.z, f.n)
        rows.append({"demand": f.demand, "limit": f.limit, "im": msa.im.name, "median_g": f.theta,
                     "beta": f.beta, "stripes": len(f.im), "runs_per_stripe": int(max(f.n)),
                     "share_at_lowest": float(share[int(np.argmin(f.im))]),
                     "share_at_highest": float(share[int(np.argmax(f.im))]),
                     "note": f.note or "-"})
    return _na_as_text(pd.DataFrame(rows), ("median_g", "beta"))


def stripe_table(msa: StripeAnalysis) -> pd.DataFrame:
    """Per stripe: its intensity [g], its converged runs, and the share beyond each limit."""
    ex = msa.responses.exceedance()
    ex = ex[ex["record"] == "all records"]
    wide = ex.pivot_table(index="scale", columns="demand", values="p_exceed", aggfunc="first")
    wide.columns = [f"share_{c}_beyond_limit" for c in wide.columns]
    n = ex.groupby("scale")["n"].max()
    out = wide.assign(runs=n).reset_index().rename(columns={"scale": f"{msa.im.name}_g"})
    return out[[out.columns[0], "runs", *wide.columns]]


# ---------------------------------------------------------------------------------------------
# step 7: the real base-isolated building (shake-table runs)
# ---------------------------------------------------------------------------------------------
def step_shake_table(ctx: DemoContext, sec: Section) -> None:
    s = ctx.settings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = shake_table_gap(None, calibrate=list(s.shake_calibrate), holdout=list(s.shake_holdout),
                              law=s.shake_law, rate_hz=s.shake_rate_hz, n_draws=s.shake_draws,
                              effects=None if s.shake_effects is None else list(s.shake_effects),
                              draws=s.shake_draws, seed=s.seed, time_budget=s.shake_budget_s,
                              progress=ctx.progress)
    ctx.results["shake_table"] = res
    cal, held = ", ".join(res.calibrate), ", ".join(res.holdout)
    sec.add_table("gap", shake_table_gap_table(res),
                  f"REAL data (BNCS building, UCSD shake table). Building calibrated on {cal}, {held} "
                  "held out: "
                  f"NRMSE of the posterior median per channel with the baseline {res.law} and with "
                  f"{res.final_law}, the shrink, and the held-out coverage of the predictive 95 % band "
                  "(parameter draws plus the calibration-run error) and of the parameter band.")
    rank = pd.DataFrame([{"effect": e.effect, "delta_elpd": e.delta_elpd, "se": e.se,
                          "delta_holdout": e.delta_holdout, "se_holdout": e.se_holdout,
                          "shrink_holdout": e.shrink_holdout, "significant": bool(e.significant)}
                         for e in res.report.ranking])
    if len(rank):
        sec.add_table("ranking", _na_as_text(rank, ("delta_holdout", "se_holdout", "shrink_holdout")),
                      "Each candidate effect (the catalogue's isolator effects and the system effects) "
                      "added to the building, fitted by output error on the calibration runs and judged "
                      "on the held-out runs' simulated responses.")
    checked = res.building_check.dropna(subset=list(CHANNELS_ST)) if len(res.building_check) else []
    if len(checked):  # a candidate whose analysis failed is named in the notes instead
        sec.add_table("building_check", checked,
                      "Held-out NRMSE per channel of the building with the optimum of the baseline and of "
                      "every candidate effect (one analysis each): does the isolation-level ranking carry "
                      "to the building? Candidates whose analysis failed are in the notes.")
    if len(res.law_scores):
        sec.add_table("laws", _na_as_text(res.law_scores, ("loco_elpd", "nrmse")),
                      "Law choice: leave-one-cycle-out elpd on the calibration isolation tests.")
    if len(res.where):
        sec.add_table("where", _na_as_text(res.where, ("nrmse",)),
                      "Where the held-out gap lies: share of each channel's squared error by run, amplitude "
                      "range, frequency band and time window (the worst five 10 s windows).")
    for name, fig in shake_table_figures(res).items():
        sec.add_figure(name.removesuffix(".png"), fig)
    sec.reading = prose.shake_table_reading(res, quick=s.quick, budget_s=s.shake_budget_s)
    for note in res.notes:
        sec.notes.append(note)


# ---------------------------------------------------------------------------------------------
# step 8: rubber
# ---------------------------------------------------------------------------------------------
def step_rubber(ctx: DemoContext, sec: Section) -> None:
    s = ctx.settings
    truth = PRESETS["A"]
    noise = 0.01  # MPa
    p1 = synthetic_test(truth, "p1", noise=noise, seed=s.seed)
    p2 = synthetic_test(truth, "p2", noise=noise, seed=s.seed + 1)
    vhb = load_vhb4910()
    kw = {"seed": s.seed, "restarts": s.rubber_restarts, "max_evals": s.rubber_evals,
          "polish_evals": s.rubber_polish_evals}
    jobs = {"both protocols": ([p1, p2], {}), "VHB 4910 (real)": ([vhb], {"bounds": "auto"})}
    if not s.quick:  # the cross-prediction study: each protocol alone too
        jobs = {"protocol 1": ([p1], {}), "protocol 2": ([p2], {}), **jobs}
    fits = {}
    for label in tqdm_or_plain(list(jobs), ctx.progress, desc="rubber fits", unit="fit", leave=False):
        tests, extra = jobs[label]
        fits[label] = fit(tests, **kw, **extra)
    # every synthetic fit on every synthetic protocol (cross-prediction); the VHB fit on its data
    rows = []
    for label, r in fits.items():
        on = [vhb] if label.startswith("VHB") else [p1, p2]
        for t in on:
            f = float(objective(r.params, [t])[0])
            rows.append({"fit": label, "evaluated_on": t.name, "data": "real" if t is vhb else SYNTHETIC,
                         "fitted_to_it": t.name in r.f, "f": f, "rms_error": math.sqrt(f),
                         "evaluations": int(r.evaluations)})
    table = pd.DataFrame(rows)
    params = pd.DataFrame({label: r.params.as_dict() for label, r in fits.items()})
    params.insert(0, "truth (preset A, synthetic)", pd.Series(truth.as_dict()))
    params.index.name = "parameter"
    combos = pd.DataFrame({label: r.combinations for label, r in fits.items()})
    combos.index.name = "combination"
    ident = pd.DataFrame({label: pd.Series(r.rel_sigma, dtype=float) for label, r in fits.items()})
    ident.index.name = "parameter"
    sec.add_table("fits", table, "Objective f = sum (s_exp - s_pred)^2 / sum s_exp^2 per test; rms_error = "
                  "sqrt(f per test), the relative RMS misfit.")
    sec.add_table("parameters", params.reset_index(), "Fitted PRF parameters (MPa, s) and the preset the "
                  "synthetic protocols were made from.")
    sec.add_table("combinations", combos.reset_index(), "Identifiable combinations: small-strain moduli per "
                  "chain [MPa], flow thresholds [MPa], equilibrium stress at three stretches [MPa].")
    sec.add_table("identifiability", ident.reset_index(), "Relative change of each free parameter that "
                  "raises f by 1e-4 with the others re-optimised: above 1, practically unidentifiable.")
    both = fits["both protocols"]
    panels = ((p1, both, f"protocol 1 ({SYNTHETIC})"), (p2, both, f"protocol 2 ({SYNTHETIC})"),
              (vhb, fits["VHB 4910 (real)"], "VHB 4910 (real data)"))
    sec.add_figure("fits", figures.rubber_fits(panels),
                   "Stress histories: data against the fitted PRF model.")
    mu_true = combinations(truth)
    mu_err = max(abs(both.combinations[k] / mu_true[k] - 1) for k in ("mu0_A", "mu0_B", "mu0_C"))
    sec.reading = prose.rubber_reading(table, fits, noise=noise, mu_err=mu_err, p2_name=p2.name,
                                       vhb_name=vhb.name, quick=s.quick)


def tqdm_or_plain(iterable, progress: bool, **kw):
    """``iterable`` with a tqdm bar when ``progress`` (tqdm imported only then), else as it is."""
    if not progress:
        return iterable
    try:
        from tqdm.auto import tqdm  # deferred: only runs with a bar need it
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return iterable
    return tqdm(iterable, **kw)


STEPS: tuple[Step, ...] = (
    Step("tests", f"The bundled isolator tests ({SYNTHETIC})", step_tests),
    Step("calibration", "Calibration of the isolator laws on protocol 1", step_calibrate),
    Step("comparison", "Which law? LOO, WAIC and leave-one-cycle-out", step_compare),
    Step("validation", "The best law on held-out protocols 2-4", step_validate),
    Step("gap", "Sim-to-real gap: where, which effect, how much it shrinks", step_gap, alone=True,
         after="comparison"),
    Step("propagation", "The best posterior on the 5-story example building", step_propagate),
    Step("shake_table", "A real base-isolated building: shake-table runs predicted and diagnosed",
         step_shake_table),
    Step("rubber", "Polyurethane (PRF) model fits", step_rubber, alone=True),
)

AHEAD: dict[str, Callable[[DemoContext], None]] = {"propagation": warm_building_kernels}
"""Work the second process does first, for a step that runs here: compile its kernels ahead.
Such a step runs last in this process (its kernels are compiled by then), so no later step may
read its results."""
