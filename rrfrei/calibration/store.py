"""Where a chain is kept: emcee's HDF5 layout written in blocks (:class:`_Store`), and the
checkpoint file's own group ``rrfrei`` holding the optimum, so a resumed run does not search again
(step 3 of :mod:`rrfrei.calibration.sampler`)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import emcee
import numpy as np

from rrfrei.calibration.convergence import CHECK

__all__ = ["FLUSH_SECONDS", "check_checkpoint", "load_optimum", "save_optimum"]

FLUSH_SECONDS = 10.0
"""Longest wall time between two checkpoint writes [s]."""


class _Store:
    """The chain in memory, appended to emcee's HDF5 layout (``mcmc`` group) in blocks.

    emcee's own ``HDFBackend`` opens the file after every step; writing every :data:`CHECK` steps
    or :data:`FLUSH_SECONDS` (whichever first) keeps a kill's loss small at a fraction of the
    cost.  Files stay readable by ``emcee.backends.HDFBackend``.
    """

    def __init__(self, path: str | Path | None, nw: int, ndim: int) -> None:
        import time

        self.path = None if path is None else str(path)
        self.chain = np.empty((0, nw, ndim))
        self.logp = np.empty((0, nw))
        self.accepted = np.zeros(nw)
        self.written = 0
        self.restart = 0  # the step at which stuck walkers were last restarted (0: never)
        self.last = time.perf_counter()
        if self.path is not None:
            backend = emcee.backends.HDFBackend(self.path)
            n = _stored_iterations(backend) if Path(self.path).exists() else 0
            if n > 0:
                if backend.shape != (nw, ndim):
                    raise ValueError(
                        f"checkpoint {self.path} holds {backend.shape[0]} walkers x {backend.shape[1]} "
                        f"parameters, this run needs {nw} x {ndim}; use another path"
                    )
                self.chain = backend.get_chain()
                self.logp = backend.get_log_prob()
                self.accepted = np.asarray(backend.accepted, dtype=float)
                self.written = n
                self.restart = min(_stored_restart(self.path), n)
            else:
                backend.reset(nw, ndim)

    @property
    def n(self) -> int:
        return self.chain.shape[0]

    def append(self, coords: np.ndarray, logp: np.ndarray, accepted: np.ndarray) -> None:
        self.chain = np.concatenate([self.chain, coords])
        self.logp = np.concatenate([self.logp, logp])
        self.accepted = self.accepted + accepted

    def flush(self, force: bool = False) -> None:
        import time

        if self.path is None or self.written == self.n:
            return
        if not force and time.perf_counter() - self.last < FLUSH_SECONDS and self.n - self.written < CHECK:
            return
        import h5py

        with h5py.File(self.path, "a") as f:
            g = f["mcmc"]
            g["chain"].resize(self.n, axis=0)
            g["log_prob"].resize(self.n, axis=0)
            g["chain"][self.written:] = self.chain[self.written:]
            g["log_prob"][self.written:] = self.logp[self.written:]
            g["accepted"][:] = self.accepted
            g.attrs["iteration"] = self.n
            g.attrs[RESTART_ATTR] = self.restart
        self.written = self.n
        self.last = time.perf_counter()


RESTART_ATTR = "rrfrei_restart"
"""Attribute of the ``mcmc`` group: the step of the last walker restart (ignored by emcee)."""


def _stored_restart(path: str) -> int:
    import h5py

    with h5py.File(path, "r") as f:
        return int(f["mcmc"].attrs.get(RESTART_ATTR, 0))


def _stored_iterations(backend: emcee.backends.HDFBackend) -> int:
    try:
        return int(backend.iteration)
    except (AttributeError, KeyError, OSError):  # no mcmc group (e.g. created by find_map only)
        return 0


def check_checkpoint(checkpoint: str | Path) -> None:
    """A ValueError naming the file when ``checkpoint`` exists but is not an HDF5 file (or is a
    folder): h5py's own error is a traceback through its C layer."""
    import h5py

    p = Path(checkpoint)
    if p.is_dir():
        raise ValueError(f"checkpoint {p} is a folder; expected an HDF5 file path (e.g. {p / 'chain.h5'})")
    if p.exists() and not h5py.is_hdf5(str(p)):
        raise ValueError(f"checkpoint {p} exists and is not an HDF5 file: give another path (the "
                         "chain is stored there) or remove the file")


def save_optimum(checkpoint: str | Path, meta: dict) -> None:
    import h5py

    with h5py.File(checkpoint, "a") as f:
        g = f.require_group("rrfrei")
        g.attrs["optimum"] = json.dumps(meta)


def load_optimum(checkpoint: str | Path) -> dict | None:
    import h5py

    if not os.path.exists(checkpoint):
        return None
    try:
        with h5py.File(checkpoint, "r") as f:
            if "rrfrei" not in f:
                return None
            return json.loads(f["rrfrei"].attrs["optimum"])
    except (OSError, KeyError):
        return None
