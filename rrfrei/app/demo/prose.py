"""The demo page's readings: one plain-language paragraph per step, computed from its numbers.

Each function takes the step's tables and results and returns the text of its section; nothing
here computes a result, draws or writes.  Shares are shown as percentages (:func:`pct`), other
numbers with :func:`rrfrei.app.report.fmt`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from rrfrei.app.demo.context import SYNTHETIC
from rrfrei.app.report import fmt
from rrfrei.calibration.sampler import CONVERGENCE_RULE
from rrfrei.gap.report import verdict_text
from structures.shake_table.report import peaks_text


def pct(x: float) -> str:
    """A share as a percentage (two significant digits below 0.1 %, so small shares are not 0.0 %)."""
    v = 100 * float(x)
    return f"{v:.2g} %" if 0 < abs(v) < 0.1 else f"{v:.1f} %"


def tests_reading(summary: pd.DataFrame, cycles: pd.DataFrame) -> str:
    """Step 1: the span of protocol 1 and how its largest and first cycles differ."""
    p1 = cycles[cycles["test"] == "protocol1"]
    big = p1.loc[p1["energy"].idxmax()] if len(p1) else None
    first = p1.iloc[0] if len(p1) else None
    reading = (
        f"The four isolator tests are {SYNTHETIC}: made by an independent model with noise, standing "
        f"in for the scaled RR-FREI specimens (no real test data are public). Protocol 1 spans "
        f"{fmt(summary.loc[0, 'disp_min_mm'], 3)} to {fmt(summary.loc[0, 'disp_max_mm'], 3)} mm and "
        f"{fmt(summary.loc[0, 'force_min_kN'], 3)} to {fmt(summary.loc[0, 'force_max_kN'], 3)} kN "
        f"in {len(p1)} full cycles."
    )
    if big is not None and first is not None:
        reading += (
            f" Its largest cycle dissipates {fmt(big['energy'], 3)} kN m with an effective stiffness "
            f"of {fmt(big['k_eff'], 3)} kN/m and effective damping {pct(big['beta_eff'])}; the first "
            f"small cycle is {'stiffer' if first['k_eff'] > big['k_eff'] else 'softer'} "
            f"(k_eff {fmt(first['k_eff'], 3)} kN/m), the usual softening of rubber bearings with "
            f"amplitude."
        )
    return reading


def calibration_reading(fits: pd.DataFrame, failed: dict[str, str], quick: bool) -> str:
    """Step 2: the closest and loosest fit, convergence, and the laws whose calibration failed."""
    best = fits.loc[fits["nrmse"].idxmin()]
    worst = fits.loc[fits["nrmse"].idxmax()]
    n_conv = int(fits["converged"].sum())
    reading = (
        f"{len(fits)} laws were calibrated on protocol 1 ({SYNTHETIC}). The closest fit is "
        f"{best['law']} (NRMSE {pct(best['nrmse'])}, noise sd {fmt(best['sigma_kN'], 3)} kN, band "
        f"coverage {pct(best['coverage'])}); the loosest is {worst['law']} (NRMSE "
        f"{pct(worst['nrmse'])}). {n_conv} of {len(fits)} chains met the convergence rule "
        f"({CONVERGENCE_RULE})"
    )
    if n_conv < len(fits):
        bad = ", ".join(fits.loc[~fits["converged"], "law"])
        reading += f"; {bad} did not"
        reading += ", as expected of the short chains of a quick run" if quick else ""
    reading += "."
    if failed:
        reading += (f" The calibration of {', '.join(failed)} failed (below); the other steps go on "
                    "without it.")
    return reading


PARETO_K_LIMIT = 0.7
"""Pareto k above which a PSIS estimate is unreliable (Vehtari et al. 2017, 2024; for the several
thousand draws of a calibration the sample-size-dependent limit min(1 - 1 / log10 S, 0.7) is 0.7)."""


def pareto_k_reading(t: pd.DataFrame, limit: float = PARETO_K_LIMIT) -> tuple[str, bool]:
    """The largest Pareto k of PSIS-LOO and of leave-one-cycle-out, both, and whether any of them
    makes the comparison unreliable: ``(sentence, reliable)``."""
    parts, bad = [], []
    for col, crit in (("k_max_loo", "PSIS-LOO (one point left out)"),
                      ("k_max_loco", "leave-one-cycle-out")):
        if col not in t.columns:
            continue
        k = t[col].astype(float)
        law = str(k.idxmax())
        parts.append(f"{fmt(float(k.max()), 3)} for {crit} ({law})")
        over = [f"{name} {fmt(float(v), 3)}" for name, v in k.items() if v > limit]
        if over:
            bad.append(f"{crit}: {', '.join(over)}")
    text = "The largest Pareto k is " + " and ".join(parts) + "."
    if bad:
        text += (f" Some k exceed {fmt(limit)} ({'; '.join(bad)}), the limit above which the PSIS estimate "
                 "of a left-out elpd is unreliable (Vehtari et al. 2017, 2024): this comparison is "
                 "UNRELIABLE, its elpd differences and standard errors are rough at best; refit with those "
                 "points or cycles left out (exact cross-validation) before trusting the ranking.")
        return text, False
    text += (f" All are at most {fmt(limit)} (the PSIS reliability limit, Vehtari et al. 2017, 2024): "
             "the estimates are reliable.")
    return text, True


def comparison_reading(t: pd.DataFrame) -> str:
    """Step 3: PSIS-LOO's ranking, how clear it is, whether WAIC and LOCO agree, Pareto k of both."""
    best, second = t.index[0], t.index[1]
    diff = float(t.loc[best, "elpd_loo"] - t.loc[second, "elpd_loo"])
    dse = float(t.loc[second, "dse_loo"])
    ratio = diff / dse if dse > 0 else float("inf")
    k_text, reliable = pareto_k_reading(t)
    verdict = ("a clear difference" if ratio > 2 else
               "within about two standard errors: the data hardly separate them")
    if not reliable:
        verdict += ", if the estimates held (see the Pareto k below)"
    loco_best = str(t["elpd_loco"].idxmax())
    waic_best = str(t["elpd_waic"].idxmax())
    reading = (
        f"PSIS-LOO ranks {best} first (elpd {fmt(t.loc[best, 'elpd_loo'], 5)} +- "
        f"{fmt(t.loc[best, 'se_loo'], 3)}), ahead of {second} by {fmt(diff, 3)} with a standard error "
        f"of the difference of {fmt(dse, 3)} ({fmt(ratio, 2)} se: {verdict}). WAIC "
        f"{'agrees' if waic_best == best else f'prefers {waic_best}'}, and leave-one-cycle-out, which "
        f"holds out whole cycles and so judges prediction of unseen loops, "
        f"{'agrees' if loco_best == best else f'prefers {loco_best}'}. "
    )
    reading += k_text
    reading += (f" The best law, {best}, is carried into the next steps." if reliable else
                f" {best}, first by PSIS-LOO, is carried into the next steps with that caveat.")
    return reading


