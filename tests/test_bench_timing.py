"""The timing rules of ``benchmarks/_timing.py``: what a reported ratio is allowed to mean.

A fake clock advances only when the sides call it, so these tests state which work falls inside
the timer without measuring any wall time.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

_ENV = dict(os.environ)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import _timing as tm  # noqa: E402

os.environ.clear()  # _timing pins the BLAS pools for benchmark scripts; keep this process as it was
os.environ.update(_ENV)


class FakeClock:
    """Reads the time; ``spend(s)`` is work taking ``s`` seconds."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def spend(self, seconds: float) -> None:
        self.now += seconds


def side(clock: FakeClock, label: str, run_s: float, setup_s: float = 0.0, finish_s: float = 0.0,
         log: list | None = None, out=1.0, work: float = 1.0) -> tm.Side:
    def setup():
        clock.spend(setup_s)

    def run(_state):
        if log is not None:
            log.append(label)
        clock.spend(run_s)
        return out

    def finish(_state, raw):
        clock.spend(finish_s)
        return raw

    return tm.Side(label, run, setup, finish, work)


def test_setup_and_teardown_are_outside_the_timer():
    clock = FakeClock()
    peer = side(clock, "peer", run_s=2.0, setup_s=50.0, finish_s=30.0)
    timing, out = tm.measure(peer, repeat=3, clock=clock)
    assert timing.times == (2.0, 2.0, 2.0)
    assert out == 1.0


def test_warm_up_is_excluded_and_both_sides_get_the_same_interleaved_repeats():
    clock, log = FakeClock(), []
    ours = side(clock, "ours", 1.0, log=log)
    peer = side(clock, "peer", 3.0, log=log)
    c = tm.compare(ours, peer, repeat=4, warmup=2, agree=lambda a, b: abs(a - b), tolerance=0.0,
                   clock=clock)
    assert log == ["ours", "peer"] * 6  # 2 warm-ups then 4 timed runs each, alternating
    assert len(c.ours.times) == len(c.peer.times) == 4
    assert c.ratio == pytest.approx(3.0)


def test_ratio_is_of_medians_per_unit_of_work():
    clock = FakeClock()
    times = iter([1.0, 100.0, 1.0])  # one slow outlier among ours

    def run(_state):
        clock.spend(next(times))
        return 0.0

    ours = tm.Side("ours", run, work=32.0)  # one batched call does 32 evaluations
    peer = side(clock, "peer", 16.0, out=0.0)
    c = tm.compare(ours, peer, repeat=3, warmup=0, agree=lambda a, b: 0.0, tolerance=0.0, clock=clock)
    assert c.ours.median == 1.0
    assert c.ratio == pytest.approx(16.0 / (1.0 / 32.0))


def test_disagreeing_results_give_no_ratio():
    clock = FakeClock()
    ours = side(clock, "ours", 1.0, out=1.0)
    peer = side(clock, "peer", 2.0, out=1.1)
    with pytest.raises(tm.AgreementError, match="ours and peer disagree by 0.1"):
        tm.compare(ours, peer, repeat=1, agree=lambda a, b: abs(a - b), tolerance=1e-3, what="case",
                   clock=clock)
    nan = side(clock, "peer", 2.0, out=float("nan"))
    with pytest.raises(tm.AgreementError):
        tm.compare(ours, nan, repeat=1, agree=lambda a, b: abs(a - b), tolerance=1e-3, clock=clock)


def test_per_core_comparison_runs_on_one_numba_thread():
    import numba

    seen = []
    ours = tm.Side("ours", lambda _s: seen.append(numba.get_num_threads()) or 0.0)
    peer = tm.Side("peer", lambda _s: seen.append(numba.get_num_threads()) or 0.0)
    before = numba.get_num_threads()
    tm.compare(ours, peer, repeat=2, agree=lambda a, b: 0.0, tolerance=0.0)
    assert set(seen) == {1}
    assert numba.get_num_threads() == before


# the snippets stand in for an import + first call: they "compile" (write a cache entry) only
# when the entry is missing, or on every run
_READS = tm.COLD_PRELUDE + """
import os, pathlib
entry = pathlib.Path(os.environ["NUMBA_CACHE_DIR"]) / "kernel.nbi"
hit = entry.exists()
entry.write_text("x") if not hit else None
print(json.dumps({"hit": float(hit)}))
"""
_ALWAYS_WRITES = tm.COLD_PRELUDE + """
import os, pathlib, uuid
(pathlib.Path(os.environ["NUMBA_CACHE_DIR"]) / f"{uuid.uuid4().hex}.nbi").write_text("x")
print(json.dumps({"hit": 0.0}))
"""


def test_cold_start_runs_empty_then_warm_in_the_same_explicit_cache():
    c = tm.cold_start(_READS)
    assert c.cold == {"hit": 0.0}
    assert c.warm == {"hit": 1.0}
    assert c.new_in_warm == 0 and c.notes == ()


def test_cold_start_says_when_the_warm_run_did_not_read_the_cache():
    c = tm.cold_start(_ALWAYS_WRITES)
    assert c.new_in_warm == 1
    assert "warm run still wrote 1 cache files" in c.notes[0]
    assert "note:" in c.describe()


def _cells(markdown: str, what: str) -> list[str]:
    line = next(ln for ln in markdown.splitlines() if ln.startswith(f"| {what}"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_readme_table_keeps_per_core_and_multi_core_figures_apart():
    import readme_table

    h = {"bench_time_history": {"ours_s": 0.004, "peer_s": 0.25, "ratio": 62.5, "steps": 8000,
                                "batch_rate_1": 200.0, "batch_rate_multi": 330.0, "threads": 2},
         "bench_calibration": {"ours_s": 1.5e-4, "peer_s": 0.015, "ratio": 100.0, "multi_rate": 12000.0,
                               "threads": 2, "posterior_median_s": 10.0, "command_s": 20.0}}
    md = readme_table.table(h)
    what, ours, peer, ratio, multi, _target = _cells(md, "5-story building")
    assert (ours, ratio) == ("4.00 ms", "**62x**")
    assert "250 ms" in peer and "330 analyses/s on 2 threads" in multi
    what, ours, peer, ratio, multi, _target = _cells(md, "full bouc_wen posterior")
    assert (ours, peer, ratio) == ("", "", "") and multi == "10.0 s on 2 threads"  # multi-core only
    assert _cells(md, "polyurethane model")[3] == readme_table.MISSING  # never a stale number
    assert readme_table.MISSING in _cells(md, "response spectrum")[3]


def test_a_section_is_replaced_in_place_and_the_rules_head_the_file(tmp_path, monkeypatch):
    import _results

    monkeypatch.setattr(_results, "RESULTS", tmp_path / "RESULTS.md")
    monkeypatch.setattr(_results, "HEADLINE", tmp_path / "headline.json")
    (tmp_path / "RESULTS.md").write_text("# old header\n\n<!-- a:start -->\nold a\n<!-- a:end -->\n\n"
                                         "<!-- b:start -->\nkept b\n<!-- b:end -->\n")
    _results.report("a", "new a", quick=False, headline={"ratio": 2.0})
    text = (tmp_path / "RESULTS.md").read_text()
    assert text.startswith(_results.HEADER) and "old header" not in text
    assert "new a" in text and "old a" not in text and "kept b" in text
    assert text.index("new a") < text.index("kept b")  # same place
    assert '"ratio": 2.0' in (tmp_path / "headline.json").read_text()
    _results.report("b", "smoke", quick=True)  # a --quick run writes nothing
    assert "kept b" in (tmp_path / "RESULTS.md").read_text()
