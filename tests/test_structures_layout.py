"""structures/ is four sub-packages by idea (issue 28.1): building, dynamics, propagation,
shake_table.  A sub-package that setuptools would not find, a kernel source the cache does not
hash, bundled data left behind by a move, or a sub-package named like one of the package's own
verbs (``structures.time_history`` is a function: a sub-package of that name would shadow it, or
be shadowed) breaks an install or a reader's import; these checks catch each."""

from __future__ import annotations

import importlib
from pathlib import Path

import structures
from rrfrei import _jit_cache

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "structures"
SUBPACKAGES = ("building", "dynamics", "propagation", "shake_table")


def test_structures_is_its_sub_packages_and_its_face():
    assert sorted(p.name for p in PKG.glob("*.py")) == ["__init__.py"]
    assert sorted(p.parent.name for p in PKG.glob("*/__init__.py")) == sorted(SUBPACKAGES)


def test_every_folder_of_python_files_is_a_package_setuptools_finds():
    for d in [PKG, *(p for p in PKG.rglob("*") if p.is_dir())]:
        if any(d.glob("*.py")):
            assert (d / "__init__.py").is_file(), f"{d.relative_to(ROOT)} holds modules but no __init__.py"
    assert 'include = ["rrfrei*", "structures*"' in (ROOT / "pyproject.toml").read_text()


def test_no_sub_package_shadows_a_name_of_the_package_face():
    for name in SUBPACKAGES:
        assert name not in structures.__all__
        assert importlib.import_module(f"structures.{name}").__name__ == f"structures.{name}"
        assert getattr(structures, name).__name__ == f"structures.{name}"


def test_every_kernel_module_of_the_sub_packages_is_hashed_by_the_kernel_cache():
    hashed = set(_jit_cache.kernel_sources(ROOT))
    numba_files = {p for p in PKG.rglob("*.py") if b"numba" in p.read_bytes()}
    assert numba_files <= hashed
    assert {PKG / "dynamics" / "newmark.py", PKG / "dynamics" / "plan_newmark.py",
            PKG / "dynamics" / "newmark_chain.py"} <= numba_files


def test_bundled_buildings_and_runs_are_found_beside_their_readers():
    assert structures.available_buildings() == ("five_story", "three_story")
    assert set(structures.available_runs()) == {"CNP100", "LAC100", "ICA50", "ICA100"}
    assert (PKG / "building" / "buildings" / "five_story.toml").is_file()
    assert (PKG / "shake_table" / "data" / "shake_table_bncs" / "LICENSE").is_file()