def validation_reading(best: str, table: pd.DataFrame, cal_nrmse: float | None) -> str:
    """Step 4: held-out errors against the calibration error, band coverage, energy error."""
    worst = table.loc[table["nrmse"].idxmax()]
    reading = (
        f"{best}, calibrated on protocol 1 only, predicts the held-out {SYNTHETIC} protocols 2-4 with "
        f"NRMSE between {pct(table['nrmse'].min())} and {pct(table['nrmse'].max())}; the hardest is "
        f"{worst['test']}"
    )
    if cal_nrmse is not None:
        ratio = float(table["nrmse"].mean()) / cal_nrmse
        reading += (f", and on average the error is {fmt(ratio, 2)} times the calibration error "
                    f"({pct(cal_nrmse)})")
    lo, hi = float(table["coverage"].min()), float(table["coverage"].max())
    reading += (
        f". The 95 % band holds {pct(lo)} to {pct(hi)} of the held-out points: "
        + ("about the nominal 95 %, so the uncertainty is honest." if lo >= 0.9 else
           "below the nominal 95 %, so the law misses something the held-out tests show (see the gap "
           "step).")
    )
    e = table[table["cycles"] > 0]
    if len(e):
        err = (e["energy_map_kNm"] - e["energy_test_kNm"]) / e["energy_test_kNm"]
        k = int(np.argmax(np.abs(err.to_numpy())))
        reading += (f" The MAP {'over' if err.iloc[k] > 0 else 'under'}estimates the energy dissipated "
                    f"in {e['test'].iloc[k]} by {pct(abs(err.iloc[k]))}.")
    return reading


