"""Shake-table run metadata from the command line: ``--rate-hz``, ``--weights``/``--masses``,
``--level-order``, ``--a1``; reading the runs with them and showing the reader's warnings.

Used by ``rrfrei shake-table``.  The sidecar keys these options stand for, their units and what
the reader checks: ``docs/shake_table_data.md``.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import warnings
from collections.abc import Sequence

from structures.shake_table import (
    A1_LEVELS,
    LEVEL_ORDERS,
    MASS_UNITS,
    WEIGHT_UNITS,
    ConsistencyWarning,
    MetadataError,
    ShakeTableRun,
    open_run,
)

DOC = "docs/shake_table_data.md"

_NUMBER_UNIT = re.compile(r"^\s*([-+0-9.eE]+)\s*([A-Za-z]*)\s*$")


def quantities(text: str, units: dict[str, float], option: str) -> tuple[list[float], str | None]:
    """``"120,110,100"`` or ``"120kN,110kN,100kN"`` -> (values, unit or None): one unit for all
    values: a unit suffix on any item applies to all; mixed units are an error)."""
    values, found = [], set()
    for i, tok in enumerate(str(text).split(",")):
        m = _NUMBER_UNIT.match(tok)
        if m is None or not m.group(1):
            raise ValueError(f"{option}: item {i + 1} {tok.strip()!r} is not a number with an "
                             f"optional unit ({', '.join(units)}); expected e.g. 120,110,100")
        try:
            x = float(m.group(1))
        except ValueError:
            raise ValueError(f"{option}: item {i + 1} {tok.strip()!r} is not a number") from None
        if not (math.isfinite(x) and x > 0):
            raise ValueError(f"{option}: item {i + 1} = {tok.strip()!r} is invalid: expected a "
                             "finite number > 0")
        if m.group(2):
            if m.group(2) not in units:
                raise ValueError(f"{option}: unit {m.group(2)!r} of item {i + 1} is unknown; "
                                 f"expected one of {', '.join(units)}")
            found.add(m.group(2))
        values.append(x)
    if len(found) > 1:
        raise ValueError(f"{option}: mixed units {', '.join(sorted(found))}; give one unit")
    return values, (found.pop() if found else None)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The metadata options of ``rrfrei shake-table`` (they apply to every RUN given)."""
    g = p.add_argument_group(
        "run metadata (raw folders a1..aN, d1..dN, u, du; they apply to every RUN and override its "
        f"sidecar run.toml; format and checks: {DOC})")
    g.add_argument("--rate-hz", type=float, default=None, metavar="HZ",
                   help="sampling rate of the recorded runs [Hz] (sidecar: rate_hz; a CSV's rate is its "
                        "time column, which this must match); not --rate, the rate the law is fitted at")
    g.add_argument("--weights", default=None, metavar="W1,W2,...",
                   help="level weights, comma-separated, in --level-order, with a unit: --weight-unit kN "
                        "or a suffix (2275.1kN,674kN,...) (sidecar: [levels] weights, weight_unit); "
                        "divided by g = 9.81 m/s^2")
    g.add_argument("--weight-unit", choices=sorted(WEIGHT_UNITS), default=None,
                   help="unit of --weights (no default: weights need a stated unit)")
    g.add_argument("--masses", default=None, metavar="M1,M2,...",
                   help="level masses, comma-separated, in --level-order, in t (or a suffix t, kg) "
                        "(sidecar: [levels] masses, mass_unit)")
    g.add_argument("--level-order", choices=LEVEL_ORDERS, default=None,
                   help="how --weights/--masses (and sidecar names, masses, weights) run: from the base "
                        "slab above the isolators up (base-first, the default) or from the roof down "
                        "(roof-first) (sidecar: [levels] level_order)")
    g.add_argument("--a1", choices=A1_LEVELS, default=None,
                   help="the level the files a1/d1 of a folder hold: roof (default, the BNCS convention: "
                        "aN is the base slab) or base (sidecar: [levels] a1)")


def reader_options(args) -> dict:
    """Keyword arguments of :func:`structures.shake_table.read_run` from the parsed options."""
    kw: dict = {}
    if args.rate_hz is not None:
        if not (math.isfinite(args.rate_hz) and args.rate_hz > 0):
            raise ValueError(f"--rate-hz must be a finite number > 0 Hz, got {args.rate_hz}")
        kw["rate_hz"] = args.rate_hz
    if args.weights is not None and args.masses is not None:
        raise ValueError("give --weights or --masses, not both")
    if args.weight_unit is not None and args.weights is None:
        raise ValueError("--weight-unit is the unit of --weights, which is not given")
    if args.weights is not None:
        values, unit = quantities(args.weights, WEIGHT_UNITS, "--weights")
        if unit and args.weight_unit and unit != args.weight_unit:
            raise ValueError(f"--weights are in {unit} but --weight-unit says {args.weight_unit}; give one")
        unit = unit or args.weight_unit
        if unit is None:
            raise ValueError(f"--weights {args.weights} has no unit: add --weight-unit "
                             f"({', '.join(WEIGHT_UNITS)}) or a suffix (e.g. 2275.1kN,674kN,...)")
        kw["weights"], kw["weight_unit"] = values, unit
    if args.masses is not None:
        values, unit = quantities(args.masses, MASS_UNITS, "--masses")
        kw["masses"] = [v * MASS_UNITS[unit or "t"] for v in values]
    if args.level_order is not None:
        kw["level_order"] = args.level_order
    if args.a1 is not None:
        kw["a1"] = args.a1
    return kw


_CLI_HINT = {
    "rate_hz": "give --rate-hz HZ, or rate_hz = ... in {sidecar}",
    "masses": "give --weights W1,W2,... --weight-unit kN (or --masses in t), base slab first unless "
              "--level-order roof-first, or [levels] weights/masses in {sidecar}",
    "time": "check the time column and the unit suffixes of its columns",
}


_OPTION_OF = {"the argument rate_hz": "--rate-hz", "the argument weights": "--weights",
              "the argument masses": "--masses", "the argument level_order": "--level-order"}


def _options(text: str) -> str:
    """The reader's words for its arguments ("the argument rate_hz") as the options that gave them."""
    for said, option in _OPTION_OF.items():
        text = text.replace(said, option)
    return text


def _one_line(message: str) -> str:
    return "; ".join(s.strip() for s in str(message).splitlines() if s.strip())


def read_runs(specs: Sequence[str], args, *, prog: str = "rrfrei shake-table"
              ) -> tuple[list[ShakeTableRun], list[str]]:
    """The runs ``specs`` (bundled names, folders, CSVs) read with the metadata options, and the
    reader's warnings as notes (each printed on stderr as it comes).  A run whose rate or masses
    are missing, or whose channels contradict its rate, is a ``ValueError`` worded for the command
    line (the option and the sidecar key)."""
    kw = reader_options(args)
    runs, notes = [], []
    for spec in specs:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                run = open_run(spec, **kw)
            except MetadataError as exc:
                hint = _CLI_HINT[exc.what].format(sidecar=exc.sidecar or "its sidecar")
                raise ValueError(f"{_options(exc.fact)}: {hint} ({DOC})") from None
            except ValueError as exc:
                raise ValueError(_options(str(exc))) from None
        for w in caught:
            if issubclass(w.category, ConsistencyWarning):
                note = _options(_one_line(w.message))
                print(f"{prog}: warning: {note}", file=sys.stderr)
                notes.append(note)
        runs.append(run)
    return runs, notes
