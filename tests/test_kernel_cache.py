"""Kernel generation is explicit and safe (issue 28.5).

Importing a package only defines things: no file is written and no environment variable changes.
The compiled kernels and the generated kernel sources live in a private per-user folder, never in
the installed package; a generated file runs only if its content matches the hash in its name;
two processes compiling into an empty cache at once both get the right numbers; and
``rrfrei kernels LAW`` lists the generated files of a law so that a reader can open them.

The subprocess cases run a copy of the packages with their own ``XDG_CACHE_HOME`` (the per-user
cache folder on Linux) so that they start cold and leave the user's cache alone.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrfrei import _jit_cache
from rrfrei.app.cli import main

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rrfrei", "structures", "rubber", "ground_motions")

U = np.linspace(0.0, 0.03, 60) * np.sin(np.linspace(0.0, 9.0, 60))
PLASTICITY = dict(k_init=1000.0, qd=2.0, alpha1=0.1, alpha2=0.0, mu=2.0)

SIMULATE = r"""
import json, sys, numpy as np
import rrfrei
from rrfrei import _jit_cache
u = np.linspace(0.0, 0.03, 60) * np.sin(np.linspace(0.0, 9.0, 60))
f = rrfrei.simulate_force("plasticity", dict(k_init=1000.0, qd=2.0, alpha1=0.1, alpha2=0.0, mu=2.0), u)
print(json.dumps({"force": f.tolist(), "cache": _jit_cache.CACHE_DIR}))
"""


def _env(tmp: Path, tree: Path | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "_RRFREI_NUMBA_CACHE")}
    env["XDG_CACHE_HOME"] = str(tmp / "xdg")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
    return env


def _files(folder: Path) -> dict[str, tuple[int, int]]:
    """Size and mtime of every file under ``folder`` except bytecode (which Python itself, and
    another pytest worker, may write there)."""
    return {p.relative_to(folder).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


@pytest.fixture
def read_only_tree(tmp_path):
    """A copy of the packages whose folders are not writable (an installed, read-only package)."""
    tree = tmp_path / "site"
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tree / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for path in sorted(tree.rglob("*"), reverse=True) + [tree]:
        mode = path.stat().st_mode
        path.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    yield tree
    for path in [tree, *tree.rglob("*")]:
        if path.is_dir():
            path.chmod(path.stat().st_mode | stat.S_IWUSR)


def test_importing_the_packages_writes_nothing_and_changes_no_environment_variable(tmp_path):
    code = (
        "import json, os, sys; before = dict(os.environ); "
        "import numba.core.config as config; numba_dir = config.CACHE_DIR; "
        "import rrfrei, ground_motions, structures, rubber, rrfrei.app.cli, rrfrei.laws; "
        "print(json.dumps({'changed': sorted(k for k in set(before) | set(os.environ) "
        "if before.get(k) != os.environ.get(k)), 'numba_dir': [numba_dir, config.CACHE_DIR]}))"
    )
    before = _files(ROOT / "rrfrei") | {"root": tuple(sorted(p.name for p in ROOT.iterdir()))}
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    out = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path, ROOT), cwd=cwd,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["changed"] == [], "importing changed environment variables"
    assert report["numba_dir"][0] == report["numba_dir"][1], "importing changed Numba's cache folder"
    assert not (tmp_path / "xdg").exists(), "importing created the kernel cache"
    assert list(cwd.iterdir()) == []
    after = _files(ROOT / "rrfrei") | {"root": tuple(sorted(p.name for p in ROOT.iterdir()))}
    assert after == before, "importing wrote into the package"


def test_a_read_only_install_caches_its_kernels_in_a_private_per_user_folder(tmp_path, read_only_tree):
    before = _files(read_only_tree)
    out = subprocess.run([sys.executable, "-c", SIMULATE], env=_env(tmp_path, read_only_tree),
                         cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    from rrfrei import simulate_force

    np.testing.assert_array_equal(got["force"], simulate_force("plasticity", PLASTICITY, U))
    assert _files(read_only_tree) == before, "the run wrote into the installed package"
    private = tmp_path / "xdg" / "rrfrei"
    assert Path(got["cache"]).is_relative_to(private)
    assert stat.S_IMODE(private.stat().st_mode) == 0o700
    cache = Path(got["cache"])
    assert list(cache.glob("*/*.nbi")), "nothing compiled was cached"
    assert list((cache / "generated").glob("*.py")), "no generated kernel source"


def test_two_processes_compiling_cold_at_once_both_get_the_right_numbers(tmp_path):
    env = _env(tmp_path, ROOT)
    runs = [subprocess.Popen([sys.executable, "-c", SIMULATE], env=env, cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(2)]
    results = []
    for proc in runs:
        stdout, stderr = proc.communicate(timeout=900)
        assert proc.returncode == 0, stderr[-3000:]
        results.append(json.loads(stdout.strip().splitlines()[-1]))
    warm = subprocess.run([sys.executable, "-c", SIMULATE], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=900)
    assert warm.returncode == 0, warm.stderr[-3000:]
    results.append(json.loads(warm.stdout.strip().splitlines()[-1]))
    from rrfrei import simulate_force

    expected = simulate_force("plasticity", PLASTICITY, U)
    for got in results:
        np.testing.assert_array_equal(got["force"], expected)
        assert got["cache"] == results[0]["cache"], "the processes share one cache folder"
    cache = Path(results[0]["cache"])
    assert not [p for p in cache.rglob("*") if ".tmp" in p.name], "a half-written file was left"


PLANTED = "raise RuntimeError('planted code ran')\n"

INSTANTIATE = r"""
import json, warnings
import rrfrei.laws as laws
from rrfrei.laws import specialise
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    drive = specialise.history(laws.get("plasticity"))
print(json.dumps({"file": drive.py_func.__code__.co_filename,
                  "warnings": [str(w.message) for w in caught]}))