def gap_reading(rep: Any, best: str) -> str:
    """Step 5: the baseline's gap, where it sits, the diagnosis and how far it shrinks the gap."""
    b_cal, b_hold = rep.baseline
    f_cal, f_hold = rep.final
    top = rep.where.iloc[0] if len(rep.where) else None
    reading = f"Baseline {best} on protocol 1 ({SYNTHETIC}): gap (NRMSE) {pct(b_cal.gap)}, of which the " \
              f"systematic part is {pct(b_cal.systematic)}"
    if b_hold is not None:
        reading += f"; on the held-out protocols 2-4 the gap is {pct(b_hold.gap)}"
    reading += "."
    if top is not None:
        reading += (f" The residuals concentrate in the {top['axis']} segment '{top['segment']}' "
                    f"({pct(top['error_share'])} of the squared error, {fmt(top['rms_over_noise'], 3)} "
                    f"times the noise level).")
    reading += " " + verdict_text(rep)
    if rep.combination:
        winner = next(e for e in rep.ranking if e.effect == rep.combination[0])
        if math.isfinite(winner.shrink_holdout):
            reading += f" It shrinks the held-out systematic gap by {pct(winner.shrink_holdout)}."
        reading += f" With it the calibration gap goes from {pct(b_cal.gap)} to {pct(f_cal.gap)}"
        if b_hold is not None and f_hold is not None:
            reading += f" and the held-out gap from {pct(b_hold.gap)} to {pct(f_hold.gap)}"
        reading += "."
    return reading


def propagation_reading(rs: Any, summary: pd.DataFrame, exceed: pd.DataFrame, split: pd.DataFrame,
                        *, building: str, count: int, law: str, scale: float) -> str:
    """Step 6: median and spread of the peak isolator displacement, drift, exceedance, variance split."""
    row = summary[(summary["demand"] == "iso_disp_peak_m") & (summary["record"] == "all records")
                  & (summary["scale"] == scale)].iloc[0]
    drift = summary[(summary["demand"] == "drift_ratio_max") & (summary["record"] == "all records")
                    & (summary["scale"] == scale)].iloc[0]
    per_rec = summary[(summary["demand"] == "iso_disp_peak_m") & (summary["record"] != "all records")
                      & (summary["scale"] == scale)]
    worst_rec = per_rec.loc[per_rec["median"].idxmax()]
    lim = rs.limits.get("iso_disp_peak_m")
    p_ex = exceed[(exceed["demand"] == "iso_disp_peak_m") & (exceed["record"] == "all records")
                  & (exceed["scale"] == scale)]["p_exceed"]
    sp = split[(split["demand"] == "iso_disp_peak_m") & (split["scale"] == scale)]["share_params"]
    n_conv = int(rs.table["converged"].astype(bool).sum())
    reading = (
        f"{len(rs.table)} analyses of the {building.replace('_', '-')} example building with its "
        f"{count} bearings following the {law} posterior ({n_conv} converged). With the records as "
        f"recorded the peak isolator displacement has a median of {fmt(1e3 * row['median'], 3)} mm "
        f"over all records (16-84 %: {fmt(1e3 * row['p16'], 3)}-{fmt(1e3 * row['p84'], 3)} mm); "
        f"{worst_rec['record']} drives it hardest (median {fmt(1e3 * worst_rec['median'], 3)} mm). "
        f"The median peak story drift ratio is {pct(drift['median'])}."
    )
    if lim is not None and len(p_ex):
        pe = float(p_ex.iloc[0])
        beyond = f"beyond {fmt(1e3 * lim, 3)} mm (the largest displacement tested, at prototype scale)"
        reading += (f" None of the runs takes the isolator {beyond}" if pe == 0 else
                    f" The chance that the isolator goes {beyond} is {pct(pe)}")
        ext = rs.extrapolated_share()
        reading += (f"; {pct(ext)} of the runs leave the calibrated range, where the law extrapolates."
                    if np.isfinite(ext) else ".")
    if len(sp) and np.isfinite(sp.iloc[0]):
        reading += (f" The isolator parameters explain {pct(float(sp.iloc[0]))} of the variance of the "
                    f"log peak isolator displacement; the records explain most of the rest"
                    if float(sp.iloc[0]) < 0.5 else
                    f" The isolator parameters explain {pct(float(sp.iloc[0]))} of the variance of the "
                    f"log peak isolator displacement, more than the records")
        reading += " (law of total variance)."
    return reading


