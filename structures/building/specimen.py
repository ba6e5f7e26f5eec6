"""Does a posterior describe an isolator for *this* building?  Checks before propagation.

A posterior calibrated on a very different specimen (a reinforced-concrete column, a steel
connection, a bearing of another size without the right ``length_scale``) runs through a
building without complaint and gives demand distributions that mean nothing.  Two physical
checks catch that before thousands of analyses are spent on it; each returns a sentence that
names the numbers, and :func:`structures.propagate` turns it into a :class:`SpecimenWarning`
and a note of the :class:`~structures.propagation.propagate.ResponseSet`:

1. **Period shift.**  An isolation layer works by lengthening the period well beyond the
   superstructure's own: the isolated period at the tested displacement, with the layer
   linearised at its secant stiffness (:meth:`ShearBuilding.isolated_period`), must be at least
   :data:`MIN_PERIOD_SHIFT` times the fixed-base period T1.  Naeim & Kelly (1999, *Design of
   Seismic Isolated Structures*, ch. 1) ask for about 3; ASCE 7-22 ch. 17 sets no number.  We
   warn below 2, where the layer barely isolates at all.
2. **Agreement with the building's own isolator.**  When the building names isolator
   parameters (its design bearing), the posterior's secant stiffness at the same prototype
   displacement must lie within a factor :data:`MAX_STIFFNESS_RATIO` of the design bearing's.
   ASCE 7-22 section 17.2.8.4 property-modification factors span about 0.6-1.8; a factor of
   4 is far outside anything one bearing type shows.

Both use the posterior's median parameters at the largest tested displacement (prototype:
``length_scale`` x specimen), or at 0.1 m prototype displacement when the tested range is
unknown.  Units: kN, m, s, t.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from rrfrei.errors import NUMERICAL_ERRORS

__all__ = ["SpecimenWarning", "specimen_checks", "MIN_PERIOD_SHIFT", "MAX_STIFFNESS_RATIO"]

#: Smallest isolated-to-fixed-base period ratio accepted without a warning.
MIN_PERIOD_SHIFT = 2.0
#: Largest ratio (either way) between the posterior's and the design bearing's secant stiffness.
MAX_STIFFNESS_RATIO = 4.0
#: Prototype displacement [m] used when the calibrated range is unknown.
DEFAULT_DISP = 0.1


class SpecimenWarning(UserWarning):
    """The posterior does not look like an isolator for the building it is run through."""


def specimen_checks(building, params: Mapping[str, float], disp_prototype: float | None) -> list[str]:
    """Sentences describing every failed check (empty when the posterior fits the building).

    Parameters
    ----------
    building : :class:`~structures.ShearBuilding` whose isolator law the parameters follow.
    params : one full parameter set of that law (typically the posterior median) [kN, m, s].
    disp_prototype : largest tested isolator displacement at prototype scale [m], or None.

    A check that cannot be evaluated (the law's local solve fails at these parameters, a
    non-positive secant stiffness) is itself reported, never raised.
    """
    d = DEFAULT_DISP if disp_prototype is None or not disp_prototype > 0 else float(disp_prototype)
    where = "at the largest tested" if disp_prototype else f"at an assumed {DEFAULT_DISP:g} m"
    out: list[str] = []
    try:
        trial = building.with_isolator_params(params)
        t1 = float(building.fixed_base_modes()[0][0])
        k_post = trial.isolator.effective_stiffness(d)
        t_iso = trial.isolated_period(d)
    except NUMERICAL_ERRORS + (ValueError,) as exc:
        return [f"the posterior's median parameters could not be checked against the building "
                f"({type(exc).__name__}: {exc})"]
    if not (math.isfinite(t_iso) and t_iso >= MIN_PERIOD_SHIFT * t1):
        out.append(
            f"the posterior gives an isolated period of {t_iso:.2f} s {where} isolator displacement "
            f"({d:.3g} m, secant layer stiffness {k_post:.4g} kN/m), only {t_iso / t1:.1f} x the "
            f"superstructure's fixed-base period {t1:.2f} s (an isolator needs >= {MIN_PERIOD_SHIFT:g} x): "
            "was it calibrated on an isolator, at this similitude scale?")
    design = building.isolator.params
    if design is not None:
        try:
            k_design = building.isolator.effective_stiffness(d)
        except NUMERICAL_ERRORS + (ValueError,):
            k_design = float("nan")
        ratio = k_post / k_design if k_design > 0 else float("nan")
        if np.isfinite(ratio) and not (1.0 / MAX_STIFFNESS_RATIO <= ratio <= MAX_STIFFNESS_RATIO):
            out.append(
                f"the posterior's secant layer stiffness {k_post:.4g} kN/m at {d:.3g} m is {ratio:.3g} x "
                f"that of the building's own isolator ({k_design:.4g} kN/m; accepted within "
                f"{MAX_STIFFNESS_RATIO:g} x either way): the posterior may come from a different specimen")
    return out
