"""The CLI imports a command's module only when that command runs (issue 28.7: the 2,401-point
``rrfrei calibrate`` spent seconds importing the demo, the building stack and Dask it never uses),
and ``rrfrei --help`` still lists every command with its help."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import pytest

from rrfrei.app import cli
from rrfrei.app.commands import HELPS

#: Packages only other commands need: none is imported by ``rrfrei calibrate`` or ``--help``.
OTHERS = ("structures", "dask", "distributed", "rrfrei.app.demo", "rrfrei.gap", "rubber")

PROBE = """
import json, sys
from rrfrei.app.cli import main
try:
    main({argv!r})
except SystemExit:
    pass
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in {{"structures", "dask",
      "distributed", "rubber"}} or m.startswith(("rrfrei.app.commands.", "rrfrei.app.demo",
      "rrfrei.gap")))))
"""


def _loaded(argv: list[str]) -> list[str]:
    """Modules of other commands loaded by ``rrfrei ARGV`` in a fresh interpreter."""
    run = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv)], capture_output=True,
                         text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_rrfrei_help_imports_no_command_module():
    assert _loaded(["--help"]) == []


def test_rrfrei_calibrate_imports_its_module_and_none_of_the_others_dependencies():
    loaded = _loaded(["calibrate", "--help"])
    assert "rrfrei.app.commands.calibrate" in loaded
    others = [m for m in loaded if m.startswith(OTHERS)
              or (m.startswith("rrfrei.app.commands.") and m not in ("rrfrei.app.commands.calibrate",
                                                                     "rrfrei.app.commands.args"))]
    assert others == []


def test_help_lists_every_command_with_its_modules_help_line(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = "".join(capsys.readouterr().out.split())  # argparse wraps (and hyphen-breaks) the lines
    for module in cli.COMMANDS:
        help_line = importlib.import_module(f"rrfrei.app.commands.{module}").HELP
        assert help_line == HELPS[module]
        assert "".join(f"{cli.command_name(module)} {help_line}".split()) in out


@pytest.mark.parametrize("module", cli.COMMANDS)
def test_each_command_parses_as_when_every_parser_is_built(module):
    """The parser built for one command is the one built with all of them (same options)."""
    name = cli.command_name(module)
    alone = cli.build_parser([module])._subparsers._group_actions[0].choices[name]
    every = cli.build_parser()._subparsers._group_actions[0].choices[name]
    assert alone.format_help() == every.format_help()


OMP_PROBE = """
import os
import rrfrei.app.cli as cli
before = os.environ.get("OMP_WAIT_POLICY")
try:
    cli.main(["--help"])
except SystemExit:
    pass
print(before, os.environ.get("OMP_WAIT_POLICY"))
"""


@pytest.mark.parametrize("user, expected", [(None, "None PASSIVE"), ("ACTIVE", "ACTIVE ACTIVE")])
def test_the_command_waits_passively_for_openmp_work_unless_the_user_chose(user, expected):
    """Spinning OpenMP threads take the CPU from the working one on shared cores (a batched law
    run 20-30 times slower under load): the command asks for a passive wait, the import alone
    changes nothing, and a policy the user set is kept."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if user is not None:
        env["OMP_WAIT_POLICY"] = user
    run = subprocess.run([sys.executable, "-c", OMP_PROBE], capture_output=True, text=True,
                         check=True, env=env)
    assert run.stdout.strip().splitlines()[-1] == expected
