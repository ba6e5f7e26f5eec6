"""The code's answers for a plan building under pairs of records (ASCE 7-22 Chapter 17).

ASCE 7-22 Chapter 17 (seismically isolated structures), response-history procedure (section
17.6): pairs of horizontal ground-motion components are applied simultaneously to the model, the
isolation-system displacement is the vector sum of the two orthogonal displacements at each time
step, and each response parameter of interest is computed per pair and combined over the suite
(:func:`ground_motions.asce7.design_value`: the average for 7 or more pairs, the maximum for fewer).
The analyses are run for the upper- and the lower-bound isolator properties (section 17.2.8.4,
property modification factors, eqs. 17.2-1 and 17.2-2) and the design takes the larger of the two.
What was verified and what was not (section numbers, torsion, default lambda factors) is listed in
``docs/asce7_bidirectional.md``.

Per pair (one analysis of the plan building, :func:`structures.plan_time_history`)::

    D_plan      = max_t sqrt(u_x(t)^2 + u_y(t)^2)     maximum plan isolator displacement [m]
    D_x, D_y    = max_t |u_x(t)|, max_t |u_y(t)|       per direction [m] (each <= D_plan)
    D_total     = D_plan * f_torsion                   total maximum displacement [m]
    V_x, V_y    = max_t |V_x(t)|, max_t |V_y(t)|       base shear per direction [kN]

with ``u`` the isolator displacement at the centre of the base slab (prototype, m) and ``V`` the
shear in the first story (above the isolators).  The plan building has no torsion (a lumped mass
per floor, no eccentricity), so every bearing has the centre's displacement and, by default,
``f_torsion = 1``: **the total maximum displacement equals the plan displacement at the centre,
torsion is not included**.  With a :class:`TorsionAmplification` (plan dimensions and
eccentricity given by the user) ``f_torsion`` is the static amplification of a corner bearing
(ASCE 7-16 eq. 17.5-3 form; see the class), applied to the response-history displacement.

Over the suite, per bound (nominal, lower, upper)::

    design value = mean over the pairs    (7 or more pairs)
                 = max over the pairs     (fewer than 7)

and the governing value is the largest over the lower- and upper-bound analyses (and the nominal
one: the response to a record need not be monotone in the isolator properties).

Units: m, s, kN, tonnes; accelerations m/s^2.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import ground_motions
from ground_motions.asce7 import design_value
from rrfrei.gap.design import bound_params
from rrfrei.laws import get as get_law
from rrfrei.laws import plan as plan_laws
from structures.dynamics.plan_history import plan_time_history
from structures.propagation.inputs import resolve_building

__all__ = ["ANSWERS", "DEFAULT_LAMBDAS", "PlanDesignAnswers", "TorsionAmplification", "check_plan_law",
           "pair_answers", "plan_arrays", "plan_design_answers", "plot_orbit", "resolve_pairs",
           "suite_rule", "suite_value", "torsion_factor"]

ANSWERS = ("plan_disp_max_m", "disp_x_max_m", "disp_y_max_m", "total_max_disp_m",
           "base_shear_x_max_kN", "base_shear_y_max_kN")
"""The per-pair answers, in table order (units in the names)."""

DEFAULT_LAMBDAS = (0.85, 1.15)
"""Default (lambda_min, lambda_max) of the bounding analyses: eqs. 17.2-1 and 17.2-2 with no aging
or environmental data (lambda_ae = 1), no test spread (lambda_test = 1) and the +-15 %
specification tolerance (lambda_spec = 0.85, 1.15) that :func:`rrfrei.gap.design.property_modification`
also defaults to.  ASCE 7-22 itself gives no numbers for a specific product here (default
lambda values are in the commentary and in McVitty & Constantinou 2015, MCEER-15-0005): pass
the project's own factors, or a :class:`rrfrei.gap.design.PropertyModification` from the tests."""

BOUNDS = ("nominal", "lower", "upper")


