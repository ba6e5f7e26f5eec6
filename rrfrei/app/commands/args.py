"""Argument types and option helpers shared by the command modules (``rrfrei/app/commands/*.py``).

An argparse ``type`` raises :class:`argparse.ArgumentTypeError`; the CLI's parser turns it into one
line on stderr, ``rrfrei COMMAND: error: argument --OPTION: MESSAGE``, and exit status 2 (a user
error). The helpers here keep each command's option names, defaults and help texts: a command
passes its own words, the helper adds the option the same way every time.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rrfrei.budget import seconds_arg

__all__ = [
    "add_command",
    "add_json",
    "add_no_progress",
    "add_report_options",
    "add_time_budget",
    "int_arg",
    "min_int",
    "paragraph",
    "nonneg_int",
    "positive_int",
]


def int_arg(minimum: int, noun: str, *, name: str | None = None,
            default_hint: bool = False) -> Callable[[str], int]:
    """An argparse type: an integer ``>= minimum``.

    Parameters
    ----------
    minimum : int
        The smallest value accepted.
    noun : str
        What is expected, e.g. ``"a positive integer"``.
    name : str, optional
        The option's name for the message (``"samples must be a positive integer, got '0'"``);
        without it the message reads ``"expected a positive integer, got '0'"``.
    default_hint : bool, optional
        A value below ``minimum`` is named as parsed and followed by
        ``"(leave the option out for the default)"`` (0 is never a silent "default").

    Returns
    -------
    callable
        ``parse(text) -> int``, raising :class:`argparse.ArgumentTypeError` with that message.
    """
    head = f"{name} must be {noun}" if name else f"expected {noun}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{head}, got {text!r}") from None
        if value < minimum:
            if default_hint:
                raise argparse.ArgumentTypeError(
                    f"{head}, got {value} (leave the option out for the default)")
            raise argparse.ArgumentTypeError(f"{head}, got {text!r}")
        return value

    return parse


nonneg_int = int_arg(0, "a non-negative integer")
"""argparse type: an integer >= 0 (seeds); ``expected a non-negative integer, got '-1'``."""

positive_int = int_arg(1, "a positive integer")
"""argparse type: an integer >= 1 (counts); ``expected a positive integer, got '0'``."""


def min_int(minimum: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``minimum`` (0 is never a silent "default").

    Parameters
    ----------
    minimum : int
        The smallest value accepted.

    Returns
    -------
    callable
        ``parse(text) -> int``; a value below ``minimum`` says
        ``expected an integer >= 2, got 0 (leave the option out for the default)``.
    """
    return int_arg(minimum, f"an integer >= {minimum}", default_hint=True)


def add_command(sub, name: str, *, help: str, description: str,  # noqa: A002 (argparse's word)
                epilog: str) -> argparse.ArgumentParser:
    """Add the parser of command ``name`` to ``sub`` (an argparse subparsers action).

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The CLI's subparsers.
    name, help, description, epilog : str
        The command's name, one-line help, description and epilog (its examples), printed as
        written (:class:`argparse.RawDescriptionHelpFormatter`).

    Returns
    -------
    argparse.ArgumentParser
        The command's parser, to add its options to.
    """
    return sub.add_parser(name, help=help, description=description, epilog=epilog,
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def add_json(p: argparse.ArgumentParser, help: str) -> None:  # noqa: A002
    """``--json``: print the results as JSON on stdout (``help`` says which)."""
    p.add_argument("--json", action="store_true", help=help)


def add_no_progress(p: argparse.ArgumentParser, help: str = "no progress bars") -> None:  # noqa: A002
    """``--no-progress``: no tqdm progress bars."""
    p.add_argument("--no-progress", action="store_true", help=help)


def add_time_budget(p: argparse.ArgumentParser, default: float, help: str) -> None:  # noqa: A002
    """``--time-budget SECONDS|none``: a wall-clock limit [s] (``none``: no limit).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser.
    default : float
        The command's default budget [s].
    help : str
        What happens when the budget is reached, with the default stated.
    """
    p.add_argument("--time-budget", type=seconds_arg, default=default, metavar="SECONDS|none", help=help)


def paragraph(text: str) -> str:
    """``text`` as one line, its white space folded (a description written as a wrapped block).

    Parameters
    ----------
    text : str
        The text, over as many lines as reads well in the source.

    Returns
    -------
    str
        The words of ``text`` joined by single spaces.
    """
    return " ".join(text.split())


def add_report_options(p: argparse.ArgumentParser, *, out: str, budget: float, budget_help: str,
                       progress_help: str) -> None:
    """The options of a diagnosis that writes a report: ``--out``, ``--seed``, ``--json``,
    ``--time-budget`` and ``--no-progress`` (``rrfrei gap``, ``rrfrei shake-table``).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser.
    out : str
        Default output folder.
    budget : float
        Default wall-clock budget [s].
    budget_help : str
        Help of ``--time-budget``: what is reported when the budget is reached.
    progress_help : str
        Help of ``--no-progress``.
    """
    p.add_argument("--out", default=out, metavar="DIR", help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of fits and draws (default 0)")
    add_json(p, "print the JSON summary on stdout")
    add_time_budget(p, budget, help=budget_help)
    add_no_progress(p, progress_help)
