"""benchmarks/RESULTS.md opens with a summary of the headline figures (the table README used to
carry), rebuilt from headline.json by ``readme_table.py --write``; a benchmark rewriting its own
section keeps the summary in place (issue 28.6)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import _results  # noqa: E402
import readme_table  # noqa: E402


def test_the_summary_goes_before_the_first_section_and_is_replaced_not_repeated(tmp_path):
    path = tmp_path / "RESULTS.md"
    path.write_text(_results.HEADER + "\n<!-- a:start -->\n## a\n<!-- a:end -->\n")
    readme_table.write_summary("## Summary\nold", path)
    readme_table.write_summary("## Summary\nnew", path)
    text = path.read_text()
    assert text.count("<!-- summary:start -->") == 1 and "old" not in text
    assert text.index("## Summary\nnew") < text.index("<!-- a:start -->")
    assert text.startswith(_results.HEADER)


def test_a_benchmark_section_rewrite_keeps_the_summary_first(tmp_path, monkeypatch):
    path = tmp_path / "RESULTS.md"
    path.write_text(_results.HEADER + "\n<!-- a:start -->\n## a\n<!-- a:end -->\n")
    readme_table.write_summary("## Summary\nfigures", path)
    monkeypatch.setattr(_results, "RESULTS", path)
    _results.write_section("a", "## a\nrerun")
    _results.write_section("b", "## b\nnew")
    text = path.read_text()
    order = [text.index(f"<!-- {name}:start -->") for name in ("summary", "a", "b")]
    assert order == sorted(order)
    assert "figures" in text and "rerun" in text
