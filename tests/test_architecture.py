"""docs/architecture.md stays true: every module, function and file it names exists, every
`rrfrei` command it names is one of the CLI's, and its layer table is the one
tests/test_layers.py enforces (issue 28.6)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from tests.test_layers import PACKAGES, RANKS, layer_of

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
TEXT = PAGE.read_text()

#: backticked spans of the page (inline code only; the page has no fenced blocks)
SPANS = re.findall(r"`([^`\n]+)`", TEXT)
DOTTED = sorted({s for s in SPANS
                 if re.fullmatch(r"[A-Za-z_][\w]*(\.[A-Za-z_]\w*)+|[A-Za-z_]\w*", s)
                 and s.split(".")[0] in PACKAGES})
PATHS = sorted({s for s in SPANS if re.fullmatch(r"[\w./-]+/[\w./-]*", s) and not s.startswith("../")})
COMMANDS = sorted({m.group(1) for s in SPANS for m in [re.match(r"rrfrei ([a-z][a-z-]*)\b", s)] if m})


def resolve(name: str) -> object:
    """The object a dotted name denotes: the longest importable module prefix, then attributes.
    Raises LookupError naming what is missing."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        module_name = ".".join(parts[:cut])
        try:
            obj = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and not module_name.startswith(exc.name):
                raise  # a module that exists failed to import something else
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                raise LookupError(f"{name}: {'.'.join(parts[:parts.index(attr)])} has no {attr!r}")
            obj = getattr(obj, attr)
        return obj
    raise LookupError(f"{name}: no module {parts[0]!r}")


def test_the_page_names_enough_to_be_checked():
    assert len(DOTTED) > 60 and len(PATHS) >= 5 and {"calibrate", "propagate"} <= set(COMMANDS)


@pytest.mark.parametrize("name", DOTTED)
def test_every_named_module_and_function_exists(name):
    resolve(name)


@pytest.mark.parametrize("path", PATHS)
def test_every_named_file_or_folder_exists(path):
    assert (ROOT / path).exists(), f"docs/architecture.md names {path}, which is not in the repository"


def test_every_named_command_is_one_of_the_cli():
    from rrfrei.app.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = set(COMMANDS) - set(sub.choices)
    assert not missing, f"docs/architecture.md names commands the CLI lacks: {sorted(missing)}"


def _layer_rows() -> list[tuple[int, str, list[str]]]:
    section = TEXT.split("## Layers", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0].isdigit():
            rows.append((int(cells[0]), cells[1], re.findall(r"`([^`]+)`", cells[2])))
    return rows


def test_the_layer_table_is_the_one_test_layers_enforces():
    rows = _layer_rows()
    assert {layer for _, layer, _ in rows} == set(RANKS)
    for rank, layer, modules in rows:
        assert RANKS[layer] == rank, f"layer {layer}: rank {rank} here, {RANKS[layer]} in test_layers"
        assert modules, f"layer {layer} lists no module"
        for module in modules:
            assert layer_of(module) == layer, f"{module} is in layer {layer_of(module)}, not {layer}"


def test_the_route_from_the_cli_reaches_a_law_step_kernel():
    """The calibrate route ends at a registered law's step kernel."""
    from rrfrei.laws import get

    route = TEXT.split("## From the command line to a kernel", 1)[1]
    steps = re.findall(r"`(rrfrei\.laws\.(\w+)\.step)`", route)
    assert steps
    for name, law in steps:
        assert resolve(name) is get(law).step


def test_resolve_reports_what_is_missing():
    with pytest.raises(LookupError, match="has no 'no_such_function'"):
        resolve("rrfrei.laws.registry.no_such_function")
    with pytest.raises(LookupError, match="no module"):
        resolve("no_such_package.x")
