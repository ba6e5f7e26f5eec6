"""Where the project's compiled kernels are cached, so compiled code is never stale.

Numba keys a cached function on the source file *of that function* only.  A cached caller in
another file (the per-law instances of ``laws/_history.py``, ``calibration/_batch.py`` and
``structures/dynamics/newmark.py``, every law through the ``inline="always"`` helpers of
``laws/_util.py``) would otherwise keep the old machine code after a law file changes, and
return the old law's forces.  (The instances' own file names also hash the bound law sources,
:mod:`rrfrei.laws.specialise`, which covers laws outside these packages.)

So the cache of every ``@njit(cache=True)`` function of the project's packages (``rrfrei``,
``structures``, ``rubber``, ``ground_motions``) and of the generated instances lives in a folder
named after a hash of every source file of those packages that uses Numba
(:func:`source_hash`): any edit to any kernel source gives every compiled function a fresh cache
(a full recompile, once).  Older folders are removed once they have not changed for two hours
(:func:`_prune`).

Where the cache lives
---------------------
``<user cache>/numba/k-<hash>/`` (:func:`cache_dir`), where ``<user cache>`` is the platform's
per-user cache folder for rrfrei (``platformdirs.user_cache_dir("rrfrei")``; on Linux
``$XDG_CACHE_HOME/rrfrei``, ``~/.cache/rrfrei`` when unset, by the same rule without importing
platformdirs), or ``$NUMBA_CACHE_DIR/rrfrei`` when
the user set Numba's cache folder.  That ``rrfrei`` folder is created private (mode 0700) at the
first save; a folder owned by another user is refused.  Never inside the installed package nor
at a fixed path in a shared temporary folder: when the user cache cannot be created, the kernels
are cached for this process only, in a fresh private temporary folder.

How Numba finds it
------------------
Importing this module registers :class:`Locator` with Numba (once): a cache locator that claims
only the source files of the project's packages and of the generated instances, so other
libraries' caches and the process environment are untouched.  Nothing is read or written at
import: the hash is computed when the first kernel is decorated (reads only) and the folder is
created at the first save of compiled code.  Worker processes (multiprocessing, Dask,
pytest-xdist) import the packages too, derive the same hash from the same sources and so share
the folder; no environment variable carries it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tempfile
import threading
from pathlib import Path

from numba.core import caching

PACKAGES = ("rrfrei", "structures", "rubber", "ground_motions")
ROOT = Path(__file__).resolve().parent.parent
"""The folder holding the project's packages (a checkout, or site-packages)."""
APP_NAME = "rrfrei"
_MARKER = b"numba"
_LOCK = threading.RLock()
_STATE: dict[str, Path] = {}


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


def _usable(folder: Path) -> bool:
    """True when ``folder`` exists as a writable folder or could be created (nothing written)."""
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            return False
        probe = probe.parent
    return probe.is_dir() and os.access(probe, os.W_OK | os.X_OK)


def private_root() -> Path:
    """The per-user folder of rrfrei's cache (not created here; see the module docstring)."""
    from numba.core import config

    if config.CACHE_DIR:
        return Path(config.CACHE_DIR) / APP_NAME
    if sys.platform.startswith("linux"):  # the XDG rule, as platformdirs applies it (without its
        xdg = os.environ.get("XDG_CACHE_HOME", "").strip()  # ~0.1 s import after Numba's)
        return Path(xdg or Path.home() / ".cache") / APP_NAME
    import platformdirs

    return Path(platformdirs.user_cache_dir(APP_NAME, appauthor=False))


def cache_dir() -> Path:
    """Numba cache folder of the current kernel sources: ``<private root>/numba/k-<hash>``.

    Computed once per process (the hash reads the kernel sources); nothing is written."""
    with _LOCK:
        hit = _STATE.get("dir")
        if hit is not None:
            return hit
        root = private_root()
        if not _usable(root):
            # per process, private and unpredictable (created by ensure_cache_dir)
            root = Path(tempfile.gettempdir()) / f"{APP_NAME}-{os.getpid()}-{os.urandom(8).hex()}"
            _STATE["fallback"] = root
        _STATE["root"] = root
        _STATE["dir"] = root / "numba" / f"k-{source_hash(ROOT)}"
        return _STATE["dir"]


def _make_private(folder: Path) -> None:
    """Create ``folder`` with mode 0700, or check an existing one is ours and private."""
    try:
        folder.mkdir(mode=0o700, parents=True)
        return
    except FileExistsError:
        pass
    if not folder.is_dir():
        raise PermissionError(f"rrfrei's kernel cache {folder} is not a plain folder")
    if hasattr(os, "getuid"):
        st = folder.stat()
        if st.st_uid != os.getuid():
            raise PermissionError(
                f"rrfrei's kernel cache {folder} belongs to user id {st.st_uid}, not to you "
                f"({os.getuid()}); remove it or set XDG_CACHE_HOME (or NUMBA_CACHE_DIR) to a folder "
                "of your own"
            )
        if st.st_mode & 0o077:
            os.chmod(folder, 0o700)


def ensure_cache_dir() -> Path:
    """:func:`cache_dir`, created (its rrfrei folder private) and older versions pruned, once."""
    with _LOCK:
        path = cache_dir()
        if _STATE.get("ready") is not None:
            return path
        root = _STATE["root"]
        _make_private(root)
        if "fallback" in _STATE:
            import atexit
            import warnings

            atexit.register(shutil.rmtree, root, True)
            warnings.warn(f"rrfrei: the per-user cache folder {private_root()} cannot be created; "
                          f"compiled kernels are cached in {root} for this process only (set "
                          "XDG_CACHE_HOME or NUMBA_CACHE_DIR to a writable folder)", RuntimeWarning,
                          stacklevel=2)
        path.mkdir(parents=True, exist_ok=True)
        _prune(path.parent, path.name)
        _STATE["ready"] = path
        return path


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


def _is_ours(py_file: str) -> bool:
    """True for a source file of the project's packages or a generated instance."""
    path = os.path.abspath(py_file)
    for pkg in PACKAGES:
        if path.startswith(os.path.join(str(ROOT), pkg) + os.sep):
            return True
    return path.startswith(str(cache_dir()) + os.sep)


class Locator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """Numba cache locator of the project's kernels: ``<cache_dir()>/<folder>_<sha1 of path>``.

    Claims only :func:`_is_ours` files; writes nothing until Numba saves compiled code (then
    :func:`ensure_cache_dir`).  The per-file source stamp is Numba's own (a hash of the file)."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = str(cache_dir() / self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self) -> str:
        return self._cache_path

    def ensure_cache_path(self) -> None:
        ensure_cache_dir()
        os.makedirs(self._cache_path, exist_ok=True)

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _is_ours(py_file) or not os.path.exists(py_file):
            return None
        return cls(py_func, py_file)


def _install() -> None:
    """Put :class:`Locator` first in Numba's locator list (idempotent; a module reload safe)."""
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    classes = impl._locator_classes
    classes[:] = [c for c in classes if getattr(c, "__qualname__", "") != "Locator"
                  or c.__module__ != __name__]
    classes.insert(0, Locator)


_install()


def __getattr__(name: str):
    if name == "CACHE_DIR":  # the folder in use, as a string (computed on first use)
        return str(cache_dir())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

