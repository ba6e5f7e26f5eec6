"""The gap in the engineer's quantities: k_eff, beta_eff, EDC, Qd and the force at DD and DM;
ASCE 7-22 property modification factors; upper- and lower-bound law parameters.

Units: displacement [m], force [kN], energy [kN m], stiffness [kN/m].

Quantities of a test (:func:`design_quantities`)
-----------------------------------------------
Per full cycle (the cycles of :func:`rrfrei.energy.cycle_bounds`, with ``d+``, ``d-`` the
extreme displacements of the cycle and ``F+``, ``F-`` the forces there), as ASCE 7-22
section 17.8.5 (eqs. 17.8-1 and 17.8-2) and isolator test reports state them::

    amplitude d = (d+ - d-) / 2
    k_eff       = (F+ - F-) / (d+ - d-)                     [kN/m]
    EDC         = the loop's energy, the trapezoidal integral of F du over the cycle   [kN m]
    beta_eff    = EDC / (2 pi k_eff d^2)                    [-]
    Qd          = mean |F| at the cycle's zero crossings of u (linear interpolation)   [kN]

(the first three from :func:`rrfrei.energy.cycle_metrics`).  A zero crossing belongs to the
cycle whose positive peak precedes it; the virgin start at rest is not a crossing of a loop.

Per test, the *design displacement* DD and the *maximum displacement* DM: by default
DD = the largest amplitude level of the test, the largest cycle amplitude ``(d+ - d-) / 2``
(for a test without a full cycle, the largest displacement reached in both directions,
``min(max u, -min u)``, or ``max |u|`` for a one-sided push), and **DM = 1.5 DD**
(:data:`DM_FACTOR`); both can be given.
The test row's k_eff, beta_eff, EDC and Qd are the means over the cycles at the DD level (the
cycles whose amplitude is within :data:`LEVEL_TOL` of DD: the three-cycle mean of a prototype
test).  ``f_dd`` and ``f_dm`` are the forces at DD and DM on the envelope of the loops, taken as
the skeleton curve: the force at each sample where the displacement reaches a new maximum in its
direction (the outermost excursion of every level), interpolated linearly at +D and at -D; the
value is the mean of |F| of the two directions (the one reached, for a one-sided test), and NaN
where the test does not reach D (no extrapolation: with the default DM = 1.5 DD it is NaN unless
DM is given within the tested range).

Property modification factors (:func:`property_modification`)
-------------------------------------------------------------
ASCE 7-22 section 17.2.8.4 bounds each isolator property by factors ``lambda_max`` and
``lambda_min`` combining aging and environment (``lambda_ae``), testing (``lambda_test``: heating,
rate, scragging, the cycle-to-cycle and test-to-test variation) and the permitted manufacturing
variation (``lambda_spec``), eqs. 17.2-1 and 17.2-2::

    lambda_max = (1 + 0.75 (lambda_ae,max - 1)) * lambda_test,max * lambda_spec,max
    lambda_min = (1 - 0.75 (1 - lambda_ae,min)) * lambda_test,min * lambda_spec,min

(the 0.75 is the standard's adjustment for the unlikelihood of all aging and environmental
maxima occurring together; the same equations are in ASCE 7-16 and in McVitty & Constantinou
2015, MCEER-15-0005).  Here ``lambda_test`` comes from the spread over cycles and tests,
as commentary C17.2.8.4 describes it (the ratio of the first-cycle, or extreme, property to the
three-cycle mean): the nominal value of a property is the mean over the cycles at the reference
amplitude of every test (the pooled three-cycle mean), and ``lambda_test,max`` /
``lambda_test,min`` are the largest / smallest ratio of a cycle's value to it.  Identical cycles
give exactly 1; a stiffer first cycle (scragging) gives lambda_test,max > 1 > lambda_test,min.
Defaults, to be overridden with the project's own values: ``lambda_ae = (1.0, 1.0)`` (no aging
or environmental data) and ``lambda_spec = (0.85, 1.15)`` (a +-15 % manufacturing tolerance,
the commentary's usual value).  The upper- and lower-bound isolator properties are the nominal
values times ``lambda_max`` and ``lambda_min``.

Upper- and lower-bound law parameters (:func:`bound_params`)
------------------------------------------------------------
Every parameter is multiplied by ``lambda ** e``, with ``e`` the power of kN in its registry
unit (``ParamSpec.unit``; everything after the first ``/`` is denominator): stiffnesses [kN/m],
strengths [kN], viscous coefficients [kN s/m], the stiffening terms of hdr [kN/m^3] take
``lambda``; a fade rate per unit work [1/kN*m] takes ``1/lambda``; dimensionless and length
parameters are unchanged.  For every law of the table whose force is homogeneous of degree one
in its force-like parameters (all of them, and the augmented laws) the bound law's force is then
exactly ``lambda`` times the nominal one along any history, so k_eff, Qd and EDC all scale by
``lambda``: one factor per bound, chosen by :meth:`PropertyModification.law_lambdas` (by default
the envelope over the properties: the largest lambda_max and the smallest lambda_min).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from rrfrei.energy import cycle_bounds, cycle_metrics
from rrfrei.io import ShearTest
from rrfrei.laws import get as get_law

__all__ = ["DM_FACTOR", "LEVEL_TOL", "PROPERTIES", "QUANTITIES", "UNITS", "PropertyModification",
           "bound_params", "design_displacements", "design_gap", "design_quantities", "kn_power",
           "plot_design_gap", "property_modification"]

DM_FACTOR = 1.5
"""Default DM / DD (the maximum displacement as 1.5 times the design displacement)."""

LEVEL_TOL = 0.05
"""Relative tolerance on the amplitude for a cycle to belong to a level (|d - D| <= tol D)."""

QUANTITIES = ("k_eff", "beta_eff", "edc", "qd", "f_dd", "f_dm")
"""The test-level design quantities of :func:`design_gap`, in table order."""

UNITS = {"amplitude": "m", "k_eff": "kN/m", "beta_eff": "-", "edc": "kN*m", "qd": "kN",
         "f_dd": "kN", "f_dm": "kN", "dd": "m", "dm": "m"}
"""Unit of every column of :func:`design_quantities`."""

PROPERTIES = ("k_eff", "qd", "edc")
"""Isolator properties bounded by :func:`property_modification`."""

COLUMNS = ("test", "scope", "cycle", "amplitude", "at_dd", "k_eff", "beta_eff", "edc", "qd",
           "f_dd", "f_dm", "dd", "dm")


# ----------------------------------------------------------------------------- helpers
def _history(test: ShearTest, force, what: str) -> np.ndarray:
    """``force`` as a float array aligned with ``test.disp`` (``test.force`` when None)."""
    if force is None:
        return np.asarray(test.force, dtype=float)
    f = np.asarray(force, dtype=float)
    if f.shape != test.disp.shape:
        raise ValueError(
            f"{what} has shape {f.shape} but test {test.name!r} has {test.disp.size} samples: "
            "give one force [kN] per displacement sample"
        )
    if not np.all(np.isfinite(f)):
        i = int(np.flatnonzero(~np.isfinite(f))[0])
        raise ValueError(f"{what} is not finite at sample {i} (value {f[i]}) for test {test.name!r}")
    return f


def _length(name: str, value) -> float | None:
    if value is None:
        return None
    x = float(value)
    if not (math.isfinite(x) and x > 0.0):
        raise ValueError(f"{name} = {value!r} m is invalid: expected a finite displacement > 0")
    return x


def _tolerance(tol) -> float:
    x = float(tol)
    if not (math.isfinite(x) and 0.0 <= x < 1.0):
        raise ValueError(f"tol = {tol!r} is invalid: expected a relative amplitude tolerance in [0, 1)")
    return x


def design_displacements(disp, *, dd: float | None = None, dm: float | None = None,
                         eps_frac: float = 0.02) -> tuple[float, float]:
    """The design and maximum displacements ``(DD, DM)`` [m] of a test's displacement history.

    Defaults: DD = the largest cycle amplitude ``(d+ - d-) / 2`` over the full cycles
    (:func:`rrfrei.energy.cycle_bounds` with ``eps_frac``); without a full cycle, the largest
    displacement reached in both directions, ``min(max u, -min u)`` (``max |u|`` when the test
    goes one way only).  DM = :data:`DM_FACTOR` * DD.
    """
    u = np.asarray(disp, dtype=float)
    dd = _length("dd", dd)
    dm = _length("dm", dm)
    if dd is None:
        bounds = cycle_bounds(u, eps_frac=eps_frac)
        if len(bounds):
            dd = max(0.5 * (float(np.max(u[s:e + 1])) - float(np.min(u[s:e + 1]))) for s, e in bounds)
        else:
            up, down = float(np.max(u)), float(-np.min(u))
            dd = min(up, down) if min(up, down) > 0.0 else max(up, down)
        if not dd > 0.0:
            raise ValueError("the displacement history never leaves zero: DD cannot be set")
    if dm is None:
        dm = DM_FACTOR * dd
    return dd, dm


def _crossings(u: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (fractional sample index) and forces at the zero crossings of ``u``.

    A sign change between samples i and i+1 is interpolated linearly; a sample exactly at zero
    counts when its neighbours lie on opposite sides (or it closes the history after a
    non-zero sample).  A run of zeros at rest (the virgin start) is no crossing.
    """
    a, b = u[:-1], u[1:]
    i = np.flatnonzero(a * b < 0.0)
    frac = -a[i] / (b[i] - a[i])
    pos = i + frac
    force = f[i] + frac * (f[i + 1] - f[i])
    n = u.size
    z = np.flatnonzero(u == 0.0)
    z = z[z > 0]
    prev = u[z - 1]
    nxt = np.where(z < n - 1, u[np.minimum(z + 1, n - 1)], -prev)
    keep = (prev != 0.0) & (prev * nxt < 0.0)
    pos = np.concatenate([pos, z[keep].astype(float)])
    force = np.concatenate([force, f[z[keep]]])
    order = np.argsort(pos)
    return pos[order], force[order]


