"""One Numba cache per version of the kernel sources, so compiled code is never stale.

Numba keys a cached function on the source file *of that function* only.  A cached caller in
another file (the per-law instances of ``laws/_history.py``, ``calibration/_batch.py`` and
``structures/newmark.py``, every law through the ``inline="always"`` helpers of
``laws/_util.py``) would otherwise keep the old machine code after a law file changes, and
return the old law's forces.  (The instances' own file names also hash the bound law sources,
:mod:`rrfrei.laws.specialise`, which covers laws outside these packages.)

This module is imported by every package of the project (``rrfrei``, ``structures``,
``rubber``, ``ground_motions``) before any ``@njit(cache=True)`` is decorated.  It hashes every
source file of those packages that uses Numba and points ``numba.config.CACHE_DIR`` at a
folder named after that hash, so any edit to any kernel source gives every compiled function a
fresh cache (a full recompile, once).  Older cache folders of the same checkout are removed once
they have not changed for two hours (:func:`_prune`).

Where the cache lives
---------------------
- ``NUMBA_CACHE_DIR`` set by the user: respected as it is (the user then owns staleness).
- otherwise ``<repository>/.numba_cache/<hash>/`` next to the packages when that folder is
  writable (an editable install or a checkout), else ``$XDG_CACHE_HOME/rrfrei/numba/<hash>/``
  (``~/.cache`` when unset) for a read-only install.

The chosen folder is exported as ``NUMBA_CACHE_DIR`` so worker processes (multiprocessing,
Dask) use the same one; :data:`CACHE_DIR` holds it and :data:`SOURCE_HASH` the hash.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

PACKAGES = ("rrfrei", "structures", "rubber", "ground_motions")
_MARKER = b"numba"


def kernel_sources(root: Path) -> list[Path]:
    """Source files of the project's packages under ``root`` that use Numba, sorted."""
    files = []
    for pkg in PACKAGES:
        base = root / pkg
        if base.is_dir():
            files.extend(p for p in base.rglob("*.py") if _MARKER in p.read_bytes())
    return sorted(files)


def source_hash(root: Path) -> str:
    """SHA-256 (first 16 hex digits) over the relative paths and bytes of the kernel sources."""
    import numba

    h = hashlib.sha256(numba.__version__.encode())
    for path in kernel_sources(root):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return False


PRUNE_AFTER = 2 * 3600.0
"""Age [s] (since its last change) after which the cache folder of other sources is removed."""


def _prune(base: Path, keep: str, older_than: float = PRUNE_AFTER) -> None:
    """Remove cache folders of earlier source versions (best effort; never raises).

    Only folders unchanged for ``older_than`` seconds go: a process started before a kernel
    source was edited still runs on its own folder, and may compile a law into it later (the
    instances of :mod:`rrfrei.laws.specialise` are written on first use); removing that folder
    under it failed its next instance with ``FileNotFoundError``.  Staleness does not depend on
    the removal: a new source version always has a new folder."""
    import time

    now = time.time()
    try:
        for child in base.iterdir():
            if child.is_dir() and child.name.startswith("k-") and child.name != keep:
                try:
                    if now - child.stat().st_mtime < older_than:
                        continue
                except OSError:
                    continue
                shutil.rmtree(child, ignore_errors=True)
    except OSError:
        pass


def configure() -> str | None:
    """Point Numba's cache at the folder of the current kernel sources; return it.

    Returns None (and changes nothing) when the user set ``NUMBA_CACHE_DIR``.
    """
    if os.environ.get("NUMBA_CACHE_DIR") and not os.environ.get("_RRFREI_NUMBA_CACHE"):
        return None
    root = Path(__file__).resolve().parent.parent
    digest = source_hash(root)
    name = f"k-{digest}"
    candidates = [root / ".numba_cache"]
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    candidates.append(Path(xdg) / "rrfrei" / "numba")
    for base in candidates:
        target = base / name
        if _writable(target):
            _prune(base, name)
            break
    else:  # nowhere writable: Numba then compiles in memory each run (its own fallback)
        return None
    from numba.core import config

    path = str(target)
    os.environ["NUMBA_CACHE_DIR"] = path
    os.environ["_RRFREI_NUMBA_CACHE"] = digest  # set by us, not by the user: children re-derive
    config.CACHE_DIR = path
    return path


SOURCE_HASH: str | None = None
CACHE_DIR: str | None = configure()
if CACHE_DIR is not None:
    SOURCE_HASH = Path(CACHE_DIR).name.removeprefix("k-")
