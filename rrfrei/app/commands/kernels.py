"""``rrfrei kernels LAW``: the generated kernel files a law runs, so a reader can open them."""

from __future__ import annotations

import argparse
import inspect
import json
import sys

from rrfrei.app.commands import HELPS
from rrfrei.app.commands.args import add_command, add_json, paragraph
from rrfrei.calibration.likelihood import batch_kernels
from rrfrei.laws import get, specialise
from structures.dynamics.history import kernel as building_kernel

EXAMPLE = """\
Example:
  rrfrei kernels plasticity          # the template each file instantiates, then its path
  rrfrei kernels bouc_wen+rate --json
"""


HELP = HELPS["kernels"]
"""One-line help of the command in ``rrfrei --help``."""
DESCRIPTION = paragraph("""
Generate (if needed) and list the kernel files bound to LAW: the whole-history drivers of simulate
and calibrate, the batched likelihood of calibrate and the building's Newmark kernel of the time
histories, plus any other instance of the law in the kernel cache (plan forms). Each file is
verified against the hash in its name; the files live in the private per-user kernel cache.
""")
"""Description of the command in its ``--help``."""


def register(sub) -> None:
    p = add_command(sub, "kernels", help=HELP, description=DESCRIPTION, epilog=EXAMPLE)
    p.add_argument("law", metavar="LAW", help="law name, e.g. plasticity or bouc_wen+rate")
    add_json(p, "print JSON instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    spec = get(args.law)
    batch_kernels(spec)  # calibrate's batched likelihood (generates the history driver too)
    building_kernel(spec)  # the time histories' Newmark kernel
    files = specialise.kernel_files(spec)
    source = inspect.getsourcefile(inspect.getmodule(getattr(spec.step, "py_func", spec.step)))
    if args.json:
        json.dump({"law": spec.name, "law_source": source, "files": [
            {"template": t, "path": str(p)} for t, p in files]}, sys.stdout, indent=2)
        print()
        return 0
    print(f"law {spec.name}: step kernel in {source}")
    width = max((len(t) for t, _ in files), default=0)
    for template, path in files:
        print(f"  {template:<{width}}  {path}")
    return 0