def _cycle_qd(u: np.ndarray, f: np.ndarray, cyc: pd.DataFrame) -> np.ndarray:
    """Mean |F| at the zero crossings of each cycle (from its positive peak to the next one)."""
    if cyc.empty:
        return np.zeros(0)
    pos, force = _crossings(u, f)
    ip = np.array([s + int(np.argmax(u[s:e + 1])) for s, e in zip(cyc["start"], cyc["end"])], dtype=float)
    stop = np.append(ip[1:], float(u.size))
    out = np.full(len(cyc), np.nan)
    for k in range(len(cyc)):
        sel = (pos > ip[k]) & (pos < stop[k])
        if sel.any():
            out[k] = float(np.mean(np.abs(force[sel])))
    return out


def _skeleton_force(u: np.ndarray, f: np.ndarray, d: float) -> float:
    """Mean |F| at +d and -d on the skeleton (new-maximum) curve; NaN where d is not reached."""
    vals = []
    for sgn in (1.0, -1.0):
        x = sgn * u
        run = np.maximum.accumulate(np.concatenate([[0.0], x]))[:-1]
        idx = np.flatnonzero((x > run) & (x > 0.0))
        if idx.size == 0 or x[idx[-1]] < d:
            continue
        xs, fs = x[idx], sgn * f[idx]
        vals.append(abs(float(np.interp(d, np.concatenate([[0.0], xs]), np.concatenate([[0.0], fs])))))
    return float(np.mean(vals)) if vals else math.nan


