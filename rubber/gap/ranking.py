"""Which catalogue effect closes the gap of a PRF model fitted by optimisation: :func:`rank_effects`.

Rule: an effect is accepted when it lowers BIC on the calibration data by more than
:data:`MARGIN` and lowers the pooled held-out NRMSE; the diagnosis is the accepted effect with the
lowest held-out NRMSE, else ``"none"``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rrfrei.gap.model import white_noise
from rrfrei.gap.residuals import gap, systematic_gap
from rrfrei.jsonable import number as _num
from rubber.gap.effects import EFFECTS
from rubber.gap.model import RubberFit, RubberModel, _tests

__all__ = ["CRITERION", "MARGIN", "EffectRow", "RubberGapReport", "rank_effects"]

CRITERION = "BIC"
MARGIN = 10.0
"""An effect must lower BIC by more than this (Kass & Raftery 1995: Delta BIC > 10 is 'very strong')."""


@dataclass(frozen=True)
class EffectRow:
    """One effect's augmented fit against the baseline (gaps as NRMSE, pooled)."""

    effect: str
    model: str
    delta_bic: float
    holdout_before: float
    holdout_after: float
    systematic_calibration_before: float
    systematic_calibration_after: float
    systematic_holdout_before: float
    systematic_holdout_after: float
    shrink_calibration: float
    shrink_holdout: float
    accepted: bool
    params: dict

    def as_dict(self) -> dict:
        return {k: (_num(v) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class RubberGapReport:
    """Result of :func:`rank_effects`: diagnosis (effect name or ``none``), per-effect rows, gaps."""

    model: str
    diagnosis: str
    criterion: str
    margin: float
    rows: tuple[EffectRow, ...]
    gap_before: tuple[float, float]  # (calibration, held-out) NRMSE of the baseline
    gap_after: tuple[float, float]   # the same for the diagnosed effect (= before for "none")
    noise: tuple[float, float]       # noise level (MPa) on calibration and held-out data
    fits: dict = field(default_factory=dict, repr=False, compare=False)

    def as_dict(self) -> dict:
        return {"model": self.model, "diagnosis": self.diagnosis, "criterion": self.criterion,
                "margin": self.margin, "rows": [r.as_dict() for r in self.rows],
                "gap_before": {"calibration": _num(self.gap_before[0]), "holdout": _num(self.gap_before[1])},
                "gap_after": {"calibration": _num(self.gap_after[0]), "holdout": _num(self.gap_after[1])},
                "noise_MPa": {"calibration": _num(self.noise[0]), "holdout": _num(self.noise[1])}}

    def table(self) -> str:
        """Markdown table of the ranking (best held-out error first) and the diagnosis."""
        lines = [f"Diagnosis: **{self.diagnosis}** (rule: Delta {self.criterion} < -{self.margin:g} on the "
                 "calibration data and lower held-out NRMSE)", "",
                 f"Gap (NRMSE) before: calibration {self.gap_before[0]:.4f}, "
                 f"held-out {self.gap_before[1]:.4f}; "
                 f"after: calibration {self.gap_after[0]:.4f}, held-out {self.gap_after[1]:.4f}", "",
                 f"| effect | Delta {self.criterion} | held-out NRMSE before | after | systematic cal. "
                 "before | after | systematic held-out before | after | shrink cal. | shrink held-out "
                 "| accepted |",
                 "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows:
            lines.append(f"| {r.effect} | {r.delta_bic:.1f} | {r.holdout_before:.4f} | "
                         f"{r.holdout_after:.4f} | "
                         f"{r.systematic_calibration_before:.4f} | {r.systematic_calibration_after:.4f} | "
                         f"{r.systematic_holdout_before:.4f} | {r.systematic_holdout_after:.4f} | "
                         f"{r.shrink_calibration:.2f} | {r.shrink_holdout:.2f} | "
                         f"{'yes' if r.accepted else 'no'} |")
        return "\n".join(lines)


def _shrink(before: float, after: float) -> float:
    return 1.0 - after / before if before > 0 else float("nan")


def rank_effects(model: RubberModel, data, holdout, *, effects: Sequence[str] | None = None, seed: int = 0,
                 margin: float = MARGIN) -> RubberGapReport:
    """Which catalogue effect closes the gap of a PRF model fitted by optimisation (no posterior).

    Steps: fit the baseline on the calibration tests ``data``; refit each effect's augmented model
    from the baseline optimum; score each on the calibration data by BIC and on the held-out tests
    ``holdout`` (protocols not used for fitting) by the pooled NRMSE.

    Rule: an effect is *accepted* when it lowers BIC on the calibration data by more than ``margin``
    (default 10, "very strong" evidence on the Kass & Raftery 1995 scale) AND lowers the pooled
    held-out NRMSE.  The diagnosis is the accepted effect with the lowest held-out NRMSE, else
    ``"none"``.  BIC rather than AIC because the question is which effect is present (BIC is
    consistent for selecting the true model, AIC aims at prediction, which the held-out error
    already measures); its likelihood is Gaussian with sd proportional to each test's RMS stress
    (the weighting of :func:`rubber.objective`), sd profiled out, so BIC = n ln(RSS/n) + k ln n.
    Residuals of a misfit are autocorrelated, which makes BIC overstate the evidence: that is why
    the held-out error must agree.

    Parameters
    ----------
    model : the baseline :class:`RubberModel` (no effects).
    data : calibration Test or list of Tests; holdout : one or more held-out Tests.
    effects : catalogue effects to try (default all of :data:`EFFECTS`).
    seed : seeds the baseline's CMA-ES search.
    margin : BIC margin of the rule.

    Returns
    -------
    RubberGapReport (rows ordered by held-out NRMSE after, lowest first).
    """
    if not isinstance(model, RubberModel) or model.effects:
        raise ValueError(f"model = {getattr(model, 'name', model)!r}: expected a RubberModel without effects")
    cal = _tests(data)
    hos = _tests(holdout)
    effects = list(EFFECTS) if effects is None else list(effects)
    for e in effects:
        if e not in EFFECTS:
            raise ValueError(f"effect {e!r}: expected one of {sorted(EFFECTS)}")
    if not (isinstance(margin, (int, float)) and margin >= 0):
        raise ValueError(f"margin = {margin!r}: expected a number >= 0")
    base = model.fit(cal, seed=seed)
    y_cal, y_ho = model.observed(cal), model.observed(hos)

    def noise_of(tests):
        return float(np.sqrt(np.mean([white_noise(t.stress - base.stress(t)) ** 2 for t in tests])))

    sig_cal, sig_ho = noise_of(cal), noise_of(hos)
    f_cal, f_ho = base.stress(cal), base.stress(hos)
    g0 = (gap(y_cal, f_cal), gap(y_ho, f_ho))
    s0 = (systematic_gap(y_cal, f_cal, sig_cal), systematic_gap(y_ho, f_ho, sig_ho))
    fits: dict[str, RubberFit] = {base.name: base}
    rows = []
    for e in effects:
        fit = model.augment([e]).fit(cal, seed=seed, start=base)
        fits[fit.name] = fit
        a_cal, a_ho = fit.stress(cal), fit.stress(hos)
        h1 = gap(y_ho, a_ho)
        s1 = (systematic_gap(y_cal, a_cal, sig_cal), systematic_gap(y_ho, a_ho, sig_ho))
        dbic = fit.bic - base.bic
        rows.append(EffectRow(
            effect=e, model=fit.name, delta_bic=float(dbic), holdout_before=g0[1], holdout_after=h1,
            systematic_calibration_before=s0[0], systematic_calibration_after=s1[0],
            systematic_holdout_before=s0[1], systematic_holdout_after=s1[1],
            shrink_calibration=_shrink(s0[0], s1[0]), shrink_holdout=_shrink(s0[1], s1[1]),
            accepted=bool(dbic < -margin and h1 < g0[1]), params=dict(fit.effect_params)))
    rows.sort(key=lambda r: r.holdout_after)
    ok = [r for r in rows if r.accepted]
    diagnosis = ok[0].effect if ok else "none"
    g1 = g0 if not ok else (gap(y_cal, fits[ok[0].model].stress(cal)), ok[0].holdout_after)
    return RubberGapReport(model=base.name, diagnosis=diagnosis, criterion=CRITERION, margin=float(margin),
                           rows=tuple(rows), gap_before=g0, gap_after=g1, noise=(sig_cal, sig_ho), fits=fits)
