"""Kernels that call a law are written once, as templates, and instantiated per law.

A *template* is an ordinary module of the package whose ``@njit(cache=True)`` functions call a
law through free module-level names, its *slots* (listed in the template's ``SLOTS`` tuple and
bound there to :func:`unbound` placeholders so the module imports, lints and documents as
usual), for example::

    SLOTS = ("law_step",)
    law_step = unbound("law_step")

    @njit(cache=True)
    def drive(p, sc, st, disp, ...):
        ...
        f, kt, status = law_step(p, sc, u, v, dt, st)

:func:`instantiate` writes the template's source, followed by one import per slot binding it to
a law's jitted function, to a generated file and imports that file as a module.  Numba resolves
a global when it compiles, so every function of the instance calls (and inlines) that law's
kernel directly: no branch over law ids, nothing to edit elsewhere when a law is added, and only
the laws a command uses are ever compiled.

Never stale
-----------
The generated file is named by a hash of its whole text, which contains the template's source
and a hash of the source file of every bound function.  An edit to the template or to a law
module therefore gives a new file and a fresh Numba cache entry; an unchanged pair reuses the
cached machine code across processes.  The files live in ``<kernel cache>/generated/``
(:func:`generated_dir`, in the private per-user folder of :mod:`rrfrei._jit_cache`), which is
itself keyed on every kernel source of the packages.

Verified before it runs
-----------------------
A file already at the expected name is read once and executed only if the SHA-256 of those bytes
matches the hash in its name; otherwise it is refused (a ``RuntimeWarning`` names it) and
rewritten.  The module runs from the verified bytes, never from a second read or a ``.pyc``.
:func:`kernel_files` (``rrfrei kernels LAW``) lists a law's generated files to read.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.machinery
import inspect
import math
import os
import re
import sys
import tempfile
import threading
import warnings
from collections.abc import Mapping
from pathlib import Path
from types import ModuleType

__all__ = [
    "bindings", "generated_dir", "history", "history_bindings", "instantiate", "kernel_files",
    "unbound",
]

_LOCK = threading.RLock()  # re-entrant: an instance may instantiate while it imports
_INSTANCES: dict[tuple, ModuleType] = {}
_FILES: dict[str, dict[Path, str]] = {}  # key -> instance file -> template (this process)
_PKG = "rrfrei._generated"


def unbound(slot: str):
    """Placeholder for a template slot: calling it (outside an instance) raises RuntimeError."""

    def _unbound(*args, **kwargs):
        raise RuntimeError(
            f"template slot {slot!r} is not bound: call the kernel through "
            "rrfrei.laws.specialise.instantiate(template, bindings), not from the template module"
        )

    _unbound.__name__ = f"unbound_{slot}"
    return _unbound


def generated_dir() -> Path:
    """Folder of the generated instance files, created on first call (private, per user)."""
    from rrfrei import _jit_cache

    path = _jit_cache.ensure_cache_dir() / "generated"
    path.mkdir(exist_ok=True)
    return path


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _load_verified(path: Path, text: str, digest: str) -> bytes:
    """The bytes of the instance file at ``path``: written atomically when missing, and when an
    existing file's content does not hash to ``digest`` (refused with a warning, rewritten)."""
    data = text.encode("utf-8")
    try:
        found = path.read_bytes()
    except FileNotFoundError:
        found = None
    if found is not None:
        if found == data:  # hence also hashes to ``digest``
            return found
        warnings.warn(
            f"refused the generated kernel file {path}: its content does not match the hash "
            f"{digest} in its name (changed after it was written); writing it again",
            RuntimeWarning, stacklevel=3,
        )
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)  # atomic: concurrent writers write the same bytes
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return data


def _exec_instance(modname: str, path: Path, data: bytes) -> ModuleType:
    """Run the verified bytes ``data`` as the module ``modname`` whose file is ``path``."""
    module = ModuleType(modname)
    module.__file__ = str(path)
    module.__spec__ = importlib.machinery.ModuleSpec(modname, None, origin=str(path))
    code = compile(data, str(path), "exec", dont_inherit=True)
    sys.modules[modname] = module
    try:
        exec(code, module.__dict__)
    except BaseException:
        sys.modules.pop(modname, None)
        raise
    return module