# ----------------------------------------------------------------------------- quantities
def design_quantities(test: ShearTest, force_pred=None, *, dd: float | None = None,
                      dm: float | None = None, eps_frac: float = 0.02,
                      tol: float = LEVEL_TOL) -> pd.DataFrame:
    """k_eff, beta_eff, EDC, Qd per cycle and per test, and the forces at DD and DM.

    Parameters
    ----------
    test : the shear test; its displacement history [m] drives everything.
    force_pred : (n,) force [kN] to analyse instead of the measured ``test.force`` (e.g. a
        law's prediction along the test's displacements), or None for the measured force.
    dd, dm : design and maximum displacement [m]; default DD = the largest amplitude level of the
        test (reached both ways), DM = 1.5 DD (see the module docstring).
    eps_frac : the cycle detection's noise band (:func:`rrfrei.energy.cycle_bounds`).
    tol : a cycle is at the DD level when ``|d - DD| <= tol DD`` (default :data:`LEVEL_TOL`;
        widen it for earthquake tests, whose cycles rarely repeat an amplitude).

    Returns
    -------
    DataFrame with columns :data:`COLUMNS`: one row per full cycle (``scope == "cycle"``,
    ``cycle`` 0-based, ``at_dd`` whether its amplitude is at the DD level) and a last row
    ``scope == "test"`` (``cycle`` -1) holding the means over the cycles at the DD level and
    ``f_dd`` / ``f_dm`` [kN]; ``dd``, ``dm`` [m] on every row.  Units: :data:`UNITS`.  A test
    without full cycles (a monotonic push) has the test row only, with NaN cycle quantities.
    """
    if not isinstance(test, ShearTest):
        raise ValueError(f"test must be a ShearTest, got {type(test).__name__}")
    u = np.asarray(test.disp, dtype=float)
    f = _history(test, force_pred, "force_pred")
    dd, dm = design_displacements(u, dd=dd, dm=dm, eps_frac=eps_frac)
    tol = _tolerance(tol)
    cyc = cycle_metrics(u, f, eps_frac=eps_frac)
    amp = 0.5 * (cyc["d_pos"].to_numpy() - cyc["d_neg"].to_numpy())
    at_dd = np.abs(amp - dd) <= tol * dd
    rows = pd.DataFrame({
        "test": test.name, "scope": "cycle", "cycle": cyc["cycle"].to_numpy(dtype=np.int64),
        "amplitude": amp, "at_dd": at_dd, "k_eff": cyc["k_eff"].to_numpy(),
        "beta_eff": cyc["beta_eff"].to_numpy(), "edc": cyc["energy"].to_numpy(),
        "qd": _cycle_qd(u, f, cyc), "f_dd": math.nan, "f_dm": math.nan, "dd": dd, "dm": dm,
    }, columns=list(COLUMNS))
    level = rows[at_dd]
    summary = {c: (float(level[c].mean()) if len(level) else math.nan)
               for c in ("amplitude", "k_eff", "beta_eff", "edc", "qd")}
    test_row = pd.DataFrame([{
        "test": test.name, "scope": "test", "cycle": -1, "at_dd": bool(len(level)), **summary,
        "f_dd": _skeleton_force(u, f, dd), "f_dm": _skeleton_force(u, f, dm), "dd": dd, "dm": dm,
    }], columns=list(COLUMNS))
    out = pd.concat([rows, test_row], ignore_index=True) if len(rows) else test_row
    return out.astype({"cycle": np.int64, "at_dd": bool})


