"""The report of a shake-table run's consistency check
(:func:`structures.shake_table.checks.check_consistency`): every acceleration against the second
derivative of its displacement, and what a common scale says about the sampling rate.  A run
carries its report (:attr:`structures.shake_table.run.ShakeTableRun.consistency`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["ConsistencyReport"]


@dataclass(frozen=True)
class ConsistencyReport:
    """Agreement of each acceleration with the derivative of its displacement.

    ``table`` has one row per check: ``check`` (``"a_i = d_i'' + a_g"`` per level or
    ``"du'' = a_g"``), ``channel``, ``correlation``, ``amplitude_ratio`` (RMS of the derived
    over the measured, after the low-pass), ``rel_error`` (RMS of the difference over the RMS of
    the measured), ``passed`` (``rel_error <= tol``), and the sampling-rate evidence: ``scale``,
    the least-squares factor c in  measured ~ c x derived  of the accelerations *relative to the
    table* (a_i - a_g against d_i''; a_g against du''), and ``scale_correlation``, their
    correlation.  A second derivative taken at a rate f' instead of the true f is (f'/f)^2 times
    too large, so a wrong rate shows as a common scale c = (f/f')^2 with a high correlation;
    :attr:`implied_rate_hz` is f' sqrt(c).
    """

    table: pd.DataFrame
    cutoff_hz: float
    tol: float
    rate_hz: float = math.nan

    @property
    def ok(self) -> bool:
        return bool(self.table["passed"].all())

    @property
    def scale(self) -> float:
        """Median of the per-check ``scale`` (NaN when no check has signal)."""
        c = self.table["scale"].to_numpy(dtype=float)
        c = c[np.isfinite(c) & (c > 0)]
        return float(np.median(c)) if c.size else math.nan

    @property
    def scale_correlation(self) -> float:
        """Smallest ``scale_correlation`` over the checks with signal."""
        r = self.table["scale_correlation"].to_numpy(dtype=float)
        r = r[np.isfinite(r)]
        return float(r.min()) if r.size else math.nan

    @property
    def implied_rate_hz(self) -> float:
        """The sampling rate [Hz] at which the displacements' second derivative matches the
        accelerations: rate_hz x sqrt(scale)."""
        return self.rate_hz * math.sqrt(self.scale) if self.scale > 0 else math.nan

    def rate_looks_wrong(self, *, rate_tol: float = 0.1, min_correlation: float = 0.9) -> bool:
        """True when most checks fail and every channel shows one common scale (correlation >=
        ``min_correlation``) whose implied rate is more than ``rate_tol`` away from the stated one:
        the signature of a wrong sampling rate (or of displacements in another unit)."""
        n_fail = int((~self.table["passed"]).sum())
        if n_fail * 2 <= len(self.table) or not self.scale_correlation >= min_correlation:
            return False
        return abs(math.sqrt(self.scale) - 1.0) > rate_tol

    @property
    def failures(self) -> list[str]:
        """One line per failing check."""
        bad = self.table[~self.table["passed"]]
        return [f"{r.check} ({r.channel}): relative error {r.rel_error:.3g} > {self.tol:g}, "
                f"correlation {r.correlation:.4f}, amplitude ratio {r.amplitude_ratio:.3f}"
                for r in bad.itertuples()]

    def __str__(self) -> str:
        worst = float(self.table["rel_error"].max())
        head = (f"consistency after a {self.cutoff_hz:g} Hz low-pass: "
                f"{int(self.table['passed'].sum())}/{len(self.table)} checks pass "
                f"(worst relative error {worst:.3g}, tolerance {self.tol:g})")
        lines = [head, *self.failures]
        if not self.ok and self.scale_correlation >= 0.9 and abs(math.sqrt(self.scale) - 1.0) > 0.02:
            lines.append(f"every channel shows one scale (d'' is {1 / self.scale:.3g} x the accelerations, "
                         f"correlation >= {self.scale_correlation:.4f}): the data match a sampling rate of "
                         f"about {self.implied_rate_hz:.3g} Hz, not {self.rate_hz:.3g} Hz (or displacements "
                         "in another unit)")
        return "\n".join(lines)
