"""Finished fits of the gap engine saved and reused (the ``checkpoint`` folder of
:func:`rrfrei.gap.diagnose`): every fit keyed by a SHA-256 of the test data, the model
settings, the seed and the step, written atomically as ``.npz``."""

from __future__ import annotations

import hashlib
import inspect
import os
from pathlib import Path

import numpy as np

from rrfrei.budget import TimeBudget
from rrfrei.gap.model import FitResult, GapModel

__all__ = ["Checkpoint"]


class Checkpoint:
    """Finished fits saved as ``.npz`` in a folder, keyed by data, model settings, seed and step."""

    def __init__(self, folder, model: GapModel, data, seed: int) -> None:
        self.model, self.seed = model, seed
        self.key = model.checkpoint_key(data) if folder is not None else None
        self.folder = Path(folder) if self.key is not None else None
        self.reused: list[str] = []
        self.error = ""

    def _path(self, step: str) -> Path:
        h = hashlib.sha256(f"{self.key}|seed={self.seed}|{step}".encode()).hexdigest()[:16]
        safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in step)
        return self.folder / f"{safe}-{h}.npz"

    def get(self, step: str, model: GapModel | None = None) -> FitResult | None:
        """The fit saved for ``step``, restored by ``model`` (the model that made it: an effect's
        refit has the augmented model's parameters; default the checkpoint's own model)."""
        if self.folder is None:
            return None
        path = self._path(step)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                fit = (model or self.model).restore({k: z[k] for k in z.files})
        except (OSError, ValueError, KeyError, TypeError, NotImplementedError):
            return None  # unreadable or from another version: fit again and overwrite
        self.reused.append(step)
        return fit

    def put(self, step: str, model: GapModel, fit: FitResult) -> None:
        if self.folder is None:
            return
        state = model.fit_state(fit)
        if state is None:
            return
        path = self._path(step)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.stem + ".part.npz")
            np.savez(tmp, **state)
            os.replace(tmp, path)  # atomic: an interrupted run never leaves a half-written fit
        except OSError as exc:
            self.error = f"checkpoint not written ({type(exc).__name__}: {exc})"


_Checkpoint = Checkpoint  # the name the engine used before it was public


def effect_step(effect: str) -> str:
    """The checkpoint step of an effect's primary refit from the baseline."""
    return f"effect-{effect}"


def _fit(model: GapModel, data, budget: TimeBudget, **kw) -> FitResult:
    """``model.fit``, passing the budget to models whose optimiser can check it."""
    budget.check()
    if "budget" in inspect.signature(model.fit).parameters:
        return model.fit(data, budget=budget, **kw)
    return model.fit(data, **kw)


def _fit_or_restore(ck: _Checkpoint, step: str, model: GapModel, data, budget: TimeBudget,
                    **kw) -> FitResult:
    fit = ck.get(step, model)
    if fit is None:
        fit = _fit(model, data, budget, **kw)
        ck.put(step, model, fit)
    return fit
