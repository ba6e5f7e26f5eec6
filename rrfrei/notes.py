"""Notes attached to a result, each with a severity: the one mechanism for what a reader must know.

A note is a :class:`Note`: its text (a ``str``, so code that lists, joins or serialises notes
keeps working) and a severity:

* ``"critical"``: it changes how the result may be read (e.g. a band made from one posterior
  draw, an incomplete diagnosis, an unconverged chain);
* ``"warning"``: part of the result is weaker than asked (a step skipped, a time budget hit);
* ``"info"``: routine bookkeeping (fits reused from a checkpoint, a variant not tried).

:func:`ordered` sorts notes critical first (stable within a severity); reports and the command
line print them in that order, with :func:`label`.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["SEVERITIES", "Note", "ordered", "label", "as_dicts", "severity_of"]

SEVERITIES = ("critical", "warning", "info")
"""Severities, most severe first."""


class Note(str):
    """A note's text with its :attr:`severity` (one of :data:`SEVERITIES`)."""

    severity: str

    def __new__(cls, text: str, severity: str = "info") -> Note:
        if severity not in SEVERITIES:
            raise ValueError(f"note severity {severity!r}: expected one of {', '.join(SEVERITIES)}")
        obj = super().__new__(cls, str(text))
        obj.severity = severity
        return obj

    def __reduce__(self):  # pickles (forked workers, checkpoints) keep the severity
        return (Note, (str(self), self.severity))


def severity_of(note: str) -> str:
    """The severity of a note (``"info"`` for a plain string)."""
    return getattr(note, "severity", "info")


def ordered(notes: Iterable[str]) -> list[Note]:
    """``notes`` as :class:`Note` objects, critical first, then warnings, then info (stable), each
    text once."""
    seen: set[str] = set()
    out: list[Note] = []
    for n in notes:
        if str(n) in seen:
            continue
        seen.add(str(n))
        out.append(n if isinstance(n, Note) else Note(n))
    return sorted(out, key=lambda n: SEVERITIES.index(n.severity))


def label(note: str) -> str:
    """``"CRITICAL: text"``, ``"warning: text"`` or ``"note: text"``."""
    sev = severity_of(note)
    return {"critical": "CRITICAL", "warning": "warning", "info": "note"}[sev] + f": {note}"


def as_dicts(notes: Iterable[str]) -> list[dict]:
    """``[{"severity", "text"}]`` in :func:`ordered` order (for JSON)."""
    return [{"severity": n.severity, "text": str(n)} for n in ordered(notes)]
