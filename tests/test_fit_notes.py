"""Every fit of the gap engine records a note once, with its severity, through one
:meth:`rrfrei.gap.model.FitResult.add_note` (isolator, building and rubber fits alike)."""

from dataclasses import dataclass, field

import pytest

from rrfrei.gap.isolator import IsolatorFit
from rrfrei.gap.model import FitResult
from rubber.gap.model import RubberFit
from structures.shake_table.building_fit import BuildingFit


class _Stored(FitResult):  # a fit with a joined ``note`` string and a ``notes`` list
    def __init__(self):
        self.note, self.notes = "", []

    def predict(self, data):  # pragma: no cover - not used
        raise NotImplementedError

    def loglik(self, data):  # pragma: no cover - not used
        raise NotImplementedError


@dataclass(frozen=True)
class _Derived(_Stored):  # a frozen fit whose ``note`` is derived from ``notes``
    notes: list = field(default_factory=list)

    def __init__(self):
        object.__setattr__(self, "notes", [])

    @property
    def note(self) -> str:
        return "; ".join(map(str, self.notes))


@pytest.mark.parametrize("fit", [_Stored(), _Derived()], ids=["stored note", "derived note"])
def test_a_note_is_recorded_once_with_its_severity(fit):
    fit.add_note("12 of 30 draws failed", "warning")
    fit.add_note("12 of 30 draws failed", "critical")  # the same text again: kept once
    fit.add_note("robust solve at 3 steps")
    assert fit.note == "12 of 30 draws failed; robust solve at 3 steps"
    assert [(str(n), n.severity) for n in fit.notes] == [("12 of 30 draws failed", "warning"),
                                                        ("robust solve at 3 steps", "info")]


def test_the_engine_fits_share_the_one_method():
    for cls in (IsolatorFit, BuildingFit, RubberFit):
        assert cls.add_note is FitResult.add_note
        assert not hasattr(cls, "_add_note")