def _file_hash(path: str) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def _import_line(slot: str, fn) -> tuple[str, str]:
    """``from <module> import <name> as <slot>`` for a top-level function, and its file hash."""
    py = getattr(fn, "py_func", fn)
    module = getattr(py, "__module__", None)
    name = getattr(py, "__name__", None)
    mod = sys.modules.get(module) if module else None
    if mod is None or getattr(mod, name, None) is not fn or "<" in getattr(py, "__qualname__", "<"):
        raise ValueError(
            f"slot {slot!r}: {fn!r} must be a module-level function (importable as "
            f"<module>.<name>) so that the instance can import it"
        )
    src = inspect.getsourcefile(mod)
    if src is None:
        raise ValueError(f"slot {slot!r}: the module {module!r} of {name!r} has no source file")
    return f"from {module} import {name} as {slot}  # noqa: E402,F401", _file_hash(src)


def _const_line(slot: str, value) -> str:
    """``<slot> = <value>`` for a constant binding (bool, int or float)."""
    if isinstance(value, bool) or isinstance(value, (int, float)) and math.isfinite(value):
        return f"{slot} = {value!r}  # noqa: E402"
    raise ValueError(f"slot {slot!r}: constant {value!r} must be a bool, an int or a finite float")


def _is_const(value) -> bool:
    return isinstance(value, (bool, int, float))


def instantiate(template: str, bindings: Mapping[str, object], key: str) -> ModuleType:
    """The module ``template`` with its slots bound to ``bindings``.

    Parameters
    ----------
    template : dotted name of the template module (it must define ``SLOTS``).
    bindings : slot name -> jitted (or plain) module-level function, or a constant (bool, int,
        float: Numba freezes a global, so e.g. an offset into the parameter vector costs
        nothing); every slot must be bound.
    key : a readable tag for the file name (e.g. the law name); the identity of an instance is
        the hash of its text, not the key.

    Returns
    -------
    The instance module (cached per process; the compiled code is cached on disk by Numba).
    """
    tmpl = importlib.import_module(template)
    slots = tuple(getattr(tmpl, "SLOTS", ()))
    missing = [s for s in slots if s not in bindings]
    extra = [s for s in bindings if s not in slots]
    if missing or extra:
        raise ValueError(
            f"template {template!r} has slots {slots}; missing bindings {missing}, unknown {extra}"
        )
    ident = (template, tuple(
        (s, (type(bindings[s]).__name__, bindings[s]) if _is_const(bindings[s]) else id(bindings[s]))
        for s in slots
    ))
    with _LOCK:
        hit = _INSTANCES.get(ident)
        if hit is not None:
            return hit
        src_path = inspect.getsourcefile(tmpl)
        source = Path(src_path).read_text(encoding="utf-8")
        lines = []
        hashes = []
        for s in slots:
            if _is_const(bindings[s]):
                lines.append(_const_line(s, bindings[s]))
                continue
            line, h = _import_line(s, bindings[s])
            lines.append(line)
            hashes.append(f"# {s}: source sha256 {h}")
        text = (
            f"# Generated by rrfrei.laws.specialise from {template} for {key!r}; do not edit.\n"
            + "\n".join(hashes)
            + "\n"
            + source
            + "\n\n# ---- slot bindings (rrfrei.laws.specialise) ----\n"
            + "\n".join(lines)
            + "\n"
        )
        digest = _digest(text.encode("utf-8"))
        tag = _tag(template, key)
        modname = f"{_PKG}.{tag}_{digest}"
        path = generated_dir() / f"{tag}_{digest}.py"
        module = _exec_instance(modname, path, _load_verified(path, text, digest))
        _FILES.setdefault(key, {})[path] = template
        _INSTANCES[ident] = module
        return module


def bindings(spec) -> dict[str, object]:
    """Slot bindings of a law for templates that call it: ``law_step`` and ``law_step_robust``.

    Both are ``(p, sc, u, v, dt, st) -> (force, tangent, status)`` (contract in
    :mod:`rrfrei.laws.registry`), read from the law's registry entry: ``LawSpec.step`` and
    ``LawSpec.step_robust`` (the law's robust local solve where it has one, which may return a
    positive status where it deviated from OpenSees; else its step).  An augmented law's step is
    itself an instance (:mod:`rrfrei.laws.effects`), so every law binds the same way.
    """
    return {"law_step": spec.step, "law_step_robust": spec.step_robust or spec.step}


