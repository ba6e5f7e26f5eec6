"""The generic model interface of the gap engine.

The engine (:mod:`rrfrei.gap.diagnose`) needs only three verbs of a model, so any family of
models (isolator laws here; the rubber package's PRF chains later) can be diagnosed:

* ``model.fit(data, seed=..., start=...) -> FitResult`` (optimum then a short posterior);
* ``fit.predict(data) -> Prediction`` (posterior-mean force, predictive band, per-draw forces);
* ``fit.loglik(data) -> (draws, points)`` pointwise log-likelihood under the posterior draws;

plus ``model.observed(data)``, ``model.groups(data)`` (the exchangeable units left out together:
loading cycles) and ``model.augment(effects)``.

The isolator implementation is :mod:`rrfrei.gap.isolator` (:class:`IsolatorModel`,
:class:`IsolatorFit`); its names stay importable from here.

The *noise level* (for the systematic part of the gap) is the white part of the residuals,
``sigma_n = 1.4826 MAD(diff(r)) / sqrt(2)`` (von Neumann 1941 successive differences): a smooth
systematic misfit barely changes between samples while white noise does.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rrfrei.gap.catalogue import Scales
from rrfrei.io import ShearTest
from rrfrei.notes import Note

__all__ = ["GapModel", "FitResult", "Prediction", "gaussian_loglik", "white_noise", "test_scales",
           "IsolatorModel", "IsolatorFit", "simulate_retry"]  # noqa: F822  (the last three: rrfrei.gap.isolator)

LEVEL = 0.95
MIN_BAND_SAMPLES = 200
"""Fewest noisy replicates behind a predictive band (surviving draws are repeated up to it)."""


@dataclass(frozen=True)
class Prediction:
    """Posterior-mean prediction, predictive band (``LEVEL``) and the per-draw model outputs."""

    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    draws: np.ndarray  # (S, n) model outputs without noise
    sigma: np.ndarray  # (S,) noise sd of each draw


class FitResult(ABC):
    """A fitted model: name, parameters at the optimum, noise levels, predictions, scores."""

    name: str
    params: dict[str, float]
    sigma: float  # likelihood noise sd at the optimum (all residual)
    noise: float  # white-noise level of the residuals

    @abstractmethod
    def predict(self, data) -> Prediction: ...

    @abstractmethod
    def loglik(self, data) -> np.ndarray: ...

    def add_note(self, text: str, severity: str = "info") -> None:
        """Record ``text`` once (the diagnosis reports every fit's notes).

        It goes to ``notes`` (a list of :class:`rrfrei.notes.Note`, with ``severity``) where the
        fit keeps that list, and to the joined string ``note`` where the fit stores one (a fit
        whose ``note`` is a property derives it from ``notes``).
        """
        notes = getattr(self, "notes", None)
        joined = str(getattr(self, "note", "") or "")
        if text in joined or (isinstance(notes, list) and any(str(n) == text for n in notes)):
            return
        if isinstance(notes, list):
            notes.append(Note(text, severity))
        if not isinstance(getattr(type(self), "note", None), property):
            self.note = f"{joined}; {text}" if joined else text


class GapModel(ABC):
    """A family of models the gap engine can fit, augment and score."""

    name: str

    @abstractmethod
    def fit(self, data, *, seed: int = 0, start: FitResult | None = None) -> FitResult: ...

    @abstractmethod
    def augment(self, effects: Sequence[str]) -> GapModel: ...

    interacting_effects: bool = False
    """Whether one effect's evidence depends on another being in the model (a building fitted by
    output error: :class:`structures.shake_table.building_model.BuildingModel`); the diagnosis then
    tries at its combination steps every effect whose gains are consistent (the rule's rank tests
    pass) but alone too small, not only the significant ones (:func:`rrfrei.gap.diagnose.diagnose`,
    step 5)."""

    def variants(self, effect: str) -> tuple[str, ...]:
        """Further ways this model fits ``effect`` (:class:`rrfrei.laws.effects.Variant`); a model
        that has any takes ``augment(effects, variants={effect: name})``.  None by default."""
        return ()

    def shape_variant(self, effect: str, variant: str) -> bool:
        """Whether ``variant`` of ``effect`` only frees more of the kernel's shape (then the
        diagnosis tries it only where the primary fit finds a trace of the effect); false for a
        variant that changes what the model simulates.  True by default."""
        return True

    @abstractmethod
    def observed(self, data) -> np.ndarray: ...

    @abstractmethod
    def groups(self, data) -> np.ndarray: ...

    def cannot_judge(self, effect: str, data) -> str | None:
        """Why ``effect`` cannot be judged on ``data`` (None when it can)."""
        return None

    # optional: checkpointing of finished fits (the engine skips it when these return None)
    def checkpoint_key(self, data) -> str | None:
        """A string that identifies this model's settings and ``data`` (None: no checkpoints)."""
        return None

    def fit_state(self, fit: FitResult) -> dict[str, np.ndarray] | None:
        """``fit`` as arrays for an ``.npz`` checkpoint (None: cannot be saved)."""
        return None

    def restore(self, state: Mapping[str, np.ndarray]) -> FitResult:
        """The fit saved by :meth:`fit_state`."""
        raise NotImplementedError


# ---------------------------------------------------------------------------------------------
def gaussian_loglik(observed, pred: Prediction) -> np.ndarray:
    """Pointwise log-likelihood (S, n) of ``observed`` (n,) under each draw of ``pred``:
    ``N(observed | draws[s], sigma[s]^2)``."""
    r = np.asarray(observed, dtype=float)[None, :] - pred.draws
    s = pred.sigma[:, None]
    return -0.5 * (r / s) ** 2 - np.log(s) - 0.5 * math.log(2 * math.pi)


def white_noise(resid: np.ndarray) -> float:
    """White-noise sd of a residual series from its successive differences (robust MAD)."""
    d = np.diff(np.asarray(resid, dtype=float))
    if d.size == 0:
        return float("nan")
    mad = float(np.median(np.abs(d - np.median(d))))
    return 1.4826 * mad / math.sqrt(2.0)


def velocity(test: ShearTest) -> np.ndarray:
    """Backward-difference velocity [m/s] as the kernels see it (zeros without real time)."""
    v = np.zeros(len(test))
    if test.has_time:
        v[1:] = np.diff(test.disp) / np.diff(test.time)
    return v


def test_scales(test: ShearTest) -> Scales:
    from rrfrei.energy import dissipated_energy

    f = float(np.max(np.abs(test.force)))
    d = float(np.max(np.abs(test.disp)))
    v = float(np.max(np.abs(velocity(test)))) or 1.0
    e = float(np.max(np.abs(dissipated_energy(test.disp, test.force)))) or f * d
    return Scales(force=f or 1.0, disp=d or 1.0, vel=v, energy=e)


_ISOLATOR = frozenset({"IsolatorFit", "IsolatorModel", "RETRY_SUBSTEPS", "simulate_retry"})
"""Names of :mod:`rrfrei.gap.isolator` importable from here, as before it was a module of its own."""


def __getattr__(name: str):
    if name in _ISOLATOR:
        from rrfrei.gap import isolator

        return getattr(isolator, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