"""


def test_a_generated_file_whose_content_does_not_match_its_hash_is_refused(tmp_path):
    env = _env(tmp_path, ROOT)

    def run():
        out = subprocess.run([sys.executable, "-c", INSTANTIATE], env=env, cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-3000:]
        return json.loads(out.stdout.strip().splitlines()[-1])

    first = run()
    assert first["warnings"] == []
    path = Path(first["file"])
    assert "_history__plasticity_" in path.name
    good = path.read_bytes()
    path.write_text(PLANTED)

    second = run()
    assert any("refused" in w and str(path) in w for w in second["warnings"]), second["warnings"]
    assert path.read_bytes() == good, "the refused file is written again from its template"
    assert path.is_relative_to(tmp_path / "xdg" / "rrfrei"), "generated files live in the user cache"


def test_rrfrei_kernels_lists_the_verified_generated_files_of_a_law(capsys):
    assert main(["kernels", "plasticity", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    assert listing["law"] == "plasticity"
    templates = {f["template"] for f in listing["files"]}
    assert "rrfrei.laws._history" in templates
    for entry in listing["files"]:
        path = Path(entry["path"])
        digest = path.stem.rsplit("_", 1)[1]
        import hashlib

        assert hashlib.sha256(path.read_bytes()).hexdigest()[:16] == digest
        assert path.is_relative_to(_jit_cache.cache_dir())
    assert listing["law_source"].endswith("plasticity.py")

    assert main(["kernels", "plasticity"]) == 0
    text = capsys.readouterr().out
    assert "rrfrei.laws._history" in text and str(_jit_cache.cache_dir()) in text


def test_rrfrei_kernels_names_an_unknown_law(capsys):
    assert main(["kernels", "no_such_law"]) == 2
    assert "no_such_law" in capsys.readouterr().err


def _cache_dir_of_a_worker() -> str:
    from rrfrei import _jit_cache as jc

    return str(jc.cache_dir())


def test_a_spawned_worker_finds_the_same_cache_without_any_environment_variable():
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(1) as pool:
        theirs = pool.apply(_cache_dir_of_a_worker)
    assert theirs == str(_jit_cache.cache_dir())
    assert "NUMBA_CACHE_DIR" not in os.environ or os.environ["NUMBA_CACHE_DIR"] != theirs


def test_an_existing_cache_folder_is_made_private_and_one_of_another_user_is_refused(tmp_path,
                                                                                    monkeypatch):
    folder = tmp_path / "rrfrei"
    folder.mkdir(mode=0o777)
    folder.chmod(0o777)
    _jit_cache._make_private(folder)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700

    fresh = tmp_path / "a" / "b" / "rrfrei"
    _jit_cache._make_private(fresh)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o700

    if not hasattr(os, "getuid"):
        pytest.skip("no user ids on this platform")
    monkeypatch.setattr(os, "getuid", lambda: folder.stat().st_uid + 1)
    with pytest.raises(PermissionError, match="belongs to user id"):
        _jit_cache._make_private(folder)


def test_the_locator_claims_only_the_project_s_files():
    assert _jit_cache._is_ours(str(ROOT / "rrfrei" / "laws" / "plasticity.py"))
    assert _jit_cache._is_ours(str(_jit_cache.cache_dir() / "generated" / "x_0123456789abcdef.py"))
    assert not _jit_cache._is_ours(str(ROOT / "tests" / "_toy_law.py"))
    assert not _jit_cache._is_ours(np.__file__)


FALLBACK = r"""
import json, warnings
import rrfrei.laws as laws
from rrfrei import _jit_cache
from rrfrei.laws import specialise
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    drive = specialise.history(laws.get("linear"))
print(json.dumps({"file": drive.py_func.__code__.co_filename, "cache": _jit_cache.CACHE_DIR,
                  "warnings": [str(w.message) for w in caught]}))
"""


def test_without_a_usable_user_cache_the_kernels_are_cached_privately_for_the_process_only(tmp_path):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    env = _env(tmp_path, ROOT)
    env["XDG_CACHE_HOME"] = str(blocker / "xdg")  # under a file: cannot be created
    out = subprocess.run([sys.executable, "-c", FALLBACK], env=env, cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert any("for this process only" in w for w in got["warnings"]), got["warnings"]
    cache = Path(got["cache"])
    assert Path(got["file"]).is_relative_to(cache)
    assert not cache.is_relative_to(blocker) and not cache.exists(), "removed when the process ends"


@pytest.mark.parametrize("xdg", [None, "", "  ", "/some/where else"])
def test_the_cache_folder_is_the_platform_s_per_user_cache_folder(monkeypatch, xdg):
    import platformdirs
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", "")
    if xdg is None:
        monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    else:
        monkeypatch.setenv("XDG_CACHE_HOME", xdg)
    assert _jit_cache.private_root() == Path(platformdirs.user_cache_dir("rrfrei", appauthor=False))
    monkeypatch.setattr(config, "CACHE_DIR", "/numba/cache")
    assert _jit_cache.private_root() == Path("/numba/cache/rrfrei")
