"""Multiple stripe analysis: records scaled to common levels of a real intensity measure.

The intensity measure (IM) is the 5 %-damped pseudo-spectral acceleration at the isolated
period, ``Sa(T_iso)``, or the peak ground acceleration, both in g.  ``T_iso`` is the first period
of the building with its isolator layer at its secant (effective) stiffness at the displacement
limit (:meth:`structures.ShearBuilding.isolated_period`), the amplitude where the fragility
matters.  At stripe ``j`` every record ``r`` is scaled by ``x_j / IM_r`` so that all records
share the intensity ``x_j`` (multiple stripe analysis: Jalayer & Cornell 2009; Baker 2015,
section "Multiple stripe analysis"); every posterior draw of the isolator law runs on every
scaled record, and the lognormal fragility ``P(D > limit | IM = x) = Phi(ln(x / theta) / beta)``
is fitted by maximum likelihood over the stripe counts
(:func:`structures.propagation.fragility.fit_fragility`,
Baker 2015 eqs. 11-12).

Stripes that span the range: unless the levels are given, a pilot analysis with the posterior
median isolator finds, for each record, the intensity at which the isolator reaches the limit
(two secant updates from a linear guess, ``x <- x * limit / D(x)``); the stripes run
geometrically from 0.8 times the smallest to 1.25 times the largest of these crossings, so the
fraction of analyses beyond the limit goes from about none to about all, with most stripes in
between (where beta is resolved).

Units: IM in g (standard gravity 9.80665 m/s^2), periods in s, displacements in m (prototype).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ground_motions import G, Record, response_spectrum
from structures.dynamics.history import time_history_batch
from structures.propagation.fragility import Fragility
from structures.propagation.inputs import pack_draws, resolve_building, resolve_posterior, resolve_records
from structures.propagation.propagate import DEFAULT_DRIFT_LIMIT, propagate
from structures.propagation.responses import ResponseSet

__all__ = ["IntensityMeasure", "StripeAnalysis", "crossing_intensities", "multiple_stripe_analysis",
           "spanning_levels"]

IM_DAMPING = 0.05
"""Damping ratio of the spectral intensity measure (the conventional 5 % of critical)."""


@dataclass(frozen=True)
class IntensityMeasure:
    """A scalar intensity measure of a record, in g.

    ``period`` [s] > 0 gives the pseudo-spectral acceleration ``Sa(T, damping)`` of a linear
    oscillator (``ground_motions.response_spectrum``); ``period=None`` gives the PGA.
    """

    period: float | None = None
    damping: float = IM_DAMPING

    def __post_init__(self) -> None:
        if self.period is not None:
            t = float(self.period)
            if not (math.isfinite(t) and t > 0.0):
                raise ValueError(f"IntensityMeasure.period = {self.period!r} s is invalid: expected a "
                                 "finite period > 0 s, or None for the PGA")
            object.__setattr__(self, "period", t)
        z = float(self.damping)
        if not (0.0 <= z < 1.0):
            raise ValueError(f"IntensityMeasure.damping = {self.damping!r} is invalid: expected a ratio "
                             "of critical damping in [0, 1)")
        object.__setattr__(self, "damping", z)

    @property
    def name(self) -> str:
        """Short name, e.g. ``Sa(1.39 s)`` or ``PGA``."""
        return "PGA" if self.period is None else f"Sa({self.period:.3g} s)"

    @property
    def label(self) -> str:
        """Axis label with its definition and unit."""
        if self.period is None:
            return "peak ground acceleration PGA [g]"
        return (f"Sa(T_iso = {self.period:.3g} s, {100 * self.damping:.3g} % damping) [g]")

    def of(self, record: Record) -> float:
        """The record's intensity [g]."""
        if self.period is None:
            return record.pga / G
        return float(response_spectrum(record, [self.period], self.damping).psa[0]) / G


@dataclass(frozen=True, eq=False)
class StripeAnalysis:
    """The result of :func:`multiple_stripe_analysis`.

    Attributes
    ----------
    responses
        The demands; its ``scale`` column is the stripe's intensity [g] and its ``im_label`` the
        IM's axis label.  ``record_factors`` holds each record's normalising factor ``1 / IM_r``.
    im
        The intensity measure.
    record_im
        Each record's own (unscaled) intensity [g].
    crossings
        The pilot's estimate, per record, of the intensity at which the median isolator reaches
        the limit [g] (empty when the levels were given).
    """

    responses: ResponseSet
    im: IntensityMeasure
    record_im: dict[str, float]
    crossings: dict[str, float]

    @property
    def levels(self) -> tuple[float, ...]:
        """The stripes' intensities [g]."""
        return self.responses.scales

    def fragility(self, limits: Mapping[str, float] | None = None) -> list[Fragility]:
        """Lognormal fragility per limit against the IM, maximum likelihood over the stripes."""
        return self.responses.fragility(limits)

    def plot_fragility(self, limits: Mapping[str, float] | None = None, ax=None):
        """Fragility curves against the IM with the observed fraction at each stripe."""
        return self.responses.plot_fragility(limits, ax=ax)


