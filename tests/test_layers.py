"""The layers of the project point one way: each imports only the layers below it.

Bottom to top (also in README's layout section and :mod:`rrfrei.app`):

0. ``rrfrei._jit_cache`` and the ``rrfrei`` package root (which only sets the cache up);
1. ``ground_motions``;
2. the ``rrfrei`` core: every ``rrfrei.*`` module outside ``rrfrei.app``;
3. ``structures`` and, beside it, ``rubber`` (neither imports the other);
4. ``rrfrei.app``: the CLI, its commands, the demo and the report page.

Checked three ways: importing every module of a layer in a fresh interpreter loads no module of a
layer at or above it (other than itself); no import statement anywhere, also inside a function,
names a module of such a layer; and imports across layers are ordinary top-level imports, with
``importlib``/``__import__`` used only by the two registries that need it.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ground_motions", "rrfrei", "structures", "rubber")

#: layer name -> rank (bottom 0); layers of equal rank are siblings and must not import each other
RANKS = {"jit_cache": 0, "ground_motions": 1, "core": 2, "structures": 3, "rubber": 3, "app": 4}

#: Files that may use importlib/__import__ to import project modules, and why.
IMPORTLIB_ALLOWED = {
    # the package's lazy public names (rrfrei.calibrate, ...): all of them core modules, imported
    # on first use so that `import rrfrei` (run by every package through rrfrei._jit_cache) is cheap
    "rrfrei/__init__.py",
    # the law-template instantiator: imports a template module by its dotted name and the
    # generated per-law file by its path (rrfrei.laws.specialise)
    "rrfrei/laws/specialise.py",
    # the law table and the effect table discover their entries (one module each in
    # rrfrei/laws/ and rrfrei/laws/effects/) with pkgutil (registry.import_entries), so adding a
    # law or an effect touches no other file (issue 13.1)
    "rrfrei/laws/registry.py",
    # the command table (rrfrei.app.commands.HELPS): a command's module is imported when the
    # command runs, so `rrfrei calibrate` does not import the demo, the buildings or Dask (28.7)
    "rrfrei/app/cli.py",
}

#: (importing file, imported module) pairs allowed to cross layers inside a function, and why.
DEFERRED_ALLOWED = {
    # looks the cache folder up when a kernel is first instantiated (layer 0, below the core)
    ("rrfrei/laws/specialise.py", "rrfrei._jit_cache"),
}


def layer_of(module: str) -> str | None:
    """The layer of a dotted module name, None for a module outside the project."""
    top = module.split(".")[0]
    if top not in PACKAGES:
        return None
    if module in ("rrfrei", "rrfrei._jit_cache"):
        return "jit_cache"
    if top == "rrfrei":
        return "app" if module == "rrfrei.app" or module.startswith("rrfrei.app.") else "core"
    return top


def forbidden_for(layer: str, module: str) -> bool:
    """True when ``layer`` must not import ``module``: a layer above it, or a sibling."""
    other = layer_of(module)
    return other is not None and other != layer and RANKS[other] >= RANKS[layer]


def source_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules_of(layer: str) -> list[str]:
    """Every importable module of a layer (entry-point ``__main__`` modules left out)."""
    names = [module_name(p) for p in source_files() if p.name != "__main__.py"]
    return [n for n in names if layer_of(n) == layer]


def test_the_layer_table_covers_every_module_of_the_packages():
    names = [module_name(p) for p in source_files()]
    assert all(layer_of(n) in RANKS for n in names)
    for layer in RANKS:
        assert modules_of(layer), f"layer {layer} has no module: the table is out of date"


PROBE = """
import json, sys
for name in json.loads(sys.argv[1]):
    __import__(name)
