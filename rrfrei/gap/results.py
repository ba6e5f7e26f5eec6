"""What the gap engine (:func:`rrfrei.gap.diagnose.diagnose`) returns: the :class:`GapReport`, each
effect's :class:`EffectScore` against its reference, and the pooled :class:`Metrics` of a fit."""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from rrfrei.gap import decision as dec
from rrfrei.jsonable import number as _num
from rrfrei.notes import as_dicts, ordered

__all__ = ["EffectScore", "GapReport", "Metrics"]


@dataclass(frozen=True)
class Metrics:
    """Gap, its systematic part, energy-per-cycle error and band coverage (pooled)."""

    gap: float
    systematic: float
    energy_error: float
    coverage: float

    def as_dict(self) -> dict:
        return {k: _num(v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class EffectScore:
    """One effect (or combination step) against its reference model."""

    effect: str
    law: str
    screen: float
    delta_elpd: float
    se: float
    delta_holdout: float
    se_holdout: float
    calibration: Metrics
    holdout: Metrics | None
    shrink_calibration: float
    shrink_holdout: float
    significant: bool
    """The effect passes the decision rule (:mod:`rrfrei.gap.decision`) against its reference;
    whether it is *named* is the report's verdict (a passing effect can be tied or not combined)."""
    params: dict
    note: str = ""
    blocks_calibration: dec.RankEvidence | None = None
    """Sign and signed-rank tests of the leave-one-block-out elpd gains on the calibration test."""
    blocks_holdout: dec.RankEvidence | None = None
    """The same over the held-out blocks' squared-error reductions (None without held-out data)."""
    shrink_ci: dec.ShrinkEvidence | None = None
    """Systematic-gap shrink with its block-bootstrap interval: pooled over the held-out tests, or
    on the calibration test when there are none."""
    why: str = ""
    """The decision rule's reading in one line (why it passes or what fails)."""
    variant: str = ""
    """The variant of the effect that was fitted ("": the primary fit,
    :class:`rrfrei.laws.effects.Variant`)."""

    @property
    def label(self) -> str:
        """The effect's name, with its variant in parentheses when one was fitted."""
        return f"{self.effect} ({self.variant})" if self.variant else self.effect

    def evidence(self) -> dict:
        """The decision rule's numbers (JSON-ready)."""
        def d(x):
            return None if x is None else x.as_dict()

        return {"calibration_blocks": d(self.blocks_calibration), "holdout_blocks": d(self.blocks_holdout),
                "shrink": d(self.shrink_ci),
                "shrink_on": "holdout" if self.blocks_holdout is not None else "calibration",
                "passes_rule": self.significant, "why": self.why}

    def as_dict(self) -> dict:
        return {
            "effect": self.effect, "variant": self.variant, "law": self.law, "screen": _num(self.screen),
            "delta_elpd": _num(self.delta_elpd), "se": _num(self.se),
            "delta_holdout": _num(self.delta_holdout), "se_holdout": _num(self.se_holdout),
            "shrink_calibration": _num(self.shrink_calibration),
            "shrink_holdout": _num(self.shrink_holdout), "significant": self.significant,
            "calibration": self.calibration.as_dict(),
            "holdout": None if self.holdout is None else self.holdout.as_dict(),
            "params": self.params, "note": self.note, "evidence": self.evidence(),
        }


@dataclass(frozen=True)
class GapReport:
    """Result of :func:`diagnose`: where the baseline misses, which effect, how far it shrinks.

    ``diagnosis`` is the named effect, or ``"none"`` when no effect is named (``"incomplete"``
    when effects were left unevaluated); ``verdict`` reads the gap: the named effect, ``"none"``
    (what is left is noise), ``"unexplained"`` (a systematic gap that no catalogued effect
    closes) or ``"incomplete"``; ``evidence`` holds the numbers behind the verdict (see
    :func:`diagnose`).
    """

    law: str
    diagnosis: str
    combination: tuple[str, ...]
    where: pd.DataFrame
    screens: dict[str, float]
    ranking: tuple[EffectScore, ...]
    steps: tuple[EffectScore, ...]
    baseline: tuple[Metrics, Metrics | None]
    final: tuple[Metrics, Metrics | None]
    notes: tuple[str, ...]
    fits: dict = field(default_factory=dict, repr=False, compare=False)
    calibration_data: object = field(default=None, repr=False, compare=False)
    holdout_data: tuple = field(default=(), repr=False, compare=False)
    skipped: dict[str, str] = field(default_factory=dict)
    """Effects whose refit or scoring failed numerically: effect -> what failed where."""
    not_evaluated: dict[str, str] = field(default_factory=dict)
    """Effects not tried: effect -> why (``"time budget"``)."""
    budget_message: str = ""
    """The one line saying the time budget was reached ("" when it was not)."""
    elapsed: float = float("nan")
    """Wall time of the diagnosis [s]."""
    reused: tuple[str, ...] = ()
    """Steps whose fits were read from the checkpoint folder instead of refitted."""
    verdict: str = ""
    """An effect name, ``"none"``, ``"unexplained"`` or ``"incomplete"``."""
    evidence: dict = field(default_factory=dict)
    """Why the verdict (JSON-ready; keys in :func:`diagnose`)."""

    @property
    def complete(self) -> bool:
        """True when every requested effect that the data can judge was refitted and scored."""
        return not self.skipped and not self.not_evaluated

    def as_dict(self) -> dict:
        """The JSON summary of the CLI (gaps as NRMSE; holdout null without held-out data)."""
        b, f = self.baseline, self.final
        return {
            "law": self.law,
            "verdict": self.verdict,
            "diagnosis": self.diagnosis,
            "combination": list(self.combination),
            "evidence": self.evidence,
            "where": [{"axis": r.axis, "segment": r.segment, "error_share": _num(r.error_share),
                       "coverage": _num(r.coverage)} for r in self.where.head(10).itertuples()],
            "ranking": [{"effect": e.effect, "variant": e.variant, "delta_elpd": _num(e.delta_elpd),
                         "se": _num(e.se),
                         "shrink_calibration": _num(e.shrink_calibration),
                         "shrink_holdout": _num(e.shrink_holdout), "passes_rule": e.significant,
                         "named": e.effect in self.combination, **e.evidence()}
                        for e in self.ranking],
            "gap_before": {"calibration": _num(b[0].gap),
                           "holdout": None if b[1] is None else _num(b[1].gap)},
            "gap_after": {"calibration": _num(f[0].gap),
                          "holdout": None if f[1] is None else _num(f[1].gap)},
            "complete": self.complete,
            "skipped": dict(self.skipped),
            "not_evaluated": dict(self.not_evaluated),
            "time_budget": {"reached": bool(self.budget_message), "message": self.budget_message or None,
                            "elapsed_s": _num(self.elapsed)},
            "reused_from_checkpoint": list(self.reused),
            "notes": [str(n) for n in ordered(self.notes)],  # critical first
            "notes_severity": as_dicts(self.notes),
        }