def design_gap(test: ShearTest, measured_force=None, pred_before=None, pred_after=None, *,
               dd: float | None = None, dm: float | None = None) -> pd.DataFrame:
    """The test-level design quantities, measured and predicted before/after an effect.

    Parameters
    ----------
    test : the shear test (its displacements drive the three force histories).
    measured_force : (n,) measured force [kN]; None uses ``test.force``.
    pred_before : (n,) force [kN] of the baseline law along ``test.disp``.
    pred_after : (n,) force [kN] of the law with the effect, or None (NaN columns).
    dd, dm : as in :func:`design_quantities` (the defaults come from the displacements, so all
        three forces are read at the same DD and DM).

    Returns
    -------
    DataFrame indexed by quantity (:data:`QUANTITIES`) with columns ``unit``, ``measured``,
    ``before``, ``after`` and the relative errors ``rel_err_before`` and ``rel_err_after``,
    ``(predicted - measured) / |measured|`` [-] (NaN where the measured value is 0 or NaN).
    """
    if pred_before is None:
        raise ValueError("pred_before is required: the baseline law's force [kN] along test.disp")
    dd, dm = design_displacements(test.disp, dd=dd, dm=dm)

    def row(force, what):
        if force is None:
            return pd.Series(math.nan, index=list(QUANTITIES))
        df = design_quantities(test, _history(test, force, what), dd=dd, dm=dm)
        return df.iloc[-1][list(QUANTITIES)].astype(float)

    meas = row(_history(test, measured_force, "measured_force"), "measured_force")
    before = row(pred_before, "pred_before")
    after = row(pred_after, "pred_after")
    out = pd.DataFrame({"unit": [UNITS[q] for q in QUANTITIES], "measured": meas.to_numpy(),
                        "before": before.to_numpy(), "after": after.to_numpy()},
                       index=pd.Index(QUANTITIES, name="quantity"))
    m = out["measured"].to_numpy()
    denom = np.where(np.abs(m) > 0.0, np.abs(m), np.nan)
    for k in ("before", "after"):
        out[f"rel_err_{k}"] = (out[k].to_numpy() - m) / denom
    return out


