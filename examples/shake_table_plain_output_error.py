"""A plain output-error fit of the BNCS building, beside what :class:`BuildingModel` gets.

The check of issue 27: does the pipeline's output-error calibration reach what a plain least-
squares fit of the simulated building reaches?  Both use the project's public API and the same
simulation (:func:`structures.shake_table.simulation.simulate`: the identified superstructure, the
isolator law, the runs in order with their state carried):

* **plain**: ``scipy.optimize.least_squares`` (trust-region reflective, the law's own bounds,
  parameters scaled by their start) of the simulated minus measured isolator displacement only,
  from the isolator loop fit (rate effect neutral), 200 evaluations at most;
* **plain, three channels**: the same, on the isolator displacement, isolation-layer force and
  roof acceleration, each over its RMS;
* **BuildingModel**: the pipeline's fit of ``law+rate`` from the loop fit, and its refit from
  the fitted baseline building (what the diagnosis does for every candidate).

Prints, for the held-out run, the isolator-displacement NRMSE and peak error and the CPU seconds.

Run: ``python examples/shake_table_plain_output_error.py [--calibrate CNP100,LAC100,ICA50]
[--holdout ICA100] [--law bouc_wen] [--effect rate]``.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.optimize import least_squares

from rrfrei.calibration.checks import nrmse
from rrfrei.gap.model import IsolatorModel
from structures.shake_table.building_model import BuildingModel
from structures.shake_table.gap import BNCS_ORDER, resolve_run
from structures.shake_table.identify import identify_superstructure
from structures.shake_table.sequence import CHANNELS
from structures.shake_table.simulation import BuildingData, Superstructure, calibration_test, simulate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calibrate", default="CNP100,LAC100,ICA50")
    ap.add_argument("--holdout", default="ICA100")
    ap.add_argument("--law", default="bouc_wen")
    ap.add_argument("--effect", default="rate")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    cal_names = args.calibrate.split(",")
    runs = {n: resolve_run(n) for n in BNCS_ORDER}
    order = [n for n in BNCS_ORDER if n in cal_names or n == args.holdout]
    seq = tuple(runs[n] for n in order)
    cal = BuildingData(seq, observed=tuple(cal_names))
    held = BuildingData(seq, observed=(args.holdout,))
    # the superstructure: the calibration run whose worst story fits best
    idents = [identify_superstructure(runs[n], seed=args.seed, n_boot=20) for n in cal_names]
    ident = max(idents, key=lambda i: float(np.min(i.r2)))
    sup = Superstructure.of(ident)
    test = calibration_test([runs[n] for n in cal_names], 25.0)
    loop = IsolatorModel(args.law, draws=20).fit(test, seed=args.seed)
    scales = {c: float(np.sqrt(np.mean(np.concatenate([cal.measured(n)[c] for n in cal_names]) ** 2)))
              for c in CHANNELS}
    a_ref = max(cal.peak_table_accel(n) for n in cal_names)
    law = f"{args.law}+{args.effect}"
    model = BuildingModel(law, sup, test, scales, loop_fit=loop, a_ref=a_ref)
    spec = model.spec
    lay = model.layout
    s_vec, lb, ub = model.scaled_bounds()
    start = {**loop.params, "k_scale": 1.0, "zeta": sup.zeta}
    x0 = np.array([start.get(n, 0.0) for n in lay.names])
    print(f"superstructure identified on {ident.run}; law {law}; free: {', '.join(lay.names)}")

    def held_out(x) -> str:
        v = dict(zip(lay.names, x))
        st, out = simulate(spec, lay.law_vector(v), sup, held, k_scale=v["k_scale"], zeta=v["zeta"])
        if st != 0:
            return f"held-out simulation failed (status {st})"
        m, p = held.measured(args.holdout)["isolator_disp"], out[args.holdout]["isolator_disp"]
        peak = float(np.max(np.abs(p)) / np.max(np.abs(m)) - 1.0)
        return f"held-out {args.holdout} isolator disp. NRMSE {nrmse(m, p):.3f}, peak {peak:+.1%}"

    def plain(channels) -> tuple[np.ndarray, float]:
        y = np.concatenate([cal.measured(o)[c] / scales[c] for o in cal.observed for c in channels])

        def resid(z):
            v = dict(zip(lay.names, z * s_vec))
            st, out = simulate(spec, lay.law_vector(v), sup, cal, k_scale=v["k_scale"], zeta=v["zeta"])
            if st != 0:
                return np.full(y.size, 10.0)
            return np.concatenate([out[o][c] / scales[c] for o in cal.observed for c in channels]) - y

        t0 = time.process_time()
        z0 = np.clip(x0 / s_vec, lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
        r = least_squares(resid, z0, bounds=(lb, ub), method="trf", max_nfev=200, diff_step=1e-3)
        return r.x * s_vec, time.process_time() - t0

    x, cpu = plain(("isolator_disp",))
    print(f"plain least squares, isolator displacement: {held_out(x)} ({cpu:.0f} s CPU)")
    x, cpu = plain(("isolator_disp", "isolator_force", "roof_accel"))
    print(f"plain least squares, three channels:        {held_out(x)} ({cpu:.0f} s CPU)")
    t0 = time.process_time()
    fit = model.fit(cal, seed=args.seed)
    print(f"BuildingModel({law}) from the loop fit:     {held_out(fit.x_opt)} "
          f"({time.process_time() - t0:.0f} s CPU, {fit.nfev} simulations)")
    t0 = time.process_time()
    base_model = BuildingModel(args.law, sup, test, scales, loop_fit=loop, a_ref=a_ref)
    base = base_model.fit(cal, seed=args.seed)
    refit = model.fit(cal, seed=args.seed, start=[base])
    print(f"BuildingModel({law}) refit from the baseline: {held_out(refit.x_opt)} "
          f"({time.process_time() - t0:.0f} s CPU for baseline and refit)")


if __name__ == "__main__":
    main()