# ----------------------------------------------------------------------------- torsion
@dataclass(frozen=True)
class TorsionAmplification:
    """Static torsional amplification of the displacement of a bearing away from the centre.

    ``factor = 1 + (y / P_T^2) * 12 e / (b^2 + d^2)``: the equivalent-lateral-force expression of
    the total maximum displacement D_TM from D_M as we know it from ASCE 7-16 (eq. 17.5-3; the
    expression Hassan 2019, Int. J. Civil Eng., "Assessment of ASCE 7-16 seismic isolation bearing
    torsional displacement", assesses).  The formula, its ASCE 7-22 number and any lower limit on
    D_TM / D_M were not verified against the standard's text; no such limit is applied.  The plan
    building itself has no torsion; this factor is applied to its response-history plan
    displacement to estimate the corner bearing.

    Attributes
    ----------
    y : distance [m] from the centre of rigidity of the isolation system to the bearing,
        perpendicular to the direction of loading (e.g. half the plan dimension for a corner).
    b, d : the shortest and longest plan dimensions of the structure [m].
    e : eccentricity [m]: the actual eccentricity plus the accidental one (5 % of the longest
        plan dimension perpendicular to the loading).
    p_t : ratio of the effective translational period to the effective torsional period of the
        isolation system [-] (1.0 when not computed).
    """

    y: float
    b: float
    d: float
    e: float
    p_t: float = 1.0

    def __post_init__(self) -> None:
        for name in ("y", "e"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"torsion.{name} = {getattr(self, name)!r} m is invalid: expected a "
                                 "finite distance >= 0")
            object.__setattr__(self, name, v)
        for name in ("b", "d", "p_t"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0.0):
                unit = "" if name == "p_t" else " m"
                raise ValueError(f"torsion.{name} = {getattr(self, name)!r}{unit} is invalid: expected "
                                 "a finite number > 0")
            object.__setattr__(self, name, v)

    @property
    def factor(self) -> float:
        """``1 + (y / P_T^2) * 12 e / (b^2 + d^2)`` [-] (>= 1)."""
        return 1.0 + self.y / self.p_t ** 2 * 12.0 * self.e / (self.b ** 2 + self.d ** 2)


def torsion_factor(torsion: TorsionAmplification | None) -> float:
    """The amplification of ``torsion`` [-], 1 when None (no torsion)."""
    if torsion is None:
        return 1.0
    if not isinstance(torsion, TorsionAmplification):
        raise ValueError(f"torsion must be a TorsionAmplification or None, got {type(torsion).__name__}")
    return torsion.factor


# ----------------------------------------------------------------------------- inputs
def check_plan_law(law) -> str:
    """The law's name if it has a coupled plan form; else ValueError listing the laws that do."""
    return plan_laws.get(get_law(law).name).name


def _is_pair(obj) -> bool:
    acc = getattr(obj, "accel", None)
    return acc is not None and hasattr(obj, "dt") and np.ndim(acc) == 2 and np.shape(acc)[1] == 2


def _one_pair(item):
    if _is_pair(item):
        return item
    if isinstance(item, ground_motions.Record):
        raise ValueError(
            f"record {item.name!r} has one component: the bidirectional analysis needs pairs of "
            "horizontal components (a bundled pair name, or two files joined by '+')"
        )
    if not isinstance(item, (str, os.PathLike)):
        raise ValueError(f"a record pair must be a name, 'A+B' file paths or a RecordPair, got "
                         f"{type(item).__name__}")
    text = str(item).strip()
    if "+" in text:
        a, _, b = text.partition("+")
        if not a.strip() or not b.strip():
            raise ValueError(f"record pair {text!r}: expected two files joined by '+' (A.AT2+B.AT2)")
        return ground_motions.read_pair(a.strip(), b.strip())
    if os.sep in text or Path(text).suffix or Path(text).exists():
        raise ValueError(
            f"record {text!r} is one file, i.e. one component: give both horizontal components as "
            f"'{text}+OTHER_COMPONENT' (two files joined by '+')"
        )
    if text in ground_motions.available() and text not in ground_motions.available_pairs():
        raise ValueError(
            f"bundled record {text!r} has one horizontal component; bundled records with both: "
            f"{', '.join(ground_motions.available_pairs())} (or give two files joined by '+')"
        )
    return ground_motions.load_pair(text)


