"""Stretch histories of the study's two testing protocols (uniaxial, engineering strain rate).

The study gives the amplitudes only in a figure, so every default below is a documented guess
(``docs/reference/prf_model.md`` section 7).  Both return sample times (s) and stretches of a
piecewise-linear history: a uniform grid of step ``dt`` plus every kink (reversal, start/end of a
hold) inserted exactly, so a simulation lands a step on each kink.
"""

from __future__ import annotations

import numpy as np


def _sample(knots_t: list[float], knots_l: list[float], dt: float) -> tuple[np.ndarray, np.ndarray]:
    if not dt > 0:
        raise ValueError(f"dt = {dt!r}: expected > 0")
    kt = np.asarray(knots_t, dtype=float)
    grid = np.arange(0.0, kt[-1], dt)
    t = np.union1d(grid, kt)
    # drop grid points closer than 1e-9 s to a knot (keep the knot)
    keep = np.ones(t.size, bool)
    for i in range(1, t.size):
        if t[i] - t[i - 1] < 1e-9:
            keep[i - 1 if t[i - 1] not in kt else i] = False
    t = t[keep]
    return t, np.interp(t, kt, np.asarray(knots_l, dtype=float))


def _rate(rate: float) -> None:
    if not rate > 0:
        raise ValueError(f"rate = {rate!r}: expected a stretch rate > 0 (1/s)")


def protocol1(lam0: float = 1.2, amp: float = 0.1, n_cycles: int = 5, rate: float = 0.093, *,
              dt: float = 0.1, hold0: float = 0.0, unload: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Saw-tooth cycles about a pre-imposed stretch (protocol 1).

    Ramp 1 -> lam0 at ``rate`` (1/s), optional hold ``hold0`` (s), then ``n_cycles`` of
    lam0 -> lam0 + amp -> lam0 - amp -> lam0; ``unload`` appends a ramp back to lambda = 1
    (beware: the model goes into compression there).  Defaults are guesses (the study shows them only
    in a figure).  Returns (time s, stretch).
    """
    _rate(rate)
    if not (lam0 > 1 and 0 < amp < lam0 - 0.0):
        raise ValueError(f"lam0 = {lam0!r}, amp = {amp!r}: expected lam0 > 1 and 0 < amp < lam0")
    if int(n_cycles) != n_cycles or n_cycles < 0:
        raise ValueError(f"n_cycles = {n_cycles!r}: expected a non-negative integer")
    t, lam = [0.0], [1.0]

    def go(target: float) -> None:
        t.append(t[-1] + abs(target - lam[-1]) / rate)
        lam.append(target)

    go(lam0)
    if hold0 > 0:
        t.append(t[-1] + hold0)
        lam.append(lam0)
    for _ in range(int(n_cycles)):
        go(lam0 + amp)
        go(lam0 - amp)
        go(lam0)
    if unload:
        go(1.0)
    return _sample(t, lam, dt)


def protocol2(levels: tuple[float, ...] = (1.1, 1.2, 1.3), hold: float = 60.0, rate: float = 0.093, *,
              dt: float = 0.1, unload: bool = False, return_between: bool = False
              ) -> tuple[np.ndarray, np.ndarray]:
    """Loading then relaxation at several stretch levels (protocol 2).

    Staircase: ramp at ``rate`` to each level of ``levels`` and hold ``hold`` s; with
    ``return_between`` the stretch returns to 1 after each hold; ``unload`` ends with a ramp to 1.
    Defaults are guesses.  Returns (time s, stretch).
    """
    _rate(rate)
    if not hold >= 0:
        raise ValueError(f"hold = {hold!r}: expected >= 0 s")
    if len(levels) == 0 or any(not (x > 0) for x in levels):
        raise ValueError(f"levels = {levels!r}: expected positive stretches")
    t, lam = [0.0], [1.0]
    for x in levels:
        t.append(t[-1] + abs(x - lam[-1]) / rate)
        lam.append(float(x))
        if hold > 0:
            t.append(t[-1] + hold)
            lam.append(float(x))
        if return_between:
            t.append(t[-1] + abs(x - 1.0) / rate)
            lam.append(1.0)
    if unload and lam[-1] != 1.0:
        t.append(t[-1] + abs(lam[-1] - 1.0) / rate)
        lam.append(1.0)
    return _sample(t, lam, dt)


def load_unload(lam_max: float, rate: float, *, dlam: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """One load-unload cycle 1 -> ``lam_max`` -> 1 at a constant stretch rate ``rate`` (1/s).

    Samples every ``dlam`` of stretch (the reversal is a sample).  Returns (time s, stretch).
    """
    _rate(rate)
    if not lam_max > 1:
        raise ValueError(f"lam_max = {lam_max!r}: expected a stretch > 1")
    if not 0 < dlam < lam_max - 1:
        raise ValueError(f"dlam = {dlam!r}: expected 0 < dlam < lam_max - 1")
    t_up = (lam_max - 1.0) / rate
    return _sample([0.0, t_up, 2.0 * t_up], [1.0, lam_max, 1.0], dlam / rate)
