"""Posterior predictive checks of a calibration on its own test or on held-out tests.

:func:`predict` drives posterior draws along a test's displacement history and returns
:class:`Prediction`:

* 95 % bands: parameter uncertainty only (quantiles of the model force over draws) and with
  noise (each draw plus a residual history from its noise model);
* ``coverage``: fraction of measured forces inside the band with noise (about 0.95 when the
  model is right); ``nrmse = RMS(F_measured - F_mean) / RMS(F_measured)`` for the posterior-mean
  prediction (``nrmse_map`` for the MAP);
* per full cycle (cycles from :func:`rrfrei.energy.cycle_metrics`): dissipated energy EDC,
  effective stiffness k_eff and effective damping beta_eff of the test, of the MAP and the 95 %
  band over draws; cumulative dissipated energy of the test and the MAP;
* the ASCE/SEI 7-22 prototype-test acceptance rules, applied to the test and to the MAP.

ASCE/SEI 7-22 Section 17.8.4 (Test Specimen Adequacy), as implemented here for one specimen
(cycles grouped by amplitude, consecutive full cycles whose amplitudes agree within 5 %):

* item 2: for each amplitude group with >= 2 cycles, the effective stiffness of every cycle
  differs from the group's average by no more than 15 %;
* item 3: over the cycles of a group, the effective stiffness changes by no more than 20 % from
  that of the group's first cycle;
* item 4: over the cycles of a group, the energy dissipated per cycle (EDC, the area of the
  loop) decreases by no more than 20 % from that of the group's first cycle.

Items 1 (positive incremental force capacity) and 5 (stability under vertical load) and the
between-specimen rule are not judged (one specimen, no vertical-load variation in the data).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from rrfrei.io import ShearTest

__all__ = ["Prediction", "predict", "asce_7_22_checks", "nrmse", "coverage"]

LEVEL = 0.95


def nrmse(measured: np.ndarray, predicted: np.ndarray) -> float:
    """RMS(measured - predicted) / RMS(measured)."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    return float(np.sqrt(np.mean((m - p) ** 2)) / np.sqrt(np.mean(m**2)))


def coverage(measured: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Fraction of ``measured`` inside [lower, upper]."""
    m = np.asarray(measured, dtype=float)
    return float(np.mean((m >= lower) & (m <= upper)))


def _cycle_metrics(disp: np.ndarray, force: np.ndarray) -> pd.DataFrame:
    from rrfrei.energy import cycle_metrics

    return cycle_metrics(disp, force)


def _cumulative(disp: np.ndarray, force: np.ndarray) -> np.ndarray:
    from rrfrei.energy import dissipated_energy

    return np.asarray(dissipated_energy(disp, force), dtype=float)


@dataclass(frozen=True, eq=False)
class Prediction:
    """Posterior predictive check of one test (forces in kN, energies in kN m)."""

    law: str
    test: ShearTest
    mean: np.ndarray
    map: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lower_param: np.ndarray
    upper_param: np.ndarray
    coverage: float
    coverage_param: float
    nrmse: float
    nrmse_map: float
    cycles: pd.DataFrame
    cumulative_test: np.ndarray
    cumulative_map: np.ndarray
    asce: pd.DataFrame
    n_draws: int
    extrapolation: tuple = ()
    """Where ``test`` leaves the calibration test's displacement range
    (:class:`rrfrei.extrapolation.Extrapolation` records; each also issued as a warning)."""
    failed_draws: int = 0
    meta: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Scalars for JSON: nrmse, nrmse_map, coverage, coverage_param, energy error of the MAP."""
        e_t = float(self.cycles["energy_test"].sum()) if len(self.cycles) else float("nan")
        e_m = float(self.cycles["energy_map"].sum()) if len(self.cycles) else float("nan")
        return {
            "extrapolation": [e.as_dict() for e in self.extrapolation],
            "nrmse": self.nrmse, "nrmse_map": self.nrmse_map, "coverage": self.coverage,
            "coverage_param": self.coverage_param, "energy_test": e_t, "energy_map": e_m,
            "n_draws": self.n_draws, "failed_draws": self.failed_draws,
        }


def predict(calibration, test: ShearTest, *, n: int = 200, seed: int = 0, level: float = LEVEL) -> Prediction:
    """Posterior predictive check of ``calibration`` on ``test`` (its own or a held-out one).

    Parameters
    ----------
    calibration : a :class:`~rrfrei.calibration.Calibration` (or anything
        :func:`~rrfrei.calibration.posterior_draws` accepts that carries sigma).
    test : the test to predict; its displacement history drives the law.
    n : posterior draws used for the bands.
    seed : seed of the draws and of the simulated noise.
    level : band probability (default 0.95).
    """
    from rrfrei.calibration.likelihood import law_forces
    from rrfrei.calibration.noise import noise_model
    from rrfrei.calibration.results import _as_calibration
    from rrfrei.extrapolation import beyond, warn

    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level}")
    cal = _as_calibration(calibration)
    spec = cal.spec
    noise = noise_model(cal.noise)
    df = cal.draws(n, seed, noise=True)
    P = np.ascontiguousarray(df[list(spec.param_names)].to_numpy(float))
    F, status = law_forces(spec, P, test)
    ok = status == 0
    if not ok.any():
        raise ValueError(f"law {cal.law!r} failed along test {test.name!r} for every posterior draw")
    F = F[ok]
    rng = np.random.default_rng(seed + 1)
    Fn = F + noise.simulate(rng, df[list(noise.params)].to_numpy(float)[ok], F.shape[1])
    a = (1 - level) / 2
    lo_p, hi_p = np.quantile(F, [a, 1 - a], axis=0)
    lo, hi = np.quantile(Fn, [a, 1 - a], axis=0)
    mean = F.mean(axis=0)
    Fmap, st = law_forces(spec, spec.pack(cal.map_params())[None, :], test)
    if st[0] != 0:
        raise ValueError(f"law {cal.law!r} at its MAP failed along test {test.name!r}")
    fmap = Fmap[0]
    obs = np.asarray(test.force)
    cyc = _cycle_table(test, fmap, F, a)
    asce = pd.concat(
        [asce_7_22_checks(_cycle_metrics(test.disp, obs)).assign(source="test"),
         asce_7_22_checks(_cycle_metrics(test.disp, fmap)).assign(source="MAP")],
        ignore_index=True,
    )
    ext = tuple(beyond(test.name, "displacement", test.disp, (cal.test.disp.min(), cal.test.disp.max()),
                       unit="m", what=f"the displacement range of the calibration test {cal.test.name!r}"))
    warn(ext)
    return Prediction(
        extrapolation=ext,
        law=cal.law, test=test, mean=mean, map=fmap, lower=lo, upper=hi, lower_param=lo_p,
        upper_param=hi_p, coverage=coverage(obs, lo, hi), coverage_param=coverage(obs, lo_p, hi_p),
        nrmse=nrmse(obs, mean), nrmse_map=nrmse(obs, fmap), cycles=cyc,
        cumulative_test=_cumulative(test.disp, obs), cumulative_map=_cumulative(test.disp, fmap),
        asce=asce, n_draws=int(ok.sum()), failed_draws=int((~ok).sum()),
        meta={"level": level, "calibrated_on": cal.test.name,
              "calibrated_disp_range_m": [float(cal.test.disp.min()), float(cal.test.disp.max())]},
    )