def _median_building(bld, posterior, n_samples: int, seed: int):
    """(building with the posterior-median isolator, packed median, default limits)."""
    law, draws, cal_range = resolve_posterior(posterior, n_samples, seed)
    spec = bld.isolator.spec
    median = np.median(pack_draws(spec, draws), axis=0)
    ref = bld.with_isolator_params(median)
    lim: dict[str, float] = {}
    if cal_range is not None:
        lim["iso_disp_peak_m"] = bld.isolator.length_scale * max(abs(cal_range[0]), abs(cal_range[1]))
    lim["drift_ratio_max"] = DEFAULT_DRIFT_LIMIT
    return ref, median, lim


def crossing_intensities(building, records: Sequence[Record], params, limit: float, *,
                         demand: str = "iso_disp_peak", iterations: int = 2) -> dict[str, float]:
    """Per record, the intensity multiplier at which ``demand`` of one isolator reaches ``limit``.

    ``records`` are normalised (their IM is 1 g), ``params`` one packed parameter set.  Starts from
    the linear guess ``x = limit / D(1)`` and applies ``iterations`` secant updates
    ``x <- x * limit / D(x)`` (demand roughly proportional to intensity near the limit).  A record
    whose analysis fails keeps its last estimate.
    """
    P = np.asarray(params, dtype=float)[None, :]
    out = {}
    for rec in records:
        x = 1.0
        for _ in range(1 + int(iterations)):
            res = time_history_batch(building, rec.scaled(x), P)
            d = float(np.asarray(res[demand]).ravel()[0])
            if not (math.isfinite(d) and d > 0.0):
                break
            x = x * limit / d
        out[rec.name] = float(x)
    return out


def spanning_levels(crossings: Mapping[str, float], n_levels: int = 7, *, below: float = 0.8,
                    above: float = 1.25) -> tuple[float, ...]:
    """``n_levels`` intensities [g], geometric from ``below`` x the smallest crossing to ``above``
    x the largest (three significant digits).

    With an efficient IM the crossings of the records lie close together (records scaled to one
    Sa(T_iso) move the isolator alike), so the stripes are kept close around them: several
    stripes fall where some but not all runs exceed the limit, which is what resolves beta.
    """
    x = np.array([v for v in crossings.values() if math.isfinite(v) and v > 0.0])
    if x.size == 0:
        raise ValueError("no record reached a finite crossing intensity: give the stripe levels")
    if int(n_levels) < 2:
        raise ValueError(f"n_levels = {n_levels!r}: a fragility needs at least 2 stripes")
    lv = np.geomspace(below * x.min(), above * x.max(), int(n_levels))
    return tuple(float(f"{v:.3g}") for v in lv)


def multiple_stripe_analysis(
    posterior,
    building,
    records,
    *,
    im: IntensityMeasure | None = None,
    levels: Sequence[float] | None = None,
    n_levels: int = 7,
    n_samples: int = 20,
    seed: int = 0,
    limits: Mapping[str, float] | None = None,
    progress: bool = True,
    chunk_size: int = 50,
) -> StripeAnalysis:
    """Run posterior draws of the isolator law on records scaled to stripes of a real IM.

    Parameters
    ----------
    posterior, building, records, n_samples, seed, progress, chunk_size
        As in :func:`structures.propagation.propagate.propagate` (records: bundled names, paths or
        ``Record``\\ s).
    im
        The intensity measure; default ``Sa(T_iso, 5 %)`` with ``T_iso`` the isolated period at
        the isolator displacement limit (posterior-median isolator; its initial stiffness when
        the limit is unknown).
    levels
        The stripes' intensities [g]; default: ``n_levels`` levels spanning the pilot's crossing
        intensities (:func:`spanning_levels`).
    limits
        Demand limits (default as in ``propagate``: the largest tested isolator displacement at
        prototype scale, and a 0.5 % drift ratio).

    Returns
    -------
    StripeAnalysis
    """
    bld = resolve_building(building)
    recs = resolve_records(records)
    ref, median, lim = _median_building(bld, posterior, n_samples, seed)
    if limits is not None:
        lim = {str(k): float(v) for k, v in dict(limits).items()}
    if im is None:
        im = IntensityMeasure(ref.isolated_period(lim.get("iso_disp_peak_m")), IM_DAMPING)
    record_im = {}
    normalised = []
    for r in recs:
        x = im.of(r)
        if not x > 0.0:
            raise ValueError(f"record {r.name!r} has {im.name} = {x:g} g: it cannot be scaled to a stripe")
        record_im[r.name] = x
        normalised.append(r.scaled(1.0 / x))
    crossings: dict[str, float] = {}
    if levels is None:
        if "iso_disp_peak_m" not in lim:
            raise ValueError("no isolator displacement limit to place the stripes on: give levels= or "
                             "limits={'iso_disp_peak_m': ...}")
        crossings = crossing_intensities(ref, normalised, median, lim["iso_disp_peak_m"])
        levels = spanning_levels(crossings, n_levels)
    rs = propagate(posterior, bld, normalised, n_samples=n_samples, scales=tuple(levels), seed=seed,
                   limits=lim, progress=progress, chunk_size=chunk_size)
    note = (f"multiple stripe analysis: {len(recs)} records scaled to {len(rs.scales)} levels of "
            f"{im.label} (each record's own value in record_im)")
    rs = replace(rs, im_label=im.label, record_factors={k: 1.0 / v for k, v in record_im.items()},
                 notes=(*rs.notes, note))
    return StripeAnalysis(responses=rs, im=im, record_im=record_im, crossings=crossings)
