"""No private name crosses a package boundary (issue 28.4).

A name or module that starts with one underscore belongs to the package that holds it: that
package and its sub-packages may import it (``rrfrei.gap.decision`` may use ``rrfrei._inputs``),
no other package may (``rrfrei.app`` may not take ``rrfrei.calibration.compare._az``, nor
``structures`` take ``rrfrei._inputs``).  What another package needs is made public in one place.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rrfrei", "structures", "rubber", "ground_motions")

#: imports that still cross a boundary, each in a module being reworked elsewhere: (importer file,
#: imported module, name).  Remove an entry when its import is fixed; never add one.
KNOWN = {
    # the kernel cache locator (layer 0), imported first by every package (issue 28.5 reworks it)
    ("ground_motions/__init__.py", "rrfrei._jit_cache", ""),
    ("rubber/__init__.py", "rrfrei._jit_cache", ""),
    ("structures/__init__.py", "rrfrei._jit_cache", ""),
    # plain-number text of the rrfrei package, used by rubber's command line
    ("rubber/__main__.py", "rrfrei._text", "plain_numbers"),
}


def _private(part: str) -> bool:
    return part.startswith("_") and not part.startswith("__")


def package_of(path: Path) -> str:
    """The dotted package a source file belongs to (a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1])


def owner(module: str, name: str | None) -> str | None:
    """The package a private module or name belongs to, or None when nothing imported is private.

    ``rrfrei._inputs`` belongs to ``rrfrei``; ``_az`` of ``rrfrei.calibration.compare`` belongs to
    ``rrfrei.calibration`` (the package holding the module)."""
    parts = module.split(".")
    for i, part in enumerate(parts):
        if _private(part):
            return ".".join(parts[:i])
    if name is not None and _private(name):
        is_package = (ROOT.joinpath(*parts) / "__init__.py").is_file()
        return module if is_package else ".".join(parts[:-1])
    return None


def crossings(path: Path) -> list[tuple[str, str, str]]:
    """(file, module, name) of every import in ``path`` of a private module or name owned by a
    package that does not contain the importing file."""
    here = package_of(path)
    rel = path.relative_to(ROOT).as_posix()
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=rel)):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            pairs = [(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            pairs = [(a.name, None) for a in node.names]
        else:
            continue
        for module, name in pairs:
            if module.split(".")[0] not in PACKAGES:
                continue
            who = owner(module, name)
            if who is not None and here != who and not here.startswith(who + "."):
                out.append((rel, module, name or ""))
    return out


def all_crossings() -> set[tuple[str, str, str]]:
    return {c for pkg in PACKAGES for f in sorted((ROOT / pkg).rglob("*.py")) for c in crossings(f)}


def test_the_rule_sees_a_crossing_and_allows_a_parents_private_module():
    app = ROOT / "rrfrei" / "app" / "commands" / "calibrate.py"
    gap = ROOT / "rrfrei" / "gap" / "decision.py"
    assert owner("rrfrei.calibration.compare", "_az") == "rrfrei.calibration"
    assert owner("rrfrei._inputs", "check") == "rrfrei"
    assert owner("rrfrei.jsonable", "number") is None  # public: any package may use it
    assert owner("rrfrei.calibration.compare", "compare") is None
    assert package_of(app) == "rrfrei.app.commands"
    here, who = package_of(gap), owner("rrfrei._inputs", "check")
    assert here.startswith(who + ".")  # a sub-package may use its parent's private module
    assert not package_of(app).startswith(owner("rrfrei.calibration.compare", "_az") + ".")


def test_no_private_name_is_imported_across_packages():
    found = all_crossings()
    new = sorted(found - KNOWN)
    assert not new, ("private names imported across packages (make the shared thing public in one "
                     f"place): {new}")


def test_the_known_crossings_are_still_there():
    """An entry of KNOWN whose import is gone must leave the list, so that it cannot come back."""
    gone = sorted(KNOWN - all_crossings())
    assert not gone, f"remove from KNOWN (fixed): {gone}"
