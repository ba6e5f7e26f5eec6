"""The report page and the demo pipeline's failure handling (fast: no real workflow runs)."""

from __future__ import annotations

import base64
import json
import os
import re

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from rrfrei.app import demo
from rrfrei.app.cli import main
from rrfrei.app.report import Report, Section, fmt, slug


def _figure() -> Figure:
    fig = Figure(figsize=(3, 2))
    ax = fig.subplots()
    ax.plot([0, 1, 2], [0, 1, 4])
    return fig


def _png_size(png: bytes) -> tuple[int, int]:
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


def test_page_is_self_contained_with_every_figure_embedded_as_a_decodable_png(tmp_path):
    rep = Report("T")
    sec = rep.add(Section("Fit A", "A fit", reading="x"))
    sec.add_figure("loop", _figure())
    sec.add_figure("energy", _figure())
    page = rep.write(tmp_path).read_text()
    uris = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(uris) == 2
    for b64, (name, png) in zip(uris, sec.figures.items()):
        decoded = base64.b64decode(b64)
        assert decoded == png
        w, h = _png_size(decoded)
        assert w > 50 and h > 50
        assert (tmp_path / "figures" / f"fit_a__{name}.png").read_bytes() == png
    # nothing else is referenced: no external src/href, no script needed
    assert not re.search(r'(src|href)="(?!data:|#)', page)
    assert "<script" not in page


def test_tables_are_written_as_csv_with_the_same_numbers_and_listed_in_the_manifest(tmp_path):
    rng = np.random.default_rng(1)
    df = pd.DataFrame({"law": ["a", "b", "c"], "elpd": rng.normal(size=3), "n": [1, 2, 3]})
    rep = Report("T")
    sec = rep.add(Section("cmp", "Comparison", reading="y"))
    sec.add_table("LOO table", df)
    rep.write(tmp_path)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    (entry,) = manifest["sections"][0]["tables"]
    assert entry["csv"] == "tables/cmp__loo_table.csv" and entry["rows"] == 3
    back = pd.read_csv(tmp_path / entry["csv"])
    np.testing.assert_array_equal(back["elpd"].to_numpy(), df["elpd"].to_numpy())  # full precision
    assert list(back.columns) == entry["columns"] == ["law", "elpd", "n"]
    assert manifest["ok"] is True and manifest["sections"][0]["status"] == "ok"


def test_text_from_errors_and_tables_is_escaped_not_rendered_as_html(tmp_path):
    rep = Report("a <b> title")
    sec = rep.add(Section("s", "S", reading="1 < 2 & <i>not italic</i>"))
    sec.add_table("t", pd.DataFrame({"<col>": ["<script>alert(1)</script>"]}))
    rep.add(Section("e", "E", error="ValueError: <img src=x onerror=alert(1)>"))
    page = rep.write(tmp_path).read_text()
    assert "<script>alert" not in page and "<img src=x" not in page and "<i>not" not in page
    assert "&lt;script&gt;" in page and "1 &lt; 2 &amp;" in page


def test_duplicate_or_unnamed_keys_are_refused():
    rep = Report("T")
    rep.add(Section("a", "A"))
    with pytest.raises(ValueError, match="already has a section 'a'"):
        rep.add(Section("a", "again"))
    sec = Section("b", "B")
    sec.add_table("t", pd.DataFrame({"x": [1.0]}))
    with pytest.raises(ValueError, match="already has a table 't'"):
        sec.add_table("t", pd.DataFrame({"x": [2.0]}))
    with pytest.raises(ValueError, match="no letters or digits"):
        slug("  -- ")
    with pytest.raises(ValueError, match="must be a pandas DataFrame"):
        sec.add_table("u", [1, 2])


def test_numbers_are_shown_with_four_significant_digits():
    assert fmt(3.14159265) == "3.142"
    assert fmt(12345678.0) == "1.235e+07"
    assert fmt(7) == "7" and fmt(np.int64(7)) == "7"
    assert fmt(float("nan")) == "n/a" and fmt(True) == "True" and fmt("bouc_wen") == "bouc_wen"


