"""Nothing tracked names a path of one machine: data is in the repository or at ``../shared``.

A test that reads the shared data by an absolute path of one machine skips or checks nothing on
another machine; a docstring that cites one points nowhere.  Every tracked Python, Markdown,
TOML and CI file is scanned.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MACHINE_PATH = re.compile(r"(?<![.\w])/(work|root|home|tmp)/\w")


def test_no_tracked_file_names_an_absolute_machine_path():
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    assert files, "git ls-files found nothing: not a checkout?"
    hits = []
    for name in files:
        if not (name.endswith((".py", ".md", ".toml")) or name.startswith(".ci/")):
            continue
        if name.startswith("docs/reference/"):  # verbatim copies of the reference notes
            continue
        for i, line in enumerate((ROOT / name).read_text(errors="replace").splitlines(), 1):
            if MACHINE_PATH.search(line):
                hits.append(f"{name}:{i}: {line.strip()[:100]}")
    assert not hits, "absolute machine paths:\n" + "\n".join(hits)