def fragility_reading(msa: Any, frs: list) -> str:
    """Step 6, fragility: the IM and its stripes, the fitted median and beta per limit, the span."""
    lv, rim = msa.levels, msa.record_im
    rs = msa.responses
    n_draws = len(rs.draws)
    text = (
        f"Fragility by multiple stripe analysis: the {len(rim)} records were scaled to {len(lv)} stripes "
        f"of {msa.im.label.removesuffix(' [g]')} from {fmt(min(lv), 3)} to {fmt(max(lv), 3)} g (the records "
        f"as recorded have {fmt(min(rim.values()), 3)} to {fmt(max(rim.values()), 3)} g), and {n_draws} "
        f"posterior draws ran on every scaled record; the lognormal curves are fitted by maximum likelihood "
        f"over the stripe counts (Baker 2015)."
    )
    for f in frs:
        share = np.divide(f.z, f.n)
        lo, hi = float(share[int(np.argmin(f.im))]), float(share[int(np.argmax(f.im))])
        if f.demand == "iso_disp_peak_m":
            what = f"the isolator goes beyond {fmt(1e3 * f.limit, 3)} mm (the largest tested displacement)"
        elif f.demand == "drift_ratio_max":
            what = f"the largest story drift ratio exceeds {pct(f.limit)}"
        else:
            what = f"{f.demand} exceeds {fmt(f.limit, 3)}"
        if math.isfinite(f.theta):
            text += (f" Half of the runs: {what} at {msa.im.name} = {fmt(f.theta, 3)} g (beta "
                     f"{fmt(f.beta, 2)}); {pct(lo)} of the runs at the lowest stripe and {pct(hi)} at the "
                     "highest.")
            if lo > 0.2 or hi < 0.8:
                text += " The stripes do not span the whole curve: beyond them it is extrapolated."
            if f.note:
                text += f" Note: {f.note}."
        else:
            text += f" {what[0].upper()}{what[1:]}: no curve ({f.note}, up to {fmt(max(lv), 3)} g)."
    return text


def orbit_reading(ans: Any, pair: str) -> str:
    """Step 6, both components at once: the plan displacement against each direction's."""
    per = ans.per_pair[ans.per_pair["bound"] == "nominal"].iloc[0]
    plan, dx, dy = per["plan_disp_max_m"], per["disp_x_max_m"], per["disp_y_max_m"]
    gov = ans.design().loc["governing"]
    return (
        f"Under both components of the {pair} pair at once (the plan building, the isolator's coupled "
        f"law) the isolator reaches {fmt(1e3 * plan, 3)} mm in plan (the vector sum at each instant), "
        f"while its largest x and y displacements are {fmt(1e3 * dx, 3)} and {fmt(1e3 * dy, 3)} mm: "
        f"{pct(plan / max(dx, dy) - 1.0)} more than the larger direction alone; over the nominal and "
        f"the two bound isolators the governing design displacement is "
        f"{fmt(1e3 * ans.design_displacement, 3)} mm (the circle of the orbit plot), the base shear "
        f"{fmt(gov['base_shear_x_max_kN'], 3)} kN in x and {fmt(gov['base_shear_y_max_kN'], 3)} kN in y. "
        "No torsion is modelled: the total maximum displacement is the plan displacement at the centre."
    )


