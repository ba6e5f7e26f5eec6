"""Priors for calibration: the registry priors, rescaled to the test, and user overrides.

The registry (:mod:`rrfrei.laws`) holds each parameter's *base* prior in absolute units.  Those
are deliberately wide and blind to the size of the specimen; a 80 mm RR-FREI and a 1 m lead-rubber
bearing differ in stiffness by four orders of magnitude.  :func:`data_scaled_prior` therefore
rescales the base prior of every parameter whose unit is made of kN and m only (not
dimensionless, no time) to the test's force and displacement scale

    s = F_max^a * d_max^b      for a unit kN^a m^b,   F_max = max|F|, d_max = max|u|,

keeping the base prior's *kind*:

* ``loguniform``  -> loguniform(1e-3 s, 1e3 s)  (six decades around the scale);
* ``lognormal``   -> lognormal(median s, same log-sd);
* ``normal``      -> normal(same mean rescaled by s/|mean| when the mean is not 0, sd s);
* ``halfnormal``  -> halfnormal(s);
* ``uniform``     -> unchanged (a dimensional uniform prior is a deliberate statement).

Dimensionless parameters, parameters with time in their unit (rates, viscosities) and geometry
keep the base prior.  Every prior is then cut to the parameter's physical bounds (by the
log prior of :class:`~.likelihood.Problem`, whose ``lower`` / ``upper`` hold them).  Pass
``priors="registry"`` to :func:`rrfrei.calibrate` to use the base priors unchanged, or a mapping /
TOML file to override any of them.

Noise priors (:meth:`.noise.NoiseModel.priors`): ``sigma`` [kN] ~ halfnormal(RMS(F)); ``rho``
(AR(1) correlation) ~ uniform(-0.99, 0.99).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rrfrei._inputs import read_toml
from rrfrei.calibration.noise import NoiseModel
from rrfrei.laws import LawSpec, Prior

__all__ = ["data_scaled_prior", "resolve_priors", "unit_exponents", "PriorSet"]


def unit_exponents(unit: str) -> dict[str, float] | None:
    """Exponents of ``kN``, ``m``, ``s`` in a unit string such as ``"kN*s/m"`` or ``"1/m^3"``.

    Returns None for units it does not understand (they keep the registry prior).
    """
    u = unit.strip().replace(" ", "")
    if u in ("-", "", "1"):
        return {}
    parts = u.split("/")
    if len(parts) > 2:
        return None
    out: dict[str, float] = {}
    for sign, part in zip((1.0, -1.0), parts):
        for tok in part.split("*"):
            if tok in ("", "1"):
                continue
            m = re.fullmatch(r"(kN|m|s)(?:\^(-?\d+(?:\.\d+)?))?", tok)
            if not m:
                return None
            out[m.group(1)] = out.get(m.group(1), 0.0) + sign * float(m.group(2) or 1)
    return {k: v for k, v in out.items() if v != 0}


def data_scaled_prior(base: Prior, unit: str, force_scale: float, disp_scale: float) -> Prior:
    """The base prior rescaled to the test (rules in the module docstring)."""
    exps = unit_exponents(unit)
    if not exps or "s" in exps or base.kind == "uniform":
        return base
    s = force_scale ** exps.get("kN", 0.0) * disp_scale ** exps.get("m", 0.0)
    if not (math.isfinite(s) and s > 0):
        return base
    if base.kind == "loguniform":
        return Prior("loguniform", 1e-3 * s, 1e3 * s)
    if base.kind == "lognormal":
        return Prior("lognormal", s, base.b)
    if base.kind == "normal":
        mean = 0.0 if base.a == 0 else math.copysign(s, base.a)
        return Prior("normal", mean, s)
    return Prior("halfnormal", s)


class PriorSet(dict):
    """``{name: Prior}`` for the sampled quantities (law parameters, then sigma, rho)."""


def _as_prior(name: str, value) -> Prior:
    if isinstance(value, Prior):
        return value
    if isinstance(value, Mapping):
        return Prior.from_mapping(value)
    if isinstance(value, (tuple, list)) and len(value) in (2, 3):
        return Prior(str(value[0]), *map(float, value[1:]))
    raise ValueError(
        f"prior of {name!r} must be a Prior, a mapping {{kind, a, b}} or a tuple (kind, a, b); "
        f"got {value!r}"
    )


def _load_overrides(priors) -> dict[str, Prior]:
    if priors is None or (isinstance(priors, str) and priors == "registry"):
        return {}
    if isinstance(priors, (str, Path)):
        data = read_toml(priors)
        data = data.get("priors", data)
        return {k: _as_prior(k, v) for k, v in data.items()}
    if isinstance(priors, Mapping):
        return {str(k): _as_prior(str(k), v) for k, v in priors.items()}
    raise ValueError(f"priors must be None, 'registry', a mapping or a TOML path; got {priors!r}")


def resolve_priors(
    spec: LawSpec,
    free: tuple[str, ...],
    force: np.ndarray,
    disp: np.ndarray,
    noise: NoiseModel,
    priors=None,
) -> PriorSet:
    """Priors of ``free`` law parameters and the noise parameters (``noise.priors``).

    Order of precedence: user override > data-scaled registry prior (or the raw registry prior
    when ``priors == "registry"``).
    """
    overrides = _load_overrides(priors)
    scaled = not (isinstance(priors, str) and priors == "registry")
    fs = float(np.max(np.abs(force)))
    ds = float(np.max(np.abs(disp)))
    out = PriorSet()
    for name in free:
        ps = spec.param(name)
        if name in overrides:
            out[name] = overrides[name]
            continue
        if ps.prior is None:
            raise ValueError(
                f"law {spec.name!r}: parameter {name!r} has no registry prior; give one in priors="
            )
        out[name] = data_scaled_prior(ps.prior, ps.unit, fs, ds) if scaled else ps.prior
    for name, pr in noise.priors(force).items():
        out[name] = overrides.get(name, pr)
    unknown = [k for k in overrides if k not in out]
    if unknown:
        raise ValueError(
            f"priors given for {', '.join(map(repr, unknown))}, which are not sampled for law "
            f"{spec.name!r}; sampled: {', '.join(out)}"
        )
    return out


# ---------------------------------------------------------------------------------------------
# unit-cube map used by the optimiser (CMA-ES works on [0, 1]^k)
# ---------------------------------------------------------------------------------------------
def cube_range(prior: Prior, lower: float, upper: float) -> tuple[str, float, float]:
    """(scale kind 'lin'|'log', lo, hi) of the search box of one parameter.

    The box spans the prior's support (uniform/loguniform), +-4 sd (normal), 4 log-sd
    (lognormal) or [0, 4 scale] (halfnormal), cut to the physical bounds.
    """
    k = prior.kind
    if k == "uniform":
        kind, lo, hi = "lin", prior.a, prior.b
    elif k == "loguniform":
        kind, lo, hi = "log", prior.a, prior.b
    elif k == "normal":
        kind, lo, hi = "lin", prior.a - 4 * prior.b, prior.a + 4 * prior.b
    elif k == "lognormal":
        kind, lo, hi = "log", prior.a * math.exp(-4 * prior.b), prior.a * math.exp(4 * prior.b)
    else:
        kind, lo, hi = "lin", 0.0, 4 * prior.a
    lo, hi = max(lo, lower), min(hi, upper)
    if kind == "log" and lo <= 0:
        lo = hi * 1e-9
    return kind, lo, hi
