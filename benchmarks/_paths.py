"""Imported first by every benchmark script (run as ``python benchmarks/bench_x.py``): puts
this folder, the repository root and ``tests/`` (the openseespy peers) at the front of
``sys.path``, so a script runs the checkout's packages and helpers whatever the current folder.
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
for _i, _folder in enumerate((HERE, HERE.parent, HERE.parent / "tests")):
    sys.path.insert(_i, str(_folder))
