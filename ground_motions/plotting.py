"""Matplotlib figures of records and spectra (labelled axes with units). Imports matplotlib lazily."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .record import G, Record
from .scaling import target_psa
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


def _psa_units(units: str, where: str) -> tuple[float, str]:
    if units not in ("g", "m/s^2"):
        raise ValueError(f"{where}: units must be 'g' or 'm/s^2', got {units!r}")
    return _UNIT[("psa", units)]


def plot_rotd(
    pair,
    periods=None,
    ax=None,
    *,
    damping: float = 0.05,
    target=None,
    target_label: str = "target",
    period_range: tuple[float, float] | None = None,
    units: str = "g",
    logx: bool = True,
):
    """RotD50 and RotD100 of a pair with its two components' spectra (PSA against period).

    Parameters
    ----------
    pair
        A :class:`~ground_motions.pairs.RecordPair`.
    periods
        Periods [s]; default 60 log-spaced from 0.05 to 5 s.
    damping
        Damping ratio of every spectrum.
    target
        Optional target PSA **in m/s^2** (as for :func:`~ground_motions.asce7.scale_pairs_asce7`):
        a callable ``T -> PSA`` (e.g. :func:`~ground_motions.asce7.mcer_target`), a
        :class:`Spectrum` or a ``(periods, psa)`` pair; drawn dashed in ``units``.
    period_range
        Optional ``(T_lo, T_hi)`` [s] shaded (e.g. the ASCE 7-22 17.3.3 range).
    units
        ``"g"`` or ``"m/s^2"`` for the PSA axis.
    """
    from .rotd import component_spectra, rotd_spectrum

    factor, ulabel = _psa_units(units, "plot_rotd")
    t = np.geomspace(0.05, 5.0, 60) if periods is None else np.asarray(periods, dtype=np.float64)
    rot = rotd_spectrum(pair, t, damping, percentile=(50, 100))
    c1, c2 = component_spectra(pair, t, damping)
    ax = _axes(ax)
    ax.plot(t, c1.psa * factor, lw=0.8, color="0.55", label=f"component {pair.components[0] or 1}")
    ax.plot(t, c2.psa * factor, lw=0.8, color="0.55", ls=":", label=f"component {pair.components[1] or 2}")
    ax.plot(t, rot.rotd50.psa * factor, lw=1.4, color="C0", label="RotD50")
    ax.plot(t, rot.rotd100.psa * factor, lw=1.6, color="C3", label="RotD100 (maximum direction)")
    if target is not None:
        ax.plot(t, target_psa(target, t, where="plot_rotd") * factor, "k--", lw=1.4, label=target_label)
    if period_range is not None:
        ax.axvspan(*period_range, color="0.9", zorder=0, label="scaling range")
    if logx:
        ax.set_xscale("log")
    ax.set_xlabel("Period T [s]")
    ax.set_ylabel(f"Pseudo-spectral acceleration [{ulabel}]")
    ax.set_title(f"{pair.name}: RotD50 / RotD100, {100 * damping:g} % damping")
    ax.legend(fontsize="small")
    ax.grid(True, which="both", lw=0.3)
    return ax


def plot_scaled_suite(suite, ax=None, *, units: str = "g"):
    """A :class:`~ground_motions.asce7.ScaledSuite`: each scaled pair's RotD100, their average,
    the target and ``fraction x target`` over the ASCE 7-22 17.3.3 period range."""
    factor, ulabel = _psa_units(units, "plot_scaled_suite")
    ax = _axes(ax)
    t = suite.periods
    for p, row in zip(suite.pairs, suite.rotd100):
        ax.plot(t, row * factor, lw=0.7, alpha=0.7, label=f"{p.name} x {p.scale_factor:.3g}")
    ax.plot(t, suite.average * factor, color="C3", lw=2.0, label="suite average RotD100")
    ax.plot(t, suite.target * factor, "k--", lw=1.4, label="target (MCE$_R$)")
    if suite.fraction != 1.0:
        ax.plot(t, suite.fraction * suite.target * factor, "k:", lw=1.0, label=f"{suite.fraction:g} x target")
    ax.axvline(suite.governing_period, color="0.5", lw=0.8, ls="-.", label="governing period")
    ax.set_xlabel("Period T [s]")
    ax.set_ylabel(f"Pseudo-spectral acceleration [{ulabel}]")
    ax.set_title(
        f"ASCE 7-22 17.3.3: {suite.n_pairs} pairs scaled over "
        f"{suite.period_range[0]:.3g}-{suite.period_range[1]:.3g} s"
    )
    ax.legend(fontsize="small")
    ax.grid(True, which="both", lw=0.3)
    return ax
