"""The demo's readings say what their numbers say (fast: readings from made-up tables)."""

from __future__ import annotations

import pandas as pd

from rrfrei.app.demo.prose import comparison_reading


def _table(k_loo, k_loco) -> pd.DataFrame:
    laws = ["bouc_wen", "plasticity", "hdr"]
    t = pd.DataFrame({
        "elpd_loo": [-100.0, -130.0, -160.0], "se_loo": [10.0, 11.0, 12.0], "dse_loo": [0.0, 5.0, 6.0],
        "elpd_waic": [-99.0, -129.0, -158.0], "elpd_loco": [-120.0, -140.0, -170.0],
        "k_max_loo": k_loo, "k_max_loco": k_loco,
    }, index=pd.Index(laws, name="law"))
    return t


def test_a_large_leave_one_cycle_out_k_makes_the_comparison_unreliable_even_when_loo_k_is_small():
    """The user's case: largest PSIS-LOO k 0.415, leave-one-cycle-out k 0.9 to 2.0."""
    text = comparison_reading(_table([0.415, 0.2, 0.3], [0.9, 2.0, 1.3]))
    assert "0.415" in text and "2 for leave-one-cycle-out (plasticity)" in text
    assert "UNRELIABLE" in text
    assert "estimates are reliable" not in text
    assert "bouc_wen 0.9" in text and "hdr 1.3" in text  # every law above the limit is named
    assert "Vehtari" in text


def test_a_large_loo_k_alone_also_makes_it_unreliable():
    text = comparison_reading(_table([0.2, 0.75, 0.3], [0.1, 0.5, 0.6]))
    assert "UNRELIABLE" in text and "plasticity 0.75" in text


def test_small_k_everywhere_is_called_reliable_with_both_maxima_reported():
    text = comparison_reading(_table([0.415, 0.2, 0.3], [0.5, 0.69, 0.1]))
    assert "UNRELIABLE" not in text
    assert "estimates are reliable" in text
    assert "0.415 for PSIS-LOO" in text and "0.69 for leave-one-cycle-out" in text
    assert "clear difference" in text and "if the estimates held" not in text
