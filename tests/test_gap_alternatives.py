"""Alternatives to the named effect (rrfrei.gap.diagnose, step 3): the effects the held-out data
cannot tell from it.

When two candidates imitate each other (on the real building: a viscous damper in the isolation
layer and a rate-dependent bearing force), which of the two a rule names can turn on rounding, so
the verdict must carry the other: an effect whose refit passes the rule's rank tests and that
the held-out blocks do not show to leave more of the baseline's systematic gap than the named one
(paired block bootstrap) is listed in ``evidence["alternatives"]``, in the report and in the
JSON.  An effect that does not imitate the named one, or that the held-out data show to be
worse, is not listed.

The model is the engine tests' linear one (tests/test_gap_robust.py): force = b0 u + effect
regressors, exact least squares.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from rrfrei.gap.diagnose import diagnose
from rrfrei.gap.report import verdict_text, write_report
from rrfrei.io import ShearTest
from tests import test_gap_robust as robust
from tests.test_gap_robust import EFFECTS, LinearModel
from tests.test_gap_robust import _tests as _robust_tests


def _ripple(n: int) -> np.ndarray:
    """A slow modulation over the test (three periods over its ten cycles)."""
    return np.sin(2 * np.pi * 3 * np.arange(n) / n)


@pytest.fixture()
def regressors(monkeypatch):
    """``slip``: |u| (1 + 0.4 ripple); ``pinching``: |u| plus a fixed jitter of sd 0.2 (a worse
    copy of asymmetry)."""
    regs = dict(robust.REGRESSORS)
    regs["slip"] = lambda u: np.abs(u) * (1.0 + 0.4 * _ripple(u.size))
    regs["pinching"] = lambda u: np.abs(u) + 0.2 * np.random.default_rng(u.size).normal(size=u.size)
    monkeypatch.setattr(robust, "REGRESSORS", regs)


def _midway(seed: int) -> list[ShearTest]:
    """force = 2 u + 0.3 |u| (1 + 0.2 ripple) + noise (sd 0.05): midway between asymmetry (no
    ripple) and slip (ripple 0.4), so neither is closer; calibration and held-out test."""
    out = []
    for k, amp in enumerate((1.0, 1.5)):
        t = np.linspace(0.0, 10.0, 500, endpoint=False)
        u = amp * np.sin(2 * np.pi * t)
        f = (2 * u + 0.3 * np.abs(u) * (1 + 0.2 * _ripple(u.size))
             + np.random.default_rng([seed, k]).normal(0, 0.05, u.size))
        out.append(ShearTest(f"test{k}", t, u, f))
    return out


def test_of_two_effects_the_data_cannot_tell_apart_one_is_named_and_the_other_is_its_alternative(
        regressors, tmp_path):
    """Over 20 seeds: always one of the two named and nothing else listed; the other listed in at
    least 14 (the named one is the better of the two on that seed's held-out blocks, so the 90 %
    interval of their difference misses zero somewhat more often than 1 in 20: 17 of 20 here)."""
    listed = 0
    for seed in range(20):
        cal, ho = _midway(seed)
        rep = diagnose(LinearModel(), cal, [ho], effects=["asymmetry", "slip", "rollover"], combine=False)
        named = rep.verdict
        assert named in ("asymmetry", "slip")  # either may win: rounding decides, not the physics
        other = "slip" if named == "asymmetry" else "asymmetry"
        alts = rep.evidence["alternatives"]
        assert [a["effect"] for a in alts] in ([], [other])  # rollover (u^3) imitates neither
        if not alts:
            continue
        listed += 1
        d = alts[0]["against_named"]
        assert d["ci"][0] <= 0.0 and abs(d["difference"]) < 0.1  # the reported interval reaches zero
        assert alts[0]["shrink"] > 0.5
        assert f"`{other}`" in verdict_text(rep)
        assert json.loads(json.dumps(rep.as_dict()))["evidence"]["alternatives"][0]["effect"] == other
        if listed == 1:
            assert "no (alternative)" in write_report(rep, tmp_path).read_text()
    assert listed >= 14


def test_a_worse_copy_of_the_named_effect_that_the_held_out_blocks_reject_is_no_alternative(regressors):
    """Truth 2 u + 0.3 |u|: pinching (|u| with jitter) passes the rule against the baseline, but
    the named asymmetry leaves no systematic gap and pinching does, on every resample of blocks."""
    cal, ho = _robust_tests()
    rep = diagnose(LinearModel(), cal, [ho], effects=["asymmetry", "pinching", "rollover"], combine=False)
    assert rep.verdict == "asymmetry"
    assert next(s for s in rep.ranking if s.effect == "pinching").significant
    assert rep.evidence["alternatives"] == []


def test_effects_that_close_none_of_the_gap_are_no_alternatives():
    cal, ho = _robust_tests()
    rep = diagnose(LinearModel(), cal, [ho], effects=EFFECTS)
    assert rep.verdict == "asymmetry"
    assert rep.evidence["alternatives"] == []
    assert "support as well" not in verdict_text(rep)


def test_an_effect_combined_with_the_named_one_is_not_its_alternative(regressors):
    """Both asymmetry and slip are needed for the midway truth: combined, not alternatives."""
    cal, ho = _midway(0)
    rep = diagnose(LinearModel(), cal, [ho], effects=["asymmetry", "slip"])
    assert set(rep.combination) == {"asymmetry", "slip"}
    assert rep.evidence["alternatives"] == []


def test_without_held_out_data_there_are_no_alternatives(regressors):
    cal, _ = _midway(0)
    rep = diagnose(LinearModel(), cal, [], effects=["asymmetry", "slip"])
    assert rep.evidence.get("alternatives", []) == []


def test_the_gap_difference_is_paired_zero_for_one_model_and_signed_for_a_worse_one():
    """gap_difference_ci: (S_b - S_a) / S_ref over the same resampled blocks; a model against
    itself differs by exactly zero on every resample; one leaving more error is positive."""
    from rrfrei.gap.decision import BlockParts, gap_difference_ci

    rng = np.random.default_rng(0)
    B = 12
    n, yy, noise = np.full(B, 100.0), rng.uniform(50, 60, B), np.full(B, 1.0)
    ref, a = rng.uniform(20, 30, B), rng.uniform(5, 8, B)
    st = np.zeros(B, dtype=np.int64)

    def parts(eff):
        return BlockParts(n=n, sse_ref=ref, sse_eff=eff, yy=yy, noise=noise, stratum=st)

    same = gap_difference_ci(parts(a), parts(a))
    assert same.difference == same.lower == same.upper == 0.0
    worse = gap_difference_ci(parts(a), parts(2 * a))
    assert 0 < worse.lower <= worse.difference <= worse.upper
    with pytest.raises(ValueError, match="one reference"):
        other = BlockParts(n=n, sse_ref=ref + 1, sse_eff=a, yy=yy, noise=noise, stratum=st)
        gap_difference_ci(parts(a), other)
