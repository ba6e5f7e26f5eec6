"""Ground motions: reading accelerograms, bundled records, response spectra and scaling.

Layers (arrows point down): the public functions here validate and orchestrate; the spectra
recurrence is a Numba kernel over arrays (``spectra._nigam_jennings``).

- :class:`Record` (``dt`` [s], ``accel`` [m/s^2], read-only), :func:`read` (AT2, V2, V1/RAW,
  text, CSV), :func:`load` / :func:`available` (bundled records), :func:`baseline_correct`.
- :func:`response_spectrum` -> :class:`Spectrum` (Nigam-Jennings, Numba), :func:`sdof_response`,
  :func:`design_spectrum` (ASCE 7-22 two-period shape).
- :func:`scale_to_pga`, :func:`scale_to_spectrum`; :func:`plot_record`, :func:`plot_spectra`.
- Pairs of horizontal components (issue 14): :class:`RecordPair` (one clock, ``scaled``,
  ``rotated``), :func:`read_pair`, :func:`load_pair` / :func:`available_pairs`;
  :func:`rotd_spectrum` -> :class:`RotDSpectrum` (RotD50/RotD100, Boore 2010, Numba);
  :func:`scale_pairs_asce7` -> :class:`ScaledSuite` (ASCE 7-22 17.3.3), :func:`mcer_target`,
  :func:`design_value` (17.6.3.4: average of 7 or more pairs, else maximum); :func:`plot_rotd`.
"""

import rrfrei._jit_cache  # noqa: F401  (first: the kernel cache locator, before any @njit)

from .asce7 import ScaledSuite, design_value, mcer_target, scale_pairs_asce7
from .catalogue import available, available_pairs, load, load_pair
from .io import read
from .pairs import RecordPair, read_pair
from .plotting import plot_record, plot_rotd, plot_scaled_suite, plot_spectra
from .processing import baseline_correct, integrate
from .record import G, Record
from .rotd import RotDSpectrum, rotd_spectrum
from .scaling import scale_to_pga, scale_to_spectrum
from .spectra import Spectrum, design_spectrum, response_spectrum, sdof_response

__all__ = [
    "G",
    "Record",
    "RecordPair",
    "RotDSpectrum",
    "ScaledSuite",
    "Spectrum",
    "design_spectrum",
    "design_value",
    "mcer_target",
    "plot_record",
    "plot_rotd",
    "plot_scaled_suite",
    "plot_spectra",
    "response_spectrum",
    "rotd_spectrum",
    "scale_pairs_asce7",
    "scale_to_pga",
    "scale_to_spectrum",
    "sdof_response",
    "available",
    "available_pairs",
    "baseline_correct",
    "integrate",
    "load",
    "load_pair",
    "read",
    "read_pair",
]