def _cycle_table(test: ShearTest, fmap: np.ndarray, F: np.ndarray, a: float) -> pd.DataFrame:
    mt = _cycle_metrics(test.disp, test.force)
    mm = _cycle_metrics(test.disp, fmap)
    out = pd.DataFrame({"cycle": np.arange(len(mt))})
    keys = ("energy", "k_eff", "beta_eff")
    for k in keys:
        out[f"{k}_test"] = mt[k].to_numpy(float)
        out[f"{k}_map"] = mm[k].to_numpy(float) if len(mm) == len(mt) else np.nan
    if len(mt):
        from rrfrei.energy import cycle_metrics_batch

        per = cycle_metrics_batch(test.disp, F)  # the test's cycles: they depend on disp only
        for k in keys:
            out[f"{k}_lo"] = np.nanquantile(per[k], a, axis=0)
            out[f"{k}_hi"] = np.nanquantile(per[k], 1 - a, axis=0)
    for c in mt.columns:
        if c not in keys and c not in out.columns and c != "cycle":
            out[c] = mt[c].to_numpy()
    return out


def _amplitudes(m: pd.DataFrame) -> np.ndarray:
    for lo, hi in (("d_neg", "d_pos"), ("disp_min", "disp_max")):
        if lo in m.columns and hi in m.columns:
            return (m[hi].to_numpy(float) - m[lo].to_numpy(float)) / 2
    for c in ("amplitude", "disp_amplitude"):
        if c in m.columns:
            return m[c].to_numpy(float)
    raise ValueError(f"cycle metrics lack amplitude columns; columns are {list(m.columns)}")


def asce_7_22_checks(metrics: pd.DataFrame, *, tol_group: float = 0.05) -> pd.DataFrame:
    """ASCE/SEI 7-22 Section 17.8.4 items 2-4 per amplitude group (rules in the module docstring).

    ``metrics`` is a :func:`rrfrei.energy.cycle_metrics` table (energy, k_eff and amplitude per
    full cycle).  One row per group: amplitude, cycles, the largest deviations and pass flags.
    """
    cols = ["group", "amplitude_m", "cycles", "keff_dev_from_mean", "keff_change_from_first",
            "edc_decrease_from_first", "item2_keff_15pct", "item3_keff_20pct", "item4_edc_20pct"]
    if len(metrics) == 0:
        return pd.DataFrame(columns=cols)
    amp = _amplitudes(metrics)
    k = metrics["k_eff"].to_numpy(float)
    e = metrics["energy"].to_numpy(float)
    groups: list[list[int]] = [[0]]
    for i in range(1, len(amp)):
        ref = amp[groups[-1][0]]
        if abs(amp[i] - ref) <= tol_group * abs(ref):
            groups[-1].append(i)
        else:
            groups.append([i])
    rows = []
    for g, idx in enumerate(groups):
        kk, ee = k[idx], e[idx]
        dev = float(np.max(np.abs(kk - kk.mean()) / abs(kk.mean()))) if len(idx) > 1 else 0.0
        chg = float(np.max(np.abs(kk - kk[0]) / abs(kk[0])))
        dec = float(max(0.0, np.max((ee[0] - ee) / abs(ee[0])))) if ee[0] != 0 else 0.0
        rows.append({
            "group": g, "amplitude_m": float(np.mean(amp[idx])), "cycles": len(idx),
            "keff_dev_from_mean": dev, "keff_change_from_first": chg, "edc_decrease_from_first": dec,
            "item2_keff_15pct": bool(dev <= 0.15), "item3_keff_20pct": bool(chg <= 0.20),
            "item4_edc_20pct": bool(dec <= 0.20),
        })
    return pd.DataFrame(rows, columns=cols)