print(json.dumps(sorted(sys.modules)))
"""


@pytest.mark.parametrize("layer", list(RANKS))
def test_importing_a_layer_in_a_fresh_interpreter_loads_nothing_above_it(layer):
    names = modules_of(layer)
    proc = subprocess.run([sys.executable, "-c", PROBE, json.dumps(names)], capture_output=True, text=True,
                          cwd=ROOT, timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0, proc.stderr[-3000:]
    loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert set(names) <= set(loaded)
    above = sorted(m for m in loaded if forbidden_for(layer, m))
    assert not above, f"importing layer {layer!r} loaded modules of layers above or beside it: {above}"


def _imports(path: Path) -> list[tuple[str, bool, int]]:
    """(absolute module name, at module top?, line) of every import statement of a file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    top_level = {id(n) for n in tree.body}
    # imports directly under a module-level if/try (e.g. TYPE_CHECKING) count as top level
    for n in tree.body:
        if isinstance(n, (ast.If, ast.Try)):
            top_level.update(id(c) for c in ast.walk(n))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # `from pkg import sub` imports the submodule pkg.sub when there is one
            names = [f"{mod}.{a.name}" if _is_module(f"{mod}.{a.name}") else mod for a in node.names]
        else:
            continue
        out += [(n, id(node) in top_level, node.lineno) for n in dict.fromkeys(names)]
    return out


def _is_module(name: str) -> bool:
    base = ROOT.joinpath(*name.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def test_no_import_statement_anywhere_points_up_or_sideways():
    bad = []
    for path in source_files():
        layer = layer_of(module_name(path))
        for mod, _, line in _imports(path):
            if forbidden_for(layer, mod):
                bad.append(f"{path.relative_to(ROOT)}:{line} ({layer}) imports {mod} ({layer_of(mod)})")
    assert not bad, "\n".join(bad)


def test_imports_across_layers_are_ordinary_top_level_imports():
    bad = []
    for path in source_files():
        rel = path.relative_to(ROOT).as_posix()
        layer = layer_of(module_name(path))
        for mod, top, line in _imports(path):
            other = layer_of(mod)
            if other is not None and other != layer and not top and (rel, mod) not in DEFERRED_ALLOWED:
                bad.append(f"{rel}:{line} imports {mod} inside a function")
    assert not bad, "\n".join(bad)


def _dynamic_imports(path: Path) -> list[int]:
    """Lines that import modules dynamically: importlib (but importlib.resources) or __import__."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "importlib" for a in node.names):
            lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "importlib":
            if not (node.module == "importlib" and all(a.name == "resources" for a in node.names)):
                lines.append(node.lineno)
        elif isinstance(node, ast.Name) and node.id == "__import__":
            lines.append(node.lineno)
        elif isinstance(node, ast.Attribute) and node.attr == "__import__":
            lines.append(node.lineno)
    return lines


def test_only_the_named_registries_import_project_modules_dynamically():
    found = {p.relative_to(ROOT).as_posix(): _dynamic_imports(p) for p in source_files()}
    users = {k for k, v in found.items() if v}
    assert users <= IMPORTLIB_ALLOWED, {k: found[k] for k in sorted(users - IMPORTLIB_ALLOWED)}
    assert users == IMPORTLIB_ALLOWED, f"no longer dynamic: {IMPORTLIB_ALLOWED - users}"


def test_the_checks_catch_what_they_are_meant_to_catch(tmp_path):
    """The static checks fail on an upward import, a deferred cross-layer import and importlib."""
    assert forbidden_for("core", "structures.propagation.propagate")
    assert forbidden_for("structures", "rubber.gap")
    assert forbidden_for("ground_motions", "rrfrei.laws") and forbidden_for("core", "rrfrei.app.cli")
    assert not forbidden_for("app", "structures") and not forbidden_for("ground_motions", "rrfrei._jit_cache")
    probe = tmp_path / "probe.py"
    probe.write_text("import importlib\n\ndef f():\n    return __import__('structures')\n")
    assert _dynamic_imports(probe) == [1, 4]
    probe.write_text("from importlib import resources\n")
    assert _dynamic_imports(probe) == []