LABELS = {"k_eff": "k_eff", "beta_eff": "beta_eff (EDC)", "edc": "EDC", "qd": "Qd",
          "f_dd": "F(DD)", "f_dm": "F(DM)"}


def plot_design_gap(gap: pd.DataFrame, *, title: str = ""):
    """Bar chart of :func:`design_gap`: the relative error [%] of each design quantity before
    and after the effect (a quantity with no value, e.g. F(DM) beyond the test, is left out).
    Returns a matplotlib ``Figure`` (not managed by pyplot; save it with ``fig.savefig``)."""
    from matplotlib.figure import Figure  # deferred: matplotlib only when a figure is drawn

    rows = gap[gap["measured"].notna()]
    fig = Figure(figsize=(6.4, 3.4), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(rows))
    ax.barh(y + 0.2, 100.0 * rows["rel_err_before"].to_numpy(), height=0.4, color="C3",
            label="before (baseline law)")
    if rows["rel_err_after"].notna().any():
        ax.barh(y - 0.2, 100.0 * rows["rel_err_after"].to_numpy(), height=0.4, color="C2",
                label="after (with the effect)")
    ax.set_yticks(y)
    ax.set_yticklabels([f"{LABELS.get(q, q)} [{rows.loc[q, 'unit']}]" for q in rows.index])
    ax.invert_yaxis()
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel("predicted - measured, relative to measured [%]")
    ax.grid(axis="x", alpha=0.3)
    fig.legend(fontsize=8, loc="outside upper center", ncols=2)
    if title:
        ax.set_title(title)
    return fig


# ----------------------------------------------------------------------------- lambdas
def _pair(name: str, value) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is invalid: expected a pair (min, max)") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= 1.0 <= hi):
        raise ValueError(f"{name} = ({lo:g}, {hi:g}) is invalid: expected 0 < min <= 1 <= max")
    return lo, hi