def resolve_pairs(pairs) -> list:
    """Record pairs from bundled pair names, ``"A.AT2+B.AT2"`` file pairs or pair objects.

    A pair object has ``name``, ``dt`` [s] and ``accel`` (n, 2) [m/s^2] (and ``scaled(f)`` for
    scales other than 1).  A single-component record or file is refused (ValueError saying how
    to give both components); names must be unique (they key the table).
    """
    if isinstance(pairs, (str, os.PathLike)) or _is_pair(pairs) or isinstance(pairs, ground_motions.Record):
        pairs = [pairs]
    out = [_one_pair(p) for p in pairs]
    if not out:
        raise ValueError("records is empty: give at least one record pair")
    names = [str(r.name) for r in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"record pair names must be unique (they key the table); repeated: {', '.join(dup)}")
    return out


# ----------------------------------------------------------------------------- one pair
def _two(name: str, a) -> np.ndarray:
    x = np.asarray(a, dtype=float)
    if x.ndim != 2 or x.shape[1] != 2 or x.shape[0] < 1:
        raise ValueError(f"{name} must be an (n, 2) array (x, y columns), got shape {x.shape}")
    return x


def _xy(resp, name: str) -> np.ndarray | None:
    """``name`` of a plan response as (n, ..., 2): ``name`` with a last axis of 2, the pair
    ``name_x`` / ``name_y``, or the per-direction responses' ``x.name`` / ``y.name``, stacked on a
    last axis (None when the response has none of them)."""
    if hasattr(resp, name):
        a = np.asarray(getattr(resp, name), dtype=float)
        if a.ndim >= 2 and a.shape[-1] == 2:
            return a
    for x, y in ((f"{name}_x", f"{name}_y"), ("x", "y")):
        if hasattr(resp, x) and hasattr(resp, y):
            ax, ay = getattr(resp, x), getattr(resp, y)
            if x == "x":
                if not (hasattr(ax, name) and hasattr(ay, name)):
                    continue
                ax, ay = getattr(ax, name), getattr(ay, name)
            return np.stack([np.asarray(ax, dtype=float), np.asarray(ay, dtype=float)], axis=-1)
    return None


def plan_arrays(response) -> dict[str, np.ndarray]:
    """The histories the answers need from a plan response (duck-typed).

    Reads the isolator displacement and the base shear as (n, 2) arrays (x, y) [m], [kN]:
    attributes ``isolator_disp`` / ``base_shear`` with a last axis of 2, or ``..._x`` / ``..._y``,
    or the per-direction responses ``x`` and ``y`` of a :class:`structures.PlanResponse`; also,
    when present, ``drift_ratio`` and ``floor_accel_abs`` per direction (n, stories, 2), the
    isolator work ``energy["isolator"]`` [kN m] and ``energy_error``.
    """
    disp = _xy(response, "isolator_disp")
    shear = _xy(response, "base_shear")
    if disp is None or shear is None:
        raise ValueError(
            f"{type(response).__name__} has no (n, 2) isolator_disp / base_shear (nor _x / _y or "
            "x / y per-direction responses): not a plan response"
        )
    out = {"isolator_disp": _two("isolator_disp", disp), "base_shear": _two("base_shear", shear)}
    for name in ("drift_ratio", "floor_accel_abs"):
        a = _xy(response, name)
        if a is not None:
            out[name] = a.reshape(a.shape[0], -1, 2)
    energy = getattr(response, "energy", None)
    if isinstance(energy, Mapping) and "isolator" in energy:
        out["iso_energy"] = np.asarray(energy["isolator"], dtype=float)
    if hasattr(response, "energy_error"):
        out["energy_error"] = np.asarray(float(response.energy_error))
    return out


