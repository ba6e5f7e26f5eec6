"""Command-line interface: ``rrfrei <command> ...`` (also ``python -m rrfrei.app``).

Each command lives in ``rrfrei/app/commands/<name>.py`` and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (called with the parsed args, returns an exit code).
Errors a user can fix (bad path, malformed file, unknown law or record, bad parameter) become
one line on stderr and exit status 2, never a traceback; a numerical failure
(:data:`rrfrei.errors.NUMERICAL_ERRORS`: a local solve, a singular matrix) exits 1 and says
what failed where.
"""

from __future__ import annotations

import argparse
import sys

from rrfrei.app.commands import calibrate, compare, demo, gap, gap_validate, kernels, propagate, shake_table
from rrfrei.errors import NUMERICAL_ERRORS

#: Command modules, in the order they appear in --help.
COMMAND_MODULES = (calibrate, compare, gap, gap_validate, propagate, shake_table, demo, kernels)
#: Their names (the module names; ``gap_validate`` is the ``gap-validate`` command, ``shake_table``
#: the ``shake-table`` command).
COMMANDS = tuple(m.__name__.rpartition(".")[2] for m in COMMAND_MODULES)

USER_ERRORS = (ValueError, FileNotFoundError, IsADirectoryError, PermissionError, KeyError)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse exits 2 already; keep one line
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="rrfrei",
        description="Calibrate isolator laws, run buildings on them, and diagnose the gap to tests.",
        epilog="Example: rrfrei demo --out report --quick",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for module in COMMAND_MODULES:
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except NUMERICAL_ERRORS as exc:  # before USER_ERRORS: LinAlgError is a ValueError too
        print(f"rrfrei {args.command}: numerical failure: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except USER_ERRORS as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        if isinstance(exc, (FileNotFoundError, IsADirectoryError, PermissionError)) and exc.filename:
            msg = f"{exc.strerror}: {exc.filename}"
        print(f"rrfrei {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rrfrei {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