def shake_table_reading(res: Any, *, quick: bool, budget_s: float | None = None) -> str:
    """Step 7: the real building: extrapolation, diagnosis with its evidence, gap before and after,
    the held-out peaks (an unconservative one called so); ``budget_s``: the step's time budget [s]."""
    rep = res.report
    ratio = max(res.extrapolation.values()) if res.extrapolation else float("nan")
    text = (
        f"REAL data: the BNCS 5-story building on isolators. The building (superstructure identified on "
        f"{res.identified_on}, isolator law {res.law}) was calibrated by output error on "
        f"{', '.join(res.calibrate)}; {', '.join(res.holdout)} takes the isolators to {fmt(ratio, 3)} "
        "times the "
        f"largest calibrated displacement ({fmt(res.calibrated_peak, 3)} m)."
    )
    text += " On the simulated building: " + verdict_text(rep)
    if res.holdout:
        hb, ha = res.gap_before["holdout"], res.gap_after["holdout"]
        sh = res.shrink()["isolator_disp"]
        text += (f" In the building, the held-out isolator-displacement NRMSE goes from "
                 f"{pct(hb['isolator_disp'])} to {pct(ha['isolator_disp'])} (shrink {pct(sh)}; goal 50 %) "
                 f"and the roof acceleration from "
                 f"{pct(hb['roof_accel'])} to {pct(ha['roof_accel'])}; the predictive 95 % band covers "
                 f"{pct(res.coverage['isolator_disp'])} of the held-out isolator displacements (goal 80 %).")
        if not sh >= 0.5:
            text += (" The goal is not met: beyond the calibrated range the law follows its form, not data, "
                     "and the model drifts out of phase with the measurement over the long record.")
        text += " " + peaks_text(res)  # the shake-table report's own sentence
    if quick:
        text += (" QUICK run: one calibration run, a closed-form law, four effects (rate, mullins, "
                 "scragging, stiffening)"
                 + (f" and a {budget_s:g} s budget." if budget_s is not None else "."))
    return text


def rubber_reading(table: pd.DataFrame, fits: dict[str, Any], *, noise: float, mu_err: float,
                   p2_name: str, vhb_name: str, quick: bool) -> str:
    """Step 7: misfit and identifiability of the PRF fits, cross-prediction, the real VHB 4910 fit."""
    def rms(fit_label: str, test_name: str) -> float:
        row = table[(table["fit"] == fit_label) & (table["evaluated_on"] == test_name)]
        return float(row["rms_error"].iloc[0])

    both = fits["both protocols"]
    both_rms = math.sqrt(both.f_total / len(both.f))
    unident = sorted(n for n, v in both.rel_sigma.items() if v is not None and v > 1)
    reading = (
        f"The polyurethane (PRF) model fitted to both {SYNTHETIC} protocols (made from preset A with "
        f"{fmt(noise)} MPa noise) misfits them by {pct(both_rms)} RMS; its small-strain chain moduli are "
        f"within {pct(mu_err)} of the truth"
    )
    reading += (f", while {', '.join(unident)} {'is' if len(unident) == 1 else 'are'} practically "
                "unidentifiable from these data." if unident else ".")
    if "protocol 1" in fits:
        cross = rms("protocol 1", p2_name) / max(rms("protocol 2", p2_name), 1e-300)
        reading += (f" Fitted to protocol 1 alone, it predicts protocol 2 with {fmt(cross, 3)} times the "
                    f"RMS error of a fit to protocol 2 itself.")
    reading += (f" On the real VHB 4910 data (Miles et al.) the fit reaches an RMS misfit of "
                f"{pct(rms('VHB 4910 (real)', vhb_name))}.")
    if quick:
        reading += " (Quick run: one short CMA-ES run per fit.)"
    return reading