HISTORY = "rrfrei.laws._history"
"""The template of the whole-history loop (:mod:`rrfrei.laws._history`)."""


def history_bindings(spec, robust: bool = False, fast: bool = True) -> dict[str, object]:
    """Slot bindings of the history loop for a law: ``law_step`` the law's step (with ``robust``
    its robust local solve, ``LawSpec.step_robust``, where it has one), ``law_run`` /
    ``law_run_setup`` its fast history solver (``LawSpec.fast_run`` / ``.fast_setup``) where it
    has one and ``fast``, else the no-op :func:`rrfrei.laws._util.no_run`."""
    from rrfrei.laws import _util

    step = spec.step_robust if robust and spec.step_robust is not None else spec.step
    if fast and spec.fast_run is not None:
        return {"law_step": step, "law_run": spec.fast_run, "law_run_setup": spec.fast_setup}
    return {"law_step": step, "law_run": _util.no_run, "law_run_setup": _util.no_run_setup}


def history(spec, robust: bool = False, fast: bool = True):
    """The law's whole-history driver (jitted).

    ``drive(p, sc, st, disp, time, use_time, substeps, force, tangent) -> (status, index)``, or
    with ``robust`` ``drive_robust(..., deviated)`` (contracts in :mod:`rrfrei.laws._history`):
    the instance of :data:`HISTORY`, the one time loop, bound to the law's local solver and its
    fast history solver (:func:`history_bindings`; ``fast=False`` leaves the fast solver out:
    the reference it is tested against).  The step is inlined in the loop (about twice as fast
    as a call per step through a dispatch).
    """
    hit = _DRIVERS.get((id(spec), robust, fast))
    if hit is not None and hit[0] is spec:
        return hit[1]
    module = instantiate(HISTORY, history_bindings(spec, robust, fast), spec.name)
    own = module.drive_robust if robust else module.drive
    _DRIVERS[(id(spec), robust, fast)] = (spec, own)  # the spec is kept alive: its id stays its own
    return own


_DRIVERS: dict[tuple[int, bool, bool], tuple[object, object]] = {}


_HEADER = re.compile(r"^# Generated by rrfrei\.laws\.specialise from (?P<template>[\w.]+) for ")
_NAME = re.compile(r"^(?P<tag>.+)_(?P<digest>[0-9a-f]{16})\.py$")


def _key_tag(key: str) -> str:
    return re.sub(r"[^0-9A-Za-z_]", "_", key)


def _tag(template: str, key: str) -> str:
    """The file-name stem of an instance, before its hash."""
    return _key_tag(f"{template.replace('.', '_')}__{key}")


def kernel_files(law, generate: bool = True) -> list[tuple[str, Path]]:
    """The generated kernel files of a law: ``(template, path)`` pairs, sorted by template.

    Parameters
    ----------
    law : a law name (``"plasticity"``, ``"bouc_wen+rate"``, ...) or its ``LawSpec``.
    generate : first instantiate the law's whole-history drivers (:func:`history`), which every
        command that simulates the law runs, so that they are listed even before any run.

    Returns
    -------
    Every instance of a template bound to the law in the current kernel cache (the history
    drivers, the batched likelihood of ``rrfrei calibrate``, the building kernels of the time
    histories, the plan forms ``plan_<law>``, where they were generated), each verified against
    the hash in its name; a file that fails the check is not listed (it is refused and rewritten
    when it is next needed).  Open a path to read the exact kernel a command runs.
    """
    from rrfrei.laws import registry

    spec = registry.get(law)
    if generate:
        history(spec)
        history(spec, robust=True)
    keys = (spec.name, f"plan_{spec.name}")
    found: dict[Path, str] = {}
    with _LOCK:
        for key in keys:
            for path, template in _FILES.get(key, {}).items():
                found[path] = template
    for path in generated_dir().glob("*.py"):
        m = _NAME.match(path.name)
        if m is None or path in found or not any(m["tag"].endswith(f"__{_key_tag(k)}") for k in keys):
            continue
        data = path.read_bytes()
        head = _HEADER.match(data.decode("utf-8", "replace"))
        if _digest(data) != m["digest"] or head is None:
            continue  # not a verified instance: never listed as a kernel to read
        template = head["template"]
        if m["tag"] in {_tag(template, k) for k in keys}:
            found[path] = template
    return sorted(((t, p) for p, t in found.items()), key=lambda tp: (tp[0], tp[1].name))
