"""Validation of the gap diagnosis on withheld effects that it was not tuned to (issue 12, point 4).

Layers: generator forms, three per effect, written in plain NumPy apart from the catalogue
kernels (:mod:`.forms`) -> cases: effect, form, base law, noise, seed and a stratified effect
size, made into protocols 1-4 (:mod:`.cases`) -> the table: one diagnosis per case, in parallel
processes, with a time budget and a resumable checkpoint (:mod:`.run`) -> Markdown, JSON and the
confusion-matrix figure (:mod:`.report`).

>>> from rrfrei.gap import validation as gv
>>> res = gv.run_table(gv.cases(10), gv.FULL, workers=2)   # doctest: +SKIP
>>> res.goals()                                            # doctest: +SKIP
"""

from rrfrei.gap.validation.cases import BASES, CONTROLS, FIXED, Case, cases, make_case_tests
from rrfrei.gap.validation.forms import FORMS, Form, Signal, forms_of
from rrfrei.gap.validation.run import FULL, REDUCED, VERDICTS, Settings, ValidationResult, run_case, run_table

__all__ = ["BASES", "CONTROLS", "FIXED", "FORMS", "FULL", "REDUCED", "VERDICTS", "Case", "Form", "Settings",
           "Signal", "ValidationResult", "cases", "forms_of", "make_case_tests", "run_case", "run_table"]