def pair_answers(isolator_disp, base_shear, *, torsion: TorsionAmplification | None = None
                 ) -> dict[str, float]:
    """The code's answers of one analysis (see the module docstring for the formulas).

    Parameters
    ----------
    isolator_disp : (n, 2) isolator displacement history (x, y) at the centre [m].
    base_shear : (n, 2) base shear history (x, y) [kN].
    torsion : optional corner-bearing amplification; None: not included (factor 1).

    Returns
    -------
    dict of :data:`ANSWERS` [m, kN].
    """
    u = _two("isolator_disp", isolator_disp)
    v = _two("base_shear", base_shear)
    plan = float(np.max(np.hypot(u[:, 0], u[:, 1])))
    return {
        "plan_disp_max_m": plan,
        "disp_x_max_m": float(np.max(np.abs(u[:, 0]))),
        "disp_y_max_m": float(np.max(np.abs(u[:, 1]))),
        "total_max_disp_m": plan * torsion_factor(torsion),
        "base_shear_x_max_kN": float(np.max(np.abs(v[:, 0]))),
        "base_shear_y_max_kN": float(np.max(np.abs(v[:, 1]))),
    }


# ----------------------------------------------------------------------------- the suite
def suite_rule(n_pairs: int) -> str:
    """``"average"`` for 7 or more pairs, ``"maximum"`` for fewer (see :func:`suite_value`)."""
    return "average" if int(n_pairs) >= 7 else "maximum"


def suite_value(values: Sequence[float]) -> float:
    """The design value of one answer over the suite of pairs (one value per pair).

    :func:`ground_motions.asce7.design_value` (the average for 7 or more pairs, the maximum for
    fewer); NaN when a pair has no value (an analysis that did not converge).
    """
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        raise ValueError("values is empty: give one value per pair of the suite")
    if not np.all(np.isfinite(x)):
        return math.nan
    return float(design_value(x, x.size))