# --- the pipeline keeps going when a step fails ----------------------------------------------
def _ok(ctx, sec):
    sec.add_table("t", pd.DataFrame({"x": [1.0, 2.0]}))
    sec.add_figure("f", _figure())
    ctx.results["ok"] = 2.0
    sec.reading = f"The mean is {fmt(1.5)}."


def _boom(ctx, sec):
    raise ValueError("the sampler diverged at step 17")


def _later(ctx, sec):
    value = ctx.need("results", "ok")
    sec.reading = f"Earlier result {value['ok']}."


def _missing(ctx, sec):
    raise demo.Placeholder("the workflow rrfrei.no_such_workflow does not exist yet")


def _silent(ctx, sec):
    sec.add_table("t", pd.DataFrame({"x": [1.0]}))


STEPS = (
    demo.Step("first", "First", _ok),
    demo.Step("broken", "Broken", _boom),
    demo.Step("later", "Later", _later),
    demo.Step("missing", "Missing", _missing),
    demo.Step("silent", "Silent", _silent),
)


def test_a_failing_step_is_shown_in_its_section_and_the_later_steps_still_run(tmp_path):
    result = demo.run_demo(tmp_path, quick=True, progress=False, steps=STEPS)
    status = {s.key: s.status for s in result.report.sections}
    assert status == {"first": "ok", "broken": "error", "later": "ok", "missing": "placeholder",
                      "silent": "error"}
    assert not result.ok and result.failed == ("broken", "missing", "silent")
    page = result.page.read_text()
    assert "ValueError: the sampler diverged at step 17" in page
    assert "produced no reading" in page  # a step without a reading is not a result
    assert "Placeholder" in page and "rrfrei.no_such_workflow does not exist yet" in page
    assert "QUICK run" in page and "SYNTHETIC" in page
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["ok"] is False
    assert [s["status"] for s in manifest["sections"]] == list(status.values())


def _whose(ctx, sec):
    sec.add_table("t", pd.DataFrame({"x": [1.0]}))
    sec.reading = f"pid {os.getpid()}"


def _bug(ctx, sec):
    raise TypeError("a bug, not a failure of the workflow")


ASIDE = (demo.Step("first", "First", _ok), demo.Step("aside", "Aside", _whose, alone=True),
         demo.Step("later", "Later", _later))


def test_a_step_that_stands_alone_runs_in_a_second_process_and_keeps_its_place_on_the_page(tmp_path):
    result = demo.run_demo(tmp_path / "p", quick=True, progress=False, steps=ASIDE, parallel=True)
    assert [(s.key, s.status) for s in result.report.sections] == [
        ("first", "ok"), ("aside", "ok"), ("later", "ok")]
    aside = result.report.sections[1]
    assert aside.reading.startswith("pid ") and aside.reading != f"pid {os.getpid()}"
    assert "t" in aside.tables  # the section came back whole
    serial = demo.run_demo(tmp_path / "s", quick=True, progress=False, steps=ASIDE, parallel=False)
    assert serial.report.sections[1].reading == f"pid {os.getpid()}"


def _chooses(ctx, sec):
    ctx.tests["protocol9"] = "a test"
    ctx.best_law = "plasticity"
    sec.reading = "chose"


def _reads(ctx, sec):
    sec.reading = f"pid {os.getpid()}: {sorted(ctx.tests)} {ctx.best_law}"


def test_a_step_run_aside_after_another_reads_the_tests_and_the_best_law_it_chose(tmp_path):
    steps = (demo.Step("reads", "Reads", _reads, alone=True, after="chooses"),
             demo.Step("chooses", "Chooses", _chooses), demo.Step("later", "Later", _whose))
    result = demo.run_demo(tmp_path, quick=True, progress=False, steps=steps, parallel=True)
    assert [s.key for s in result.report.sections] == ["reads", "chooses", "later"]  # page order
    reads = result.report.sections[0].reading
    assert reads.endswith("['protocol9'] plasticity") and not reads.startswith(f"pid {os.getpid()}:")


