"""Matplotlib figures of records and spectra (labelled axes with units). Imports matplotlib lazily."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .record import G, Record
from .spectra import Spectrum

_QUANTITY = {
    "psa": ("Pseudo-spectral acceleration", "psa"),
    "sd": ("Spectral displacement", "sd"),
    "sv": ("Pseudo-spectral velocity", "sv"),
}
_UNIT = {
    ("psa", "g"): (1 / G, "g"),
    ("psa", "m/s^2"): (1.0, "m/s$^2$"),
    ("sd", "m"): (1.0, "m"),
    ("sd", "cm"): (100.0, "cm"),
    ("sv", "m/s"): (1.0, "m/s"),
    ("sv", "cm/s"): (100.0, "cm/s"),
}
_DEFAULT_UNIT = {"psa": "g", "sd": "m", "sv": "m/s"}


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7, 3.5))
    return ax


def plot_record(record: Record, ax=None, *, units: str = "g", **line_kw):
    """Acceleration history: time [s] against acceleration in ``units`` (``"g"`` or ``"m/s^2"``)."""
    if units not in ("g", "m/s^2"):
        raise ValueError(f"plot_record: units must be 'g' or 'm/s^2', got {units!r}")
    ax = _axes(ax)
    f = 1 / G if units == "g" else 1.0
    ax.plot(record.time, record.accel * f, lw=0.6, label=line_kw.pop("label", record.name), **line_kw)
    ax.set_xlabel("Time [s]")
    ax.set_ylabel(f"Ground acceleration [{'g' if units == 'g' else 'm/s$^2$'}]")
    ax.set_title(f"{record.name}: PGA = {record.pga / G:.3f} g, dt = {record.dt:g} s")
    ax.axhline(0.0, color="0.6", lw=0.4)
    return ax


def plot_spectra(
    spectra: Spectrum | Sequence[Spectrum],
    ax=None,
    *,
    quantity: str = "psa",
    units: str | None = None,
    target: tuple[np.ndarray, np.ndarray] | None = None,
    target_label: str = "target",
    logx: bool = True,
):
    """Spectra against period [s]; ``target`` is ``(periods, values)`` in the plotted ``units``.

    ``quantity`` is ``"psa"`` (units ``"g"`` or ``"m/s^2"``), ``"sd"`` (``"m"``/``"cm"``) or
    ``"sv"`` (``"m/s"``/``"cm/s"``).
    """
    if quantity not in _QUANTITY:
        raise ValueError(f"plot_spectra: quantity must be one of {sorted(_QUANTITY)}, got {quantity!r}")
    units = units or _DEFAULT_UNIT[quantity]
    if (quantity, units) not in _UNIT:
        raise ValueError(f"plot_spectra: units {units!r} do not fit quantity {quantity!r}")
    factor, ulabel = _UNIT[(quantity, units)]
    ax = _axes(ax)
    items = [spectra] if isinstance(spectra, Spectrum) else list(spectra)
    for s in items:
        ax.plot(s.periods, getattr(s, quantity) * factor, lw=1.0, label=s.name or None)
    if target is not None:
        ax.plot(target[0], target[1], "k--", lw=1.6, label=target_label)
    if logx:
        ax.set_xscale("log")
    zeta = {s.damping for s in items}
    title, _ = _QUANTITY[quantity]
    ax.set_xlabel("Period T [s]")
    ax.set_ylabel(f"{title} [{ulabel}]")
    if len(zeta) == 1:
        ax.set_title(f"{title}, {100 * zeta.pop():g} % damping")
    if any(s.name for s in items) or target is not None:
        ax.legend(fontsize="small")
    ax.grid(True, which="both", lw=0.3)
    return ax
