"""Ground motions: reading accelerograms, bundled records, response spectra and scaling.

Layers (arrows point down): the public functions here validate and orchestrate; the spectra
recurrence is a Numba kernel over arrays (``spectra._nigam_jennings``).

- :class:`Record` (``dt`` [s], ``accel`` [m/s^2], read-only), :func:`read` (AT2, V2, V1/RAW,
  text, CSV), :func:`load` / :func:`available` (bundled records), :func:`baseline_correct`.
"""

from .catalogue import available, load
from .io import read
from .processing import baseline_correct, integrate
from .record import G, Record

__all__ = [
    "G",
    "Record",
    "available",
    "baseline_correct",
    "integrate",
    "load",
    "read",
]
