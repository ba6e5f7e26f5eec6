"""The withheld isolator stiffening of the building-level validation's slow subset (issue 27.7).

The study's other slow case, the control, and the checks both cases share are in
``test_shake_table_validation.py``; the two cases sit in two files so that pytest-xdist's
``--dist loadfile`` runs them on the two workers at once.
"""

from __future__ import annotations

import pytest
from test_shake_table_validation import run_slow_case


@pytest.mark.slow
def test_validation_subset_the_withheld_stiffening_finishes_and_the_diagnosis_points_at_it(tmp_path):
    """The stiffening case of the subset (:func:`run_slow_case`: it finishes with every candidate
    scored, 8+ blocks each side, a named effect never worsens the held-out building).

    Top-1: the withheld isolator stiffening leaves the largest held-out gap of the forms and on
    every seed of the study its own candidate is the one named or the closest, closing 18-83 % of
    the held-out systematic gap (more than the rule's 10 %).  Whether it is *named* rests on 9
    held-out blocks, where one losing block decides (8/9 gaining gave p = 0.0039 on seed 0 and
    0.0059 on seed 2, against 0.005), so the name is not asserted: the test asserts that the
    diagnosis points at the right effect with a shrink the rule counts."""
    from rrfrei.gap.decision import MIN_SHRINK
    from structures.shake_table.validation import summarise

    df = run_slow_case("stiffening", tmp_path)
    stiff = df[df["effect"] == "stiffening"].iloc[0]
    assert stiff["top_candidate"] == "stiffening", stiff[["verdict", "top_candidate", "top_why"]]
    assert stiff["top_shrink_holdout"] > MIN_SHRINK, stiff[["verdict", "top_shrink_holdout"]]
    assert stiff["verdict"] in {"stiffening", "unexplained"}, summarise(df)["verdicts"]