def _counted(ctx, sec):
    ctx.results["runs"] = ctx.results.get("runs", 0) + 1
    sec.reading = f"run {ctx.results['runs']}"


def _compile_ahead(ctx):
    with open(os.environ["RRFREI_TEST_AHEAD"], "w") as f:
        f.write(str(os.getpid()))


def test_the_second_process_first_does_the_work_ahead_of_a_step_that_runs_here(tmp_path, monkeypatch):
    mark = tmp_path / "ahead.txt"
    monkeypatch.setenv("RRFREI_TEST_AHEAD", str(mark))
    monkeypatch.setattr(demo.steps, "AHEAD", {"later": _compile_ahead})
    steps = (demo.Step("first", "First", _counted), demo.Step("later", "Later", _counted),
             demo.Step("aside", "Aside", _whose, alone=True), demo.Step("last", "Last", _counted))
    result = demo.run_demo(tmp_path / "page", quick=True, progress=False, steps=steps, parallel=True)
    assert result.ok
    assert mark.read_text() != str(os.getpid())  # done, and not here
    # the step with work ahead ran after the others here (its kernels compiled by then); the page
    # keeps its order
    readings = {s.key: s.reading for s in result.report.sections}
    assert [s.key for s in result.report.sections] == ["first", "later", "aside", "last"]
    assert (readings["first"], readings["last"], readings["later"]) == ("run 1", "run 2", "run 3")
    mark.unlink()
    demo.run_demo(tmp_path / "serial", quick=True, progress=False, steps=steps, parallel=False)
    assert not mark.exists()  # serial: nothing is compiled ahead (the step compiles what it needs)


UNGUARDED = """
import os, sys
from rrfrei.app import demo

def first(ctx, sec):
    sec.reading = "first"

def aside(ctx, sec):
    sec.reading = f"pid {os.getpid()}"

steps = (demo.Step("first", "First", first), demo.Step("aside", "Aside", aside, alone=True))
result = demo.run_demo(sys.argv[1], quick=True, progress=False, steps=steps, parallel=True)
print("RESULT", result.ok, result.report.sections[1].reading == f"pid {os.getpid()}")
"""


def test_a_script_without_a_main_guard_still_gets_its_page_the_steps_run_here(tmp_path):
    """A spawned process re-imports the calling script; without ``if __name__ == "__main__"`` the
    script starts a demo there too, and the second process dies: the steps run here instead."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED)
    run = subprocess.run([sys.executable, str(script), str(tmp_path / "page")], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "RESULT True True" in run.stdout


def test_a_bug_in_a_step_run_aside_is_raised_not_written_into_the_page(tmp_path):
    steps = (ASIDE[0], demo.Step("bug", "Bug", _bug, alone=True))
    with pytest.raises(TypeError, match="a bug, not a failure"):
        demo.run_demo(tmp_path, quick=True, progress=False, steps=steps, parallel=True)


def test_rrfrei_demo_exits_nonzero_naming_the_failed_step(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(demo.steps, "STEPS", STEPS[:3])  # the default steps of run_demo
    code = main(["demo", "--out", str(tmp_path / "rep"), "--quick", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1
    assert "step 'broken' error: ValueError: the sampler diverged at step 17" in err
    assert (tmp_path / "rep" / "index.html").is_file()


def test_demo_refuses_a_negative_seed_and_an_out_path_that_is_a_file(tmp_path):
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        demo.run_demo(tmp_path, seed=-1, steps=STEPS[:1])
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a folder"):
        demo.run_demo(f, steps=STEPS[:1])


def test_quick_settings_are_smaller_than_the_full_run_in_every_long_step():
    q, f = demo.DemoSettings.quick_run(), demo.DemoSettings.full_run()
    assert q.quick and not f.quick
    assert q.walkers * q.steps < f.walkers * (f.steps or f.max_steps)
    assert q.gap_draws < f.gap_draws
    assert q.n_samples < f.n_samples and q.rubber_evals < f.rubber_evals
    assert q.records is not None and f.records is None  # full run: every bundled record

