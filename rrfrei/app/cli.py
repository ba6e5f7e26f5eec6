"""Command-line interface: ``rrfrei <command> ...`` (also ``python -m rrfrei.app``).

Each command lives in ``rrfrei/app/commands/<name>.py`` and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (called with the parsed args, returns an exit code).
A command's module is imported only when that command runs (:func:`main` builds its parser in
full and the others as their one-line help, :data:`rrfrei.app.commands.HELPS`), so
``rrfrei calibrate`` starts without the demo, the building stack or Dask; a module that cannot
be imported stops its command with an ImportError naming it, never a CLI without it.
Errors a user can fix (bad path, malformed file, unknown law or record, bad parameter) become
one line on stderr and exit status 2, never a traceback; a numerical failure
(:data:`rrfrei.errors.NUMERICAL_ERRORS`: a local solve, a singular matrix) exits 1 and says
what failed where.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Iterable

from rrfrei._text import plain_numbers
from rrfrei.app.commands import HELPS
from rrfrei.errors import NUMERICAL_ERRORS

#: Command modules (names under ``rrfrei.app.commands``), in the order they appear in --help;
#: ``gap_validate`` is the ``gap-validate`` command, ``shake_table`` the ``shake-table`` command.
COMMANDS = tuple(HELPS)

USER_ERRORS = (ValueError, FileNotFoundError, IsADirectoryError, PermissionError, KeyError)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse exits 2 already; keep one line
        self.exit(2, f"{self.prog}: error: {message}\n")


def command_name(module: str) -> str:
    """The command as typed for command module ``module`` (``gap_validate`` -> ``gap-validate``)."""
    return module.replace("_", "-")


def build_parser(full: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The parser of the ``rrfrei`` command.

    ``full``: the command modules (:data:`COMMANDS`) whose parsers are built in full, their
    modules imported (None: every command); the others are listed with their one-line help only.
    """
    parser = _Parser(
        prog="rrfrei",
        description="Calibrate isolator laws, run buildings on them, and diagnose the gap to tests.",
        epilog="Example: rrfrei demo --out report --quick",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    full = set(COMMANDS if full is None else full)
    for module in COMMANDS:
        if module in full:
            importlib.import_module(f"rrfrei.app.commands.{module}").register(sub)
        else:
            sub.add_parser(command_name(module), help=HELPS[module])
    return parser


def _command(argv: list[str]) -> list[str]:
    """The command module named by ``argv`` (its first word not an option), as a list of none or one."""
    typed = next((a for a in argv if not a.startswith("-")), None)
    return [m for m in COMMANDS if command_name(m) == typed]


def passive_omp_wait() -> None:
    """``OMP_WAIT_POLICY=PASSIVE`` for this process unless the user chose a policy.

    Numba's parallel kernels run on the OpenMP threading layer, whose threads by default spin
    while they wait for work.  When the cores are shared with other processes the spinning
    threads take the CPU from the working one, and a batched law run of one row became tens of
    times slower than on one thread.  A passive wait costs a thread wake-up per parallel call on
    an idle machine.  OpenMP reads the variable when it starts, at the first parallel kernel
    call, so the command sets it before it runs (importing the package changes nothing).
    """
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    passive_omp_wait()
    parser = build_parser(_command(argv))
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except NUMERICAL_ERRORS as exc:  # before USER_ERRORS: LinAlgError is a ValueError too
        print(plain_numbers(f"rrfrei {args.command}: numerical failure: {type(exc).__name__}: {exc}"),
              file=sys.stderr)
        return 1
    except USER_ERRORS as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        if isinstance(exc, (FileNotFoundError, IsADirectoryError, PermissionError)) and exc.filename:
            msg = f"{exc.strerror}: {exc.filename}"
        print(plain_numbers(f"rrfrei {args.command}: error: {msg}"), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rrfrei {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
