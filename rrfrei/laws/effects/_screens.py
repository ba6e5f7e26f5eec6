"""Regression helpers of the effects' signature screens (plain NumPy, no kernels).

A screen scores how well the baseline residual of a calibration test correlates with an effect's
tell-tale regressor, after both are cleared of what the base law already explains (its
``controls``): a number in [0, 1] that the gap diagnosis (:mod:`rrfrei.gap.diagnose`) uses as a
hint, never as a verdict.
"""

from __future__ import annotations

import numpy as np

__all__ = ["corr", "partial", "signed_partial", "force_sign"]


def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return 0.0 if den == 0 else float((a * b).sum()) / den


def corr(a: np.ndarray, b: np.ndarray) -> float:
    """|Pearson correlation| of ``a`` and ``b`` (0 when either is constant)."""
    return abs(_pearson(a, b))


def _cleared(r: np.ndarray, x: np.ndarray, controls: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    C = np.column_stack([np.ones_like(r), *controls])
    br, *_ = np.linalg.lstsq(C, r, rcond=None)
    bx, *_ = np.linalg.lstsq(C, x, rcond=None)
    return r - C @ br, x - C @ bx


def partial(r: np.ndarray, x: np.ndarray, controls: list[np.ndarray]) -> float:
    """|corr| of r and x after regressing both on the controls (and a constant)."""
    return corr(*_cleared(r, x, controls))


def signed_partial(r: np.ndarray, x: np.ndarray, controls: list[np.ndarray]) -> float:
    """:func:`partial` with its sign, in [-1, 1]: for effects whose residual has a known
    direction (a stiffening adds force, a pinching removes it)."""
    return _pearson(*_cleared(r, x, controls))


def force_sign(ctx) -> np.ndarray:
    """Sign of the baseline's predicted force (``ctx.force_pred``)."""
    return np.sign(ctx.force_pred)