@dataclass(frozen=True)
class PropertyModification:
    """ASCE 7-22 section 17.2.8.4 property modification factors and bounding properties.

    Attributes
    ----------
    reference_amplitude : the amplitude [m] whose cycles were pooled (DD of the first test by
        default).
    tests : names of the tests that had cycles at that amplitude.
    n_cycles : number of pooled cycles.
    nominal : property -> nominal value (pooled three-cycle mean): ``k_eff`` [kN/m], ``qd``
        [kN], ``edc`` [kN m].
    test_max, test_min : property -> lambda_test,max / lambda_test,min (extreme cycle / nominal).
    lambda_ae, lambda_spec : the (min, max) aging/environment and specification factors used.
    lambda_max, lambda_min : property -> the combined factors (eqs. 17.2-1 and 17.2-2).
    upper, lower : property -> upper- and lower-bound values (nominal * lambda_max / lambda_min).
    """

    reference_amplitude: float
    tests: tuple[str, ...]
    n_cycles: int
    nominal: Mapping[str, float]
    test_max: Mapping[str, float]
    test_min: Mapping[str, float]
    lambda_ae: tuple[float, float]
    lambda_spec: tuple[float, float]
    lambda_max: Mapping[str, float] = field(init=False)
    lambda_min: Mapping[str, float] = field(init=False)
    upper: Mapping[str, float] = field(init=False)
    lower: Mapping[str, float] = field(init=False)

    def __post_init__(self) -> None:
        ae_lo, ae_hi = _pair("lambda_ae", self.lambda_ae)
        sp_lo, sp_hi = _pair("lambda_spec", self.lambda_spec)
        object.__setattr__(self, "lambda_ae", (ae_lo, ae_hi))
        object.__setattr__(self, "lambda_spec", (sp_lo, sp_hi))
        lmax = {p: (1.0 + 0.75 * (ae_hi - 1.0)) * self.test_max[p] * sp_hi for p in self.nominal}
        lmin = {p: (1.0 - 0.75 * (1.0 - ae_lo)) * self.test_min[p] * sp_lo for p in self.nominal}
        object.__setattr__(self, "lambda_max", lmax)
        object.__setattr__(self, "lambda_min", lmin)
        object.__setattr__(self, "upper", {p: self.nominal[p] * lmax[p] for p in self.nominal})
        object.__setattr__(self, "lower", {p: self.nominal[p] * lmin[p] for p in self.nominal})

    def table(self) -> pd.DataFrame:
        """One row per property: unit, nominal, lambda_test min/max, lambda_min/max, lower, upper."""
        props = list(self.nominal)
        return pd.DataFrame({
            "unit": [UNITS[p] for p in props], "nominal": [self.nominal[p] for p in props],
            "lambda_test_min": [self.test_min[p] for p in props],
            "lambda_test_max": [self.test_max[p] for p in props],
            "lambda_min": [self.lambda_min[p] for p in props],
            "lambda_max": [self.lambda_max[p] for p in props],
            "lower": [self.lower[p] for p in props], "upper": [self.upper[p] for p in props],
        }, index=pd.Index(props, name="property"))

    def to_dict(self) -> dict:
        """Plain JSON-ready values (floats, lists, dicts)."""
        return {
            "reference_amplitude_m": self.reference_amplitude, "tests": list(self.tests),
            "n_cycles": self.n_cycles, "lambda_ae": list(self.lambda_ae),
            "lambda_spec": list(self.lambda_spec), "units": {p: UNITS[p] for p in self.nominal},
            **{k: dict(getattr(self, k)) for k in ("nominal", "test_min", "test_max", "lambda_min",
                                                   "lambda_max", "lower", "upper")},
        }

    def law_lambdas(self, prop: str = "envelope") -> tuple[float, float]:
        """``(lambda_lower, lambda_upper)`` for scaling a law (:func:`bound_params`).

        ``prop`` names one property (``k_eff``, ``qd``, ``edc``) or ``"envelope"`` (default): the
        smallest lambda_min and the largest lambda_max over the properties, so the bound laws
        bracket every property.
        """
        if prop == "envelope":
            return min(self.lambda_min.values()), max(self.lambda_max.values())
        if prop not in self.nominal:
            raise ValueError(
                f"prop = {prop!r} is unknown; expected 'envelope' or one of {tuple(self.nominal)}"
            )
        return self.lambda_min[prop], self.lambda_max[prop]

    def law_bounds(self, law, params: Mapping[str, float],
                   prop: str = "envelope") -> dict[str, dict[str, float]]:
        """``{"nominal", "upper", "lower"}`` parameter sets of ``law`` (:func:`bound_params`)."""
        lo, hi = self.law_lambdas(prop)
        spec = get_law(law)
        return {"nominal": spec.as_dict(spec.pack(params)), "upper": bound_params(law, params, hi),
                "lower": bound_params(law, params, lo)}


