"""FEMA 450-style displacement protocols of the RR-FREI study (quasi-static cyclic shear tests).

Amplitudes are multiples of the design displacement DD and the maximum displacement DM
(FEMA 450, sec. 13.6.2.2 prototype tests).  Every cyclic protocol is a sequence of fully reversed
sine cycles ``u(t) = A_k sin(2 pi t / T)`` (cycle k on ``k T <= t <= (k+1) T``), starting and
ending at rest, sampled at ``rate`` Hz.  Displacements in m, time in s.

=========  ====================================================================  ============
protocol   amplitude sequence (one entry per cycle)                              period T [s]
=========  ====================================================================  ============
1          3 x 0.25 DD, 3 x 0.5 DD, 3 x 1.0 DD, 3 x 1.0 DM (calibration)         10
2          2 x 0.5 DD, 2 x 1.0 DM, 2 x 0.25 DD, 3 x 1.0 DD                       8
3          0.2 DD, 0.4 DD, 0.7 DD, 1.0 DD, 0.85 DM, 1.0 DM, 0.4 DM (up, down)    12
4          monotonic push from 0 to 1.5 DM at constant speed                     30 (duration)
=========  ====================================================================  ============

Protocols 2 and 3 were recovered from the bundled synthetic tests
(``rrfrei/data/isolator_synthetic/protocol{2,3}.csv``): with the defaults DD = 20 mm,
DM = 30 mm every cycle is a sine of the amplitude above to the files' 1e-5 mm rounding.  Where an
amplitude is both a round multiple of DD and of DM (12 mm = 0.6 DD = 0.4 DM) the table's choice
is a convention that matters only when DD and DM are changed independently.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["protocol", "protocol1", "protocol2", "protocol3", "protocol4", "AMPLITUDES",
           "DEFAULT_PERIOD"]

# Cycle amplitudes as (multiplier, "dd" | "dm").
AMPLITUDES: dict[int, tuple[tuple[float, str], ...]] = {
    1: ((0.25, "dd"),) * 3 + ((0.5, "dd"),) * 3 + ((1.0, "dd"),) * 3 + ((1.0, "dm"),) * 3,
    2: ((0.5, "dd"),) * 2 + ((1.0, "dm"),) * 2 + ((0.25, "dd"),) * 2 + ((1.0, "dd"),) * 3,
    3: ((0.2, "dd"), (0.4, "dd"), (0.7, "dd"), (1.0, "dd"), (0.85, "dm"), (1.0, "dm"), (0.4, "dm")),
}
"""Cycle amplitude sequences of the cyclic protocols, as (multiplier, base) pairs."""

DEFAULT_PERIOD = {1: 10.0, 2: 8.0, 3: 12.0, 4: 30.0}
"""Cycle period [s] of each protocol (for protocol 4: the duration of the push)."""

PUSH_FACTOR = 1.5
"""Protocol 4 pushes to PUSH_FACTOR * DM."""

MIN_SAMPLES_PER_CYCLE = 8


def _positive(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0.0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return x


def protocol(number: int, *, dd: float = 0.020, dm: float = 0.030, period: float | None = None,
             rate: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Time [s] and displacement [m] of RR-FREI test protocol ``number`` (1-4).

    Parameters
    ----------
    number : protocol number, 1 to 4 (see the module table).
    dd : design displacement DD [m] (> 0).
    dm : maximum displacement DM [m] (>= dd).
    period : cycle period [s] for protocols 1-3, duration of the push for protocol 4; None
        takes the protocol's own value (:data:`DEFAULT_PERIOD`: 10, 8, 12, 30 s).
    rate : sampling rate [Hz]; at least 8 samples per cycle.

    Returns
    -------
    (time, disp) : float64 arrays of equal length; ``time = arange(n) / rate`` and the history
    starts and ends at zero (protocols 1-3) or runs from 0 to 1.5 DM (protocol 4).  The number
    of samples per cycle is ``round(period * rate)``; a non-integer ``period * rate`` is rounded,
    so each cycle lasts exactly that many samples.

    Raises
    ------
    ValueError
        unknown ``number``, non-positive or non-finite values, ``dm < dd``, or fewer than 8
        samples per cycle.
    """
    if isinstance(number, bool) or not isinstance(number, (int, np.integer)) or number not in (1, 2, 3, 4):
        raise ValueError(f"protocol number must be 1, 2, 3 or 4, got {number!r}")
    number = int(number)
    dd = _positive("dd", dd)
    dm = _positive("dm", dm)
    if dm < dd:
        raise ValueError(f"dm = {dm:g} m must be >= dd = {dd:g} m (DM is the larger, maximum displacement)")
    rate = _positive("rate", rate)
    period = DEFAULT_PERIOD[number] if period is None else _positive("period", period)
    m = int(round(period * rate))
    if m < MIN_SAMPLES_PER_CYCLE:
        raise ValueError(
            f"period * rate = {period:g} s * {rate:g} Hz gives {m} samples per cycle; "
            f"at least {MIN_SAMPLES_PER_CYCLE} are needed"
        )
    if number == 4:
        k = np.arange(m + 1)
        return k / rate, (PUSH_FACTOR * dm) * (k / m)
    base = {"dd": dd, "dm": dm}
    amps = np.array([f * base[b] for f, b in AMPLITUDES[number]])
    n_cyc = amps.size
    k = np.arange(n_cyc * m + 1)
    cyc = np.minimum(k // m, n_cyc - 1)
    phase = (k - cyc * m) / m  # in [0, 1], exact at cycle boundaries
    disp = amps[cyc] * np.sin(2.0 * np.pi * phase)
    disp[k % m == 0] = 0.0
    return k / rate, disp


def protocol1(**kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Protocol 1 (calibration): 3 cycles each at 0.25 DD, 0.5 DD, DD and DM; see :func:`protocol`."""
    return protocol(1, **kwargs)


def protocol2(**kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Protocol 2: 2 x 0.5 DD, 2 x DM, 2 x 0.25 DD, 3 x DD, 8 s cycles; see :func:`protocol`."""
    return protocol(2, **kwargs)


def protocol3(**kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Protocol 3: increasing then decreasing amplitudes, 12 s cycles; see :func:`protocol`."""
    return protocol(3, **kwargs)


def protocol4(**kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Protocol 4: monotonic push to 1.5 DM in 30 s; see :func:`protocol`."""
    return protocol(4, **kwargs)
