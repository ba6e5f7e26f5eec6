"""Write one benchmark's section of ``benchmarks/RESULTS.md`` (other sections are kept).

Each script owns the block between ``<!-- NAME:start -->`` and ``<!-- NAME:end -->``.
"""

from __future__ import annotations

import json
import os
import platform
import re
import time
from pathlib import Path

RESULTS = Path(__file__).with_name("RESULTS.md")
HEADLINE = Path(__file__).with_name("headline.json")  # the figures README's speed table quotes
HEADER = (
    "# Benchmark results\n\n"
    "Every ratio is measured against the peer (openseespy, NumPy, scipy) in the same run on the "
    "same machine, by the rules of `benchmarks/_timing.py` (see `benchmarks/README.md`): warm-up "
    "excluded on both sides, the same number of interleaved repeats, the median, the peer's model "
    "building and teardown outside its timer, agreement asserted in the same run. **Per core** "
    "ratios put one thread against one thread; multi-core throughput is reported separately. "
    "Regenerate a section with `python benchmarks/<script>.py`.\n"
)


def machine() -> str:
    """Processor, cores, Python, date and the 1-minute load average (when available)."""
    try:
        load = f", load average {os.getloadavg()[0]:.1f}"
    except OSError:
        load = ""
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d')}{load}"
    )


def write_section(name: str, markdown: str) -> None:
    """Replace (or append) the section ``name`` of RESULTS.md with ``markdown``."""
    text = RESULTS.read_text() if RESULTS.exists() else HEADER
    first = text.find("<!-- ")
    text = HEADER + "\n" + (text[first:] if first >= 0 else "")  # the rules above every section
    block = f"<!-- {name}:start -->\n{markdown.strip()}\n\n_Machine: {machine()}._\n<!-- {name}:end -->"
    pattern = re.compile(rf"<!-- {re.escape(name)}:start -->.*?<!-- {re.escape(name)}:end -->", re.S)
    if pattern.search(text):
        text = pattern.sub(lambda _m: block, text)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    RESULTS.write_text(text)


def write_headline(name: str, figures: dict) -> None:
    """Replace the entry ``name`` of headline.json (figures in SI units: s, 1/s) with ``figures``."""
    data = json.loads(HEADLINE.read_text()) if HEADLINE.exists() else {}
    data[name] = {**figures, "machine": machine()}
    HEADLINE.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")


def report(name: str, markdown: str, *, quick: bool, headline: dict | None = None) -> None:
    """Print ``markdown``; unless this is a ``--quick`` smoke run, write it as section ``name`` of
    RESULTS.md and ``headline`` (the figures README's speed table quotes) to headline.json."""
    print(markdown)
    if quick:
        print(f"\n(--quick: section {name!r} of {RESULTS.name} and {HEADLINE.name} left unchanged)")
        return
    write_section(name, markdown)
    if headline is not None:
        write_headline(name, headline)