def property_modification(tests: ShearTest | Sequence[ShearTest], forces=None, *,
                          amplitude: float | None = None,
                          lambda_ae: tuple[float, float] = (1.0, 1.0),
                          lambda_spec: tuple[float, float] = (0.85, 1.15),
                          tol: float = LEVEL_TOL) -> PropertyModification:
    """Property modification factors from the spread of k_eff, Qd and EDC over cycles and tests.

    Parameters
    ----------
    tests : one test or several (e.g. the calibration test and the held-out ones).
    forces : None (the measured forces), or one (n,) force history [kN] per test, e.g. the
        prediction of the law with the named effect along each test's displacements.
    amplitude : reference amplitude [m] whose cycles are pooled (``|d - amplitude| <= tol
        amplitude``); default: DD of the first test (its largest amplitude level).  Tests
        without cycles at that amplitude do not contribute.
    lambda_ae : (min, max) aging and environmental factors; default (1.0, 1.0): no data.
    lambda_spec : (min, max) specification tolerance; default (0.85, 1.15).
    tol : relative amplitude tolerance of the pool (default :data:`LEVEL_TOL`).

    Returns
    -------
    :class:`PropertyModification` (formulas in the module docstring).
    """
    tests = [tests] if isinstance(tests, ShearTest) else list(tests)
    if not tests or not all(isinstance(t, ShearTest) for t in tests):
        raise ValueError("tests must be a ShearTest or a non-empty sequence of ShearTest")
    if forces is None:
        forces = [None] * len(tests)
    forces = list(forces)
    if len(forces) != len(tests):
        raise ValueError(f"forces has {len(forces)} histories for {len(tests)} tests: give one per test")
    ref = _length("amplitude", amplitude)
    if ref is None:
        ref = design_displacements(tests[0].disp)[0]
    pooled, used, seen = [], [], []
    for t, f in zip(tests, forces):
        df = design_quantities(t, f, dd=ref, tol=tol)
        cyc = df[(df["scope"] == "cycle")]
        seen += [f"{a:.4g}" for a in cyc["amplitude"]]
        cyc = cyc[cyc["at_dd"]]
        if len(cyc):
            pooled.append(cyc)
            used.append(t.name)
    if not pooled:
        raise ValueError(
            f"no cycle of the tests has the reference amplitude {ref:.4g} m (+-{tol:.0%}); "
            f"cycle amplitudes found [m]: {', '.join(dict.fromkeys(seen)) or 'none (no full cycle)'}"
        )
    pool = pd.concat(pooled, ignore_index=True)
    nominal, tmax, tmin = {}, {}, {}
    for p in PROPERTIES:
        v = pool[p].to_numpy(dtype=float)
        v = v[np.isfinite(v)]
        if v.size == 0 or not np.mean(v) > 0.0:
            raise ValueError(f"property {p} has no positive value at the reference amplitude {ref:.4g} m")
        nominal[p] = float(np.mean(v))
        tmax[p] = float(np.max(v)) / nominal[p]
        tmin[p] = float(np.min(v)) / nominal[p]
    return PropertyModification(ref, tuple(used), len(pool), nominal, tmax, tmin, lambda_ae, lambda_spec)


# ----------------------------------------------------------------------------- bound laws
_FACTOR = re.compile(r"^\s*([A-Za-z]+)(?:\^(-?\d+))?\s*$")


def kn_power(unit: str) -> int:
    """The power of kN in a registry unit string: ``"kN/m"`` -> 1, ``"1/kN*m"`` -> -1, ``"-"`` -> 0.

    Factors are separated by ``*`` and ``/``; everything after the first ``/`` is denominator
    (the registry writes 1/(kN m) as ``1/kN*m``); ``kN^2`` counts 2.
    """
    num, _, den = str(unit).partition("/")
    power = 0
    for part, sign in ((num, 1), (den, -1)):
        for factor in part.split("*") if part else ():
            m = _FACTOR.match(factor.replace("/", ""))
            if m and m.group(1) == "kN":
                power += sign * int(m.group(2) or 1)
    return power


def bound_params(law, params: Mapping[str, float], lam: float) -> dict[str, float]:
    """``params`` of ``law`` with every parameter scaled by ``lam ** kn_power(unit)``.

    Force-like parameters (stiffness, strength, viscous coefficients: kN in the numerator) are
    multiplied by ``lam``, inverse ones (kN in the denominator) divided by it, the others kept;
    the rule is read from the law table (``rrfrei.laws.get(law).params``), so it holds for any
    registered law and any augmented law ``base+effect``.  A parameter at its upper bound (a
    sentinel such as slip's ``slip_force = 1e12``, "never slips") stays there.  Returns the
    complete validated set.
    """
    lam = float(lam)
    if not (math.isfinite(lam) and lam > 0.0):
        raise ValueError(f"lambda = {lam!r} is invalid: expected a finite factor > 0")
    spec = get_law(law)
    base = spec.as_dict(spec.pack(params))
    out = {p.name: base[p.name] if base[p.name] == p.upper else base[p.name] * lam ** kn_power(p.unit)
           for p in spec.params}
    return spec.as_dict(spec.pack(out))