# ----------------------------------------------------------------------------- the answers
@dataclass(frozen=True, eq=False)
class PlanDesignAnswers:
    """The code's answers of a plan building under a suite of record pairs, per bound.

    Attributes
    ----------
    law, building : the isolator law and the building's name.
    pairs : names of the record pairs, in suite order.
    per_pair : one row per (bound, pair): ``bound`` (nominal, lower, upper), ``lambda`` (the
        property modification factor of the bound), ``pair``, then :data:`ANSWERS`.
    lambdas : bound -> lambda (nominal 1).
    rule : ``"average"`` (7 or more pairs) or ``"maximum"`` (fewer).
    torsion : the torsional amplification applied to ``total_max_disp_m`` (None: not included).
    orbits : (bound, pair) -> (n, 2) isolator displacement history [m] (for orbit plots).
    notes : what the numbers include and leave out.
    """

    law: str
    building: str
    pairs: tuple[str, ...]
    per_pair: pd.DataFrame
    lambdas: Mapping[str, float]
    rule: str
    torsion: TorsionAmplification | None = None
    orbits: Mapping[tuple[str, str], np.ndarray] = field(default_factory=dict, repr=False)
    notes: tuple[str, ...] = ()

    def design(self) -> pd.DataFrame:
        """Design values over the suite per bound, and ``governing`` = the largest over every
        analysis run (the code asks for the lower- and upper-bound ones; the nominal one is kept in
        the maximum because a record's response need not be monotone in the isolator properties:
        the nominal isolator can move more than both bounds)."""
        rows = {}
        for b in [b for b in BOUNDS if b in set(self.per_pair["bound"])]:
            g = self.per_pair[self.per_pair["bound"] == b]
            rows[b] = {a: suite_value(g[a].to_numpy(float)) for a in ANSWERS}
        rows["governing"] = {a: float(max(rows[b][a] for b in rows)) for a in ANSWERS}
        out = pd.DataFrame.from_dict(rows, orient="index")[list(ANSWERS)]
        out.index.name = "bound"
        return out

    @property
    def design_displacement(self) -> float:
        """The governing total maximum displacement [m] (the orbit plots' circle)."""
        return float(self.design().loc["governing", "total_max_disp_m"])

    def table(self) -> pd.DataFrame:
        """The per-pair rows followed by one design row per bound (``pair`` names the rule:
        ``"design (average of 7)"`` or ``"design (maximum of 3)"``) and the governing row."""
        des = self.design().reset_index()
        des["lambda"] = [self.lambdas.get(b, math.nan) for b in des["bound"]]
        des["pair"] = f"design ({self.rule} of {len(self.pairs)})"
        cols = ["bound", "lambda", "pair", *ANSWERS]
        return pd.concat([self.per_pair[cols], des[cols]], ignore_index=True)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values."""
        des = self.design()
        return {
            "law": self.law, "building": self.building, "pairs": list(self.pairs),
            "rule": self.rule, "lambdas": dict(self.lambdas),
            "torsion": None if self.torsion is None else {
                "y_m": self.torsion.y, "b_m": self.torsion.b, "d_m": self.torsion.d,
                "e_m": self.torsion.e, "p_t": self.torsion.p_t, "factor": self.torsion.factor},
            "per_pair": self.per_pair.to_dict(orient="records"),
            "design": {b: {a: float(des.loc[b, a]) for a in ANSWERS} for b in des.index},
            "design_displacement_m": self.design_displacement,
            "notes": list(self.notes),
        }


def _lambdas(bounds) -> dict[str, float]:
    if bounds is None:
        return {"nominal": 1.0}
    if hasattr(bounds, "law_lambdas"):  # rrfrei.gap.design.PropertyModification
        lo, hi = bounds.law_lambdas()
    else:
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise ValueError(f"bounds = {bounds!r} is invalid: expected (lambda_min, lambda_max), a "
                             "PropertyModification or None") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= 1.0 <= hi):
        raise ValueError(f"bounds = ({lo:g}, {hi:g}) is invalid: expected 0 < lambda_min <= 1 <= lambda_max")
    return {"nominal": 1.0, "lower": float(lo), "upper": float(hi)}


def plan_design_answers(
    building,
    pairs,
    *,
    params: Mapping[str, float] | None = None,
    bounds=DEFAULT_LAMBDAS,
    torsion: TorsionAmplification | None = None,
    scale: float = 1.0,
    simulate: Callable | None = None,
) -> PlanDesignAnswers:
    """Run the plan building on every pair for the nominal, lower- and upper-bound isolator.

    Parameters
    ----------
    building : a :class:`structures.ShearBuilding` (or example name / TOML path) whose isolator
        law has a coupled plan form (:func:`rrfrei.laws.plan.names`).
    pairs : record pairs (objects with ``name``, ``dt``, ``accel`` (n, 2) [m/s^2] and
        ``scaled(f)``), bundled pair names or ``"A.AT2+B.AT2"`` file pairs
        (:func:`structures.propagation.plan_propagate.resolve_pairs`).
    params : isolator parameters by name (specimen scale); default: the building's own.
    bounds : (lambda_min, lambda_max), a :class:`rrfrei.gap.design.PropertyModification`
        (its envelope lambdas), or None for the nominal analysis only.  Every force-like
        parameter is scaled by :func:`rrfrei.gap.design.bound_params`.
    torsion : the corner-bearing amplification of ``total_max_disp_m`` (None: not included).
    scale : one amplitude factor applied to both components of every pair.
    simulate : ``simulate(building, law, params, pair) -> plan response``; default
        :func:`structures.plan_time_history`.

    Returns
    -------
    :class:`PlanDesignAnswers`
    """
    bld = resolve_building(building)
    recs = resolve_pairs(pairs)
    law = check_plan_law(bld.isolator.law)
    spec = get_law(law)
    if params is None:
        if bld.isolator.params is None:
            raise ValueError("the building's isolator has no parameters: pass params=")
        params = bld.isolator.params
    nominal = spec.as_dict(spec.pack(params))
    s = float(scale)
    if not (math.isfinite(s) and s > 0.0):
        raise ValueError(f"scale = {scale!r} is invalid: expected a finite factor > 0")
    lam = _lambdas(bounds)
    factor = torsion_factor(torsion)
    run = simulate or plan_time_history
    rows, orbits = [], {}
    for b, lm in lam.items():
        p = nominal if b == "nominal" else bound_params(law, nominal, lm)
        for r in recs:
            ground = r if s == 1.0 else r.scaled(s)
            arr = plan_arrays(run(bld, law, p, ground))
            rows.append({"bound": b, "lambda": lm, "pair": r.name,
                         **pair_answers(arr["isolator_disp"], arr["base_shear"], torsion=torsion)})
            orbits[(b, r.name)] = arr["isolator_disp"]
    notes = ["no torsion in the model: the total maximum displacement is the plan displacement at "
             "the centre" if torsion is None else
             f"total maximum displacement = plan displacement x {factor:.4g} (torsional amplification "
             "of a corner bearing, applied to the response-history result)"]
    if len(recs) < 7:
        notes.append(f"{len(recs)} pairs: fewer than the 7 the code asks for; the design value is the "
                     "maximum over the pairs")
    if "lower" not in lam:
        notes.append("nominal properties only: no upper- and lower-bound analyses")
    return PlanDesignAnswers(
        law=law, building=str(getattr(bld, "name", "") or ""), pairs=tuple(r.name for r in recs),
        per_pair=pd.DataFrame(rows, columns=["bound", "lambda", "pair", *ANSWERS]), lambdas=lam,
        rule=suite_rule(len(recs)), torsion=torsion, orbits=orbits, notes=tuple(notes),
    )


# ----------------------------------------------------------------------------- orbit plot
def plot_orbit(isolator_disp, radius: float | None = None, *, title: str = "",
               others: Mapping[str, np.ndarray] | None = None, ax=None):
    """Isolator orbit: y against x displacement [m] with a circle of ``radius`` [m].

    ``isolator_disp`` is the (n, 2) history at the centre; ``others`` adds more orbits by label
    (e.g. the bound analyses); ``radius`` is typically the design displacement
    (:attr:`PlanDesignAnswers.design_displacement`).  Returns a matplotlib ``Figure`` (not
    managed by pyplot; save it with ``fig.savefig``), or draws on ``ax`` and returns its figure.
    """
    from matplotlib.figure import Figure  # deferred: matplotlib only when a figure is drawn

    u = _two("isolator_disp", isolator_disp)
    if ax is None:
        fig = Figure(figsize=(5.2, 5.0), layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    ax.plot(u[:, 0], u[:, 1], lw=0.8, color="C0", label="nominal" if others else "isolator (centre)")
    for color, (lab, o) in zip(("C2", "C1", "C4", "C5", "C6"), (others or {}).items()):
        o = _two(lab, o)
        ax.plot(o[:, 0], o[:, 1], lw=0.6, color=color, alpha=0.7, label=lab)
    k = int(np.argmax(np.hypot(u[:, 0], u[:, 1])))
    ax.plot([0.0, u[k, 0]], [0.0, u[k, 1]], color="C0", lw=1.0, ls=":")
    ax.plot(u[k, 0], u[k, 1], "o", color="C0", ms=4,
            label=f"max plan displacement {1e3 * float(np.hypot(*u[k])):.0f} mm")
    if radius is not None and math.isfinite(float(radius)) and float(radius) > 0.0:
        t = np.linspace(0.0, 2.0 * math.pi, 241)
        r = float(radius)
        ax.plot(r * np.cos(t), r * np.sin(t), color="C3", lw=1.4, ls="--",
                label=f"design displacement {1e3 * r:.0f} mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("isolator displacement x [m]")
    ax.set_ylabel("isolator displacement y [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    if title:
        ax.set_title(title)
    return fig
