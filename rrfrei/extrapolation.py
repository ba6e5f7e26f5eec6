"""A prediction beyond the calibrated range says so: one record, one check, one warning.

A calibrated model is evidence inside the range of its calibration data and only its form
beyond it.  Every model of the project reports that the same way:

- the isolator calibration's predictions (:func:`rrfrei.calibration.predict`): a test whose
  displacement goes beyond the calibration test's displacement range [m];
- the buildings (``structures``): an isolator displacement beyond the calibrated one [m];
- the rubber model (``rubber``): a test whose stretch goes beyond the fitted stretch range, or
  comes within 10 % of a chain's locking stretch (where the eight-chain spring stiffens without
  bound and the fitted model has no data).

:func:`beyond` and :func:`approaching` return :class:`Extrapolation` records (empty when the test
stays inside); :func:`warn` issues each as an :class:`ExtrapolationWarning` naming the source
(file, test or run), the quantity, the value reached and the limit; :meth:`Extrapolation.as_dict`
is the JSON form the commands carry per file.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["MARGIN", "Extrapolation", "ExtrapolationWarning", "approaching", "beyond", "by_source", "exceeds",
           "warn"]

MARGIN = 0.10
"""Relative distance to a hard limit (e.g. a locking stretch) within which a prediction is flagged."""

_RTOL = 1e-9  # a value equal to the calibrated bound up to round-off is inside


class ExtrapolationWarning(UserWarning):
    """A prediction goes beyond the range its model was calibrated on."""


@dataclass(frozen=True)
class Extrapolation:
    """One prediction outside its model's evidence.

    source : the file, test or run predicted.
    quantity : what left the range (``"stretch"``, ``"displacement"``, ...), with ``unit``.
    value : the extreme the prediction reaches (signed: the side it leaves on).
    limit : the bound it passes (``kind = "beyond"``) or approaches (``kind = "near"``).
    reason : the bound, in words (``"the fitted range 1 to 3"``, ``"chain B's locking stretch"``).
    """

    source: str
    quantity: str
    value: float
    limit: float
    kind: str
    reason: str
    unit: str = ""

    @property
    def ratio(self) -> float:
        """value / limit (> 1 beyond an upper bound)."""
        return float(self.value / self.limit) if self.limit else float("inf")

    @property
    def message(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        if self.kind == "beyond":
            where = f"goes beyond {self.reason}{u}"
        elif self.value >= self.limit:
            where = f"passes {self.reason}, {self.limit:.4g}{u}"
        else:
            where = f"comes within {100 * MARGIN:.0f} % of {self.reason}, {self.limit:.4g}{u}"
        return (f"{self.source}: {self.quantity} {self.value:.4g}{u} {where}; the prediction there "
                "follows the model's form, not calibration data")

    def as_dict(self) -> dict:
        return {**asdict(self), "ratio": self.ratio, "message": self.message}


def exceeds(values, peak: float) -> np.ndarray:
    """Elementwise |values| > ``peak`` (beyond a calibrated peak magnitude, round-off excluded): the
    vectorised form of :func:`beyond` with ``symmetric`` (e.g. one flag per simulated run)."""
    return np.abs(np.asarray(values, dtype=float)) > abs(float(peak)) * (1 + _RTOL)


def beyond(source: str, quantity: str, values, calibrated: Sequence[float], *, unit: str = "",
           symmetric: bool = False, what: str = "the calibrated range") -> list[Extrapolation]:
    """Records of ``values`` leaving ``calibrated = (low, high)`` (one per side left; [] inside).

    With ``symmetric`` the check is on magnitudes: max|values| against max(|low|, |high|) (a peak
    displacement in either direction against the calibrated peak).
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    lo, hi = float(calibrated[0]), float(calibrated[1])
    if v.size == 0:
        return []
    span = f"{what} {lo:.4g} to {hi:.4g}"
    if symmetric:
        peak = max(abs(lo), abs(hi))
        reached = float(np.max(np.abs(v)))
        if exceeds(reached, peak):
            return [Extrapolation(source, f"peak |{quantity}|", reached, peak, "beyond",
                                  f"{what}, peak {peak:.4g}", unit)]
        return []
    out = []
    top, bottom = float(v.max()), float(v.min())
    if top > hi + _RTOL * abs(hi):
        out.append(Extrapolation(source, quantity, top, hi, "beyond", span, unit))
    if bottom < lo - _RTOL * abs(lo):
        out.append(Extrapolation(source, quantity, bottom, lo, "beyond", span, unit))
    return out


def approaching(source: str, quantity: str, values, limit: float, *, reason: str, unit: str = "",
                margin: float = MARGIN) -> Extrapolation | None:
    """A record when max(``values``) reaches (1 - ``margin``) of the upper ``limit``, else None."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0 or not np.isfinite(limit):
        return None
    top = float(v.max())
    if top >= (1.0 - margin) * limit:
        return Extrapolation(source, quantity, top, float(limit), "near", reason, unit)
    return None


def warn(items: Iterable[Extrapolation], stacklevel: int = 2) -> None:
    """Issue each record as an :class:`ExtrapolationWarning` (its :attr:`~Extrapolation.message`)."""
    for item in items:
        warnings.warn(item.message, ExtrapolationWarning, stacklevel=stacklevel + 1)


def by_source(items: Iterable[Extrapolation]) -> dict[str, list[dict]]:
    """``{source: [record as dict, ...]}`` for JSON output, in the order given."""
    out: dict[str, list[dict]] = {}
    for item in items:
        out.setdefault(item.source, []).append(item.as_dict())
    return out
