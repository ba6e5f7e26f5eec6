"""Identification of a shear superstructure (story stiffness and damping) from floor records.

Equation (a shear building; story j joins level j-1 below and level j above, levels bottom-up
with level 0 the base slab on the isolators): the free body of the levels above story j gives

    V_j(t) = -sum_{i >= j} m_i a_i(t) = k_j delta_j(t) + c_j delta_j'(t),

with a_i the absolute level accelerations [m/s^2], m_i [t], delta_j = d_j - d_{j-1} the story
drift [m] and delta_j' its rate [m/s]; k_j [kN/m], c_j [kN s/m].  For each story (k_j, c_j)
follow from ordinary least squares over the record.  The equation is linear and time-invariant,
so it holds for V and delta band-passed by the same filter: both sides are band-passed
(zero-phase Butterworth, 1-15 Hz by default) to drop the isolation mode (where the drift is a
tiny, noise-dominated fraction of the level displacements) and the displacement baseline
errors below, and the sensor noise above.  delta' comes from a five-point central difference of
the filtered drift.

Uncertainty: a moving-block bootstrap (blocks of ``block_s`` seconds, longer than the
correlation time of the band-passed residuals) of the regression rows, ``n_boot`` replicates;
standard errors and 95 % intervals per story.  The OLS standard errors, which assume white
residuals and are too small for filtered data, are reported alongside.

The model of :class:`structures.ShearBuilding` has stiffness-proportional damping
c_j = (2 zeta / omega_1) k_j; :meth:`SuperstructureIdentification.building` fits zeta to the
identified c_j by least squares, zeta = (omega_1 / 2) sum(c_j k_j) / sum(k_j^2), with omega_1
the first fixed-base circular frequency of the identified stiffnesses and the run's masses.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.signal

from structures.shake_table import ShakeTableRun, derivative

__all__ = ["BNCS_STORY_HEIGHT_M", "SuperstructureIdentification", "identify_superstructure"]

BNCS_STORY_HEIGHT_M = 4.27
"""Nominal story height of the BNCS building [m] (14 ft; not stated by the data source).  It only
turns drifts into drift ratios; predictions are compared in drift [m]."""


@dataclass(frozen=True, eq=False)
class SuperstructureIdentification:
    """Story stiffness and damping identified from one run.

    Attributes
    ----------
    run : name of the run.
    stiffness, damping : (S,) k_j [kN/m] and c_j [kN s/m], story 1 (base slab to level 1) first
        (least-squares estimates on the whole record).
    stiffness_se, damping_se : (S,) block-bootstrap standard errors.
    stiffness_ci, damping_ci : (S, 2) bootstrap 95 % percentile intervals.
    ols_se : (S, 2) OLS standard errors of (k_j, c_j) assuming white residuals (too small).
    r2 : (S,) coefficient of determination of each story's regression (band-passed).
    masses : (L,) level masses [t] of the run, base slab first.
    band_hz : (low, high) band-pass [Hz].
    boot : (n_boot, S, 2) bootstrap replicates of (k_j, c_j).
    """

    run: str
    stiffness: np.ndarray
    damping: np.ndarray
    stiffness_se: np.ndarray
    damping_se: np.ndarray
    stiffness_ci: np.ndarray
    damping_ci: np.ndarray
    ols_se: np.ndarray
    r2: np.ndarray
    masses: np.ndarray
    band_hz: tuple[float, float]
    boot: np.ndarray = field(repr=False)

    @property
    def n_stories(self) -> int:
        return int(self.stiffness.size)

    def fixed_base_periods(self) -> np.ndarray:
        """Fixed-base periods [s] of the identified superstructure (base slab held), longest first."""
        k = self.stiffness
        if np.any(k <= 0):
            return np.full(self.n_stories, math.nan)
        K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
        w2 = scipy.linalg.eigh(K, np.diag(self.masses[1:]), eigvals_only=True)
        return 2.0 * math.pi / np.sqrt(w2)

    def damping_ratio(self) -> float:
        """zeta of the stiffness-proportional model fitted to the c_j (module docstring)."""
        w1 = 2.0 * math.pi / float(self.fixed_base_periods()[0])
        k, c = self.stiffness, self.damping
        return float(0.5 * w1 * np.dot(c, k) / np.dot(k, k))

    def table(self) -> pd.DataFrame:
        """One row per story: k [kN/m], its SE and 95 % interval, c [kN s/m], its SE, R^2."""
        return pd.DataFrame({
            "story": np.arange(1, self.n_stories + 1),
            "k_kN_per_m": self.stiffness, "k_se": self.stiffness_se,
            "k_lo95": self.stiffness_ci[:, 0], "k_hi95": self.stiffness_ci[:, 1],
            "c_kNs_per_m": self.damping, "c_se": self.damping_se,
            "c_lo95": self.damping_ci[:, 0], "c_hi95": self.damping_ci[:, 1],
            "k_se_ols": self.ols_se[:, 0], "r2": self.r2,
        })

    def building(self, isolator, *, story_heights: float | Sequence[float] = BNCS_STORY_HEIGHT_M,
                 damping_ratio: float | None = None, name: str = ""):
        """A :class:`structures.ShearBuilding` with the identified stiffnesses and the run's masses.

        Parameters
        ----------
        isolator : a :class:`structures.Isolator`, or a ``rrfrei.Calibration`` of the isolation
            system (e.g. on :func:`structures.shake_table.isolation_test`): its law with the MAP
            parameters as the layer (count 1, length scale 1).
        story_heights : [m], one value or one per story (only for drift ratios).
        damping_ratio : zeta; None fits it to the identified c_j (clipped to [0, 0.3]).
        """
        from structures.building.shear_building import Isolator, ShearBuilding

        if not isinstance(isolator, Isolator):
            law = getattr(isolator, "law", None)
            if law is None or not hasattr(isolator, "map_params"):
                raise ValueError(f"isolator must be a structures.Isolator or a rrfrei.Calibration, got "
                                 f"{type(isolator).__name__}")
            isolator = Isolator(law, isolator.map_params())
        h = np.broadcast_to(np.asarray(story_heights, dtype=float), (self.n_stories,))
        if damping_ratio is None:
            zeta = float(np.clip(self.damping_ratio(), 0.0, 0.3))
        else:
            zeta = float(damping_ratio)
        if np.any(self.stiffness <= 0):
            j = int(np.flatnonzero(self.stiffness <= 0)[0])
            raise ValueError(f"run {self.run!r}: identified stiffness of story {j + 1} is "
                             f"{self.stiffness[j]:.4g} kN/m (not > 0); the run cannot give a building")
        return ShearBuilding(self.masses[1:], self.stiffness, h, zeta, float(self.masses[0]), isolator,
                             damping="stiffness", name=name or f"identified from {self.run}")


def _bandpass(x: np.ndarray, band: tuple[float, float], fs: float) -> np.ndarray:
    sos = scipy.signal.butter(4, band, btype="bandpass", fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def _lstsq(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(X, y, rcond=None)[0]


def identify_superstructure(
    run: ShakeTableRun,
    *,
    band_hz: tuple[float, float] = (1.0, 15.0),
    n_boot: int = 200,
    block_s: float = 2.0,
    seed: int | np.random.Generator = 0,
    trim_s: float = 2.0,
    min_r2: float = 0.8,
) -> SuperstructureIdentification:
    """Story stiffness k_j [kN/m] and damping c_j [kN s/m] from the floor records of ``run``.

    Least squares per story on V_j = k_j delta_j + c_j delta_j' after an identical band-pass
    (``band_hz``, zero-phase 4th-order Butterworth) of both sides; ``trim_s`` seconds at each end
    are dropped (filter transients).  Moving-block bootstrap (``n_boot`` replicates of blocks of
    ``block_s`` s, random generator from ``seed``) for the uncertainty.  See the module docstring.

    Warns (UserWarning) when a story's R^2 < ``min_r2`` or an estimate is not positive: the
    records do not support a shear-building reading of that story.
    """
    if not isinstance(run, ShakeTableRun):
        raise ValueError(f"run must be a ShakeTableRun, got {type(run).__name__}")
    if run.n_levels < 2:
        raise ValueError(f"run {run.name!r} has {run.n_levels} level(s); at least 2 are needed for a story")
    fs = run.rate_hz
    lo, hi = (float(b) for b in band_hz)
    if not (0.0 < lo < hi < fs / 2):
        raise ValueError(f"band_hz = {band_hz!r} is invalid: expected 0 < low < high < {fs / 2:g} Hz "
                         f"(Nyquist of run {run.name!r})")
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 2:
        raise ValueError(f"n_boot = {n_boot!r} is invalid: expected an integer >= 2")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    V = _bandpass(run.story_shear(), (lo, hi), fs)
    D = _bandpass(run.drift(), (lo, hi), fs)
    Dv = derivative(D, run.dt)
    cut = int(round(trim_s * fs))
    if run.time.size - 2 * cut < 50:
        raise ValueError(f"run {run.name!r} is too short ({run.time.size} samples) for trim_s = {trim_s} s")
    V, D, Dv = V[cut:-cut or None], D[cut:-cut or None], Dv[cut:-cut or None]
    n, S = D.shape
    est = np.empty((S, 2))
    ols = np.empty((S, 2))
    r2 = np.empty(S)
    for j in range(S):
        X = np.column_stack([D[:, j], Dv[:, j]])
        y = V[:, j]
        b = _lstsq(X, y)
        res = y - X @ b
        est[j] = b
        s2 = float(res @ res) / (n - 2)
        ols[j] = np.sqrt(np.diag(s2 * np.linalg.inv(X.T @ X)))
        r2[j] = 1.0 - float(res @ res) / float(((y - y.mean()) ** 2).sum())
    L = max(2, int(round(block_s * fs)))
    nb = int(math.ceil(n / L))
    boot = np.empty((n_boot, S, 2))
    for r in range(n_boot):
        starts = rng.integers(0, n - L + 1, size=nb)
        idx = (starts[:, None] + np.arange(L)[None, :]).reshape(-1)[:n]
        for j in range(S):
            boot[r, j] = _lstsq(np.column_stack([D[idx, j], Dv[idx, j]]), V[idx, j])
    se = boot.std(axis=0, ddof=1)
    ci = np.percentile(boot, [2.5, 97.5], axis=0)  # (2, S, 2)
    bad = [j for j in range(S) if r2[j] < min_r2 or est[j, 0] <= 0 or est[j, 1] < 0]
    if bad:
        warnings.warn(
            f"run {run.name!r}: stories {[j + 1 for j in bad]} do not follow V = k drift + c drift' well "
            f"(R^2 {np.round(r2[bad], 3).tolist()}, k {np.round(est[bad, 0]).tolist()} "
            f"kN/m, c {np.round(est[bad, 1]).tolist()} kN s/m): check the channels' timing "
            "and the masses before using this identification", UserWarning, stacklevel=2)
    return SuperstructureIdentification(
        run=run.name, stiffness=est[:, 0].copy(), damping=est[:, 1].copy(),
        stiffness_se=se[:, 0].copy(), damping_se=se[:, 1].copy(),
        stiffness_ci=ci[:, :, 0].T.copy(), damping_ci=ci[:, :, 1].T.copy(), ols_se=ols, r2=r2,
        masses=np.asarray(run.masses, dtype=float).copy(), band_hz=(lo, hi), boot=boot,
    )
