"""The shake-table building simulated through its runs (issue 27): the superstructure, the runs
driven one after the other, and the simulation of every channel a sensor measured.

The model is the *building*: the identified superstructure (story masses, stiffness, damping), the
isolation layer's law (possibly augmented by catalogue effects) and optional system effects, driven
by each run's measured table acceleration, the runs one after the other in chronological order
(``pad_s`` seconds of rest between them) so the isolators' state is carried from run to run.  What
is compared is what the sensors measured: the isolator displacement d_0 [m] (relative to the
table, from the start of each run), the isolation-layer force F = -sum_i m_i a_i [kN] and the roof
absolute acceleration [m/s^2] (:data:`FIT_CHANNELS`).  The story-1 shear [kN] is predicted and
reported too.

Every simulation has the robust local solve: where OpenSees' local iteration of the law fails
even at the last subdivision of a step, the law's bracketed, safeguarded Newton solves it (a
deviation from OpenSees, counted in :attr:`BuildingFit.robust_sims` and the fit's note).  A
simulation that fails even so is a bad point of the optimiser (a large constant residual) and a
dropped draw of the posterior, never an exception; the count is reported in the fit's note.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rrfrei.errors import NUMERICAL_ERRORS
from rrfrei.io import ShearTest, concat_tests
from rrfrei.laws import LawSpec
from structures.dynamics.history import kernel, solver_settings
from structures.dynamics.newmark_records import Chain, Histories, Layer
from structures.shake_table import ShakeTableRun, isolation_test

__all__ = ["FIT_CHANNELS", "REPORT_CHANNELS", "BuildingData", "Superstructure", "calibration_test",
           "concatenate_runs", "measured_channels", "simulate"]

FIT_CHANNELS = ("isolator_disp", "isolator_force", "roof_accel")
"""The channels the output error compares (isolator displacement [m], isolation-layer force
[kN], roof absolute acceleration [m/s^2])."""
REPORT_CHANNELS = ("isolator_disp", "isolator_force", "base_shear", "roof_accel")
"""The channels predicted and reported (the fitted ones and the story-1 shear [kN])."""


def concatenate_runs(runs: Sequence[ShakeTableRun], pad_s: float,
                     dt: float) -> tuple[np.ndarray, dict[str, slice]]:
    """The runs' table accelerations [m/s^2] one after the other, ``pad_s`` [s] of rest between
    two, and each run's slice of the result (the runs share the sample interval ``dt`` [s])."""
    npad = int(round(pad_s / dt))
    parts: list[np.ndarray] = []
    slices: dict[str, slice] = {}
    i0 = 0
    for r in runs:
        if parts:
            parts.append(np.zeros(npad))
            i0 += npad
        a = np.asarray(r.table_accel, dtype=float)
        parts.append(a)
        slices[r.name] = slice(i0, i0 + a.size)
        i0 += a.size
    return np.concatenate(parts), slices


def measured_channels(run: ShakeTableRun) -> dict[str, np.ndarray]:
    """The :data:`REPORT_CHANNELS` of ``run`` as measured."""
    return {"isolator_disp": np.asarray(run.isolator_disp, dtype=float),
            "isolator_force": np.asarray(run.isolator_force, dtype=float),
            "base_shear": np.asarray(run.story_shear()[:, 0], dtype=float),
            "roof_accel": np.asarray(run.accel[:, -1], dtype=float)}


@dataclass(frozen=True, eq=False)
class Superstructure:
    """The building above the isolators: masses [t] (base slab first), story stiffness [kN/m]
    (story 1 first), damping ratio zeta (stiffness-proportional), story heights [m], and where it
    comes from."""

    masses: np.ndarray
    stiffness: np.ndarray
    zeta: float
    heights: np.ndarray
    source: str = ""

    @classmethod
    def of(cls, sup, source: str = "") -> Superstructure:
        """From a :class:`structures.shake_table.identify.SuperstructureIdentification` or a
        :class:`structures.ShearBuilding`."""
        from structures.building.shear_building import ShearBuilding

        if isinstance(sup, Superstructure):
            return sup
        if isinstance(sup, ShearBuilding):
            return cls(np.concatenate([[sup.base_mass], sup.story_masses]),
                       np.asarray(sup.story_stiffness, float),
                       float(sup.damping_ratio), np.asarray(sup.story_heights, float), source or sup.name)
        b = sup.building(_placeholder_isolator())
        return cls(np.asarray(sup.masses, float), np.asarray(sup.stiffness, float), float(b.damping_ratio),
                   np.asarray(b.story_heights, float), source or f"identified from {sup.run}")

    def omega1(self, k: np.ndarray) -> float:
        """First fixed-base circular frequency [rad/s] with story stiffness ``k``."""
        K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
        return float(math.sqrt(scipy.linalg.eigh(K, np.diag(self.masses[1:]), eigvals_only=True)[0]))


def _placeholder_isolator():
    from structures.building.shear_building import Isolator

    return Isolator("plasticity", {"k_init": 1.0, "qd": 0.0, "alpha1": 0.5, "alpha2": 0.0, "mu": 2.0})


@dataclass(frozen=True, eq=False)
class BuildingData:
    """Runs driven one after the other (chronological order) and the ones that are observed.

    ``runs``: every run simulated, in order (the state they leave is carried into the next);
    ``observed``: names of the runs whose channels are compared (by default all).  A held-out run
    is ``BuildingData(all runs up to it, observed=(it,))``.
    """

    runs: tuple[ShakeTableRun, ...]
    observed: tuple[str, ...] = ()
    pad_s: float = 10.0

    def __post_init__(self) -> None:
        runs = tuple(self.runs)
        if not runs:
            raise ValueError("BuildingData needs at least one run")
        names = [r.name for r in runs]
        obs = tuple(self.observed) or tuple(names)
        for o in obs:
            if o not in names:
                raise ValueError(f"observed run {o!r} is not among the runs ({', '.join(names)})")
        dt = runs[0].dt
        for r in runs[1:]:
            if abs(r.dt - dt) > 1e-9 * dt:
                raise ValueError(f"runs {runs[0].name!r} ({1 / dt:g} Hz) and {r.name!r} ({r.rate_hz:g} Hz) "
                                 "have different sampling rates; give runs at one rate")
        # simulate only up to the last observed run
        last = max(names.index(o) for o in obs)
        object.__setattr__(self, "runs", runs[: last + 1])
        object.__setattr__(self, "observed", tuple(n for n in names if n in obs))
        acc, slices = concatenate_runs(self.runs, self.pad_s, dt)
        # the record starts at rest: one leading zero sample, every slice shifted by it
        object.__setattr__(self, "_ag", np.concatenate([[0.0], acc]))
        object.__setattr__(self, "_slices", {k: slice(v.start + 1, v.stop + 1) for k, v in slices.items()})
        object.__setattr__(self, "_meas", {r.name: measured_channels(r) for r in self.runs
                                           if r.name in self.observed})

    @property
    def name(self) -> str:
        pre = [r.name for r in self.runs if r.name not in self.observed]
        obs = "+".join(self.observed)
        return obs if not pre else f"{obs} (after {', '.join(pre)})"

    @property
    def dt(self) -> float:
        return self.runs[0].dt

    def run(self, name: str) -> ShakeTableRun:
        return next(r for r in self.runs if r.name == name)

    def alone(self, name: str) -> BuildingData:
        """The observed run ``name`` driven on its own, from rest (built once, then kept)."""
        cache = self.__dict__.setdefault("_alone", {})
        if name not in cache:
            cache[name] = BuildingData((self.run(name),), observed=(name,), pad_s=self.pad_s)
        return cache[name]

    def measured(self, run: str) -> dict[str, np.ndarray]:
        return self._meas[run]

    def time(self, run: str) -> np.ndarray:
        r = self.run(run)
        return np.asarray(r.time, float) - float(r.time[0])

    def peak_table_accel(self, run: str) -> float:
        return float(np.max(np.abs(self.run(run).table_accel)))

    def __len__(self) -> int:
        return sum(self._meas[o]["isolator_disp"].size for o in self.observed) * len(FIT_CHANNELS)


def simulate(spec: LawSpec, law_p: np.ndarray, sup: Superstructure, data: BuildingData, *,
             k_scale: float = 1.0, zeta: float | None = None, c_iso: float = 0.0, soft_exp: float = 0.0,
             a_ref: float | None = None, recover: bool = False, tally: dict | None = None
             ) -> tuple[int, dict[str, dict[str, np.ndarray]]]:
    """Simulate the building through ``data``'s runs; (status, run -> channel -> (n,) arrays).

    The Newmark step is OpenSees' (Newton, then subdivision of a failing step); at the last
    subdivision level the law's robust local solve (bracketed, safeguarded Newton) replaces a
    failed local iteration, a deviation from OpenSees counted in ``tally`` (when given: its
    ``"robust_steps"`` grows by the output steps where it acted, ``"robust_sims"`` by one when it
    acted at all).  Status 0 on success; otherwise the kernel's status (Newton failed even so) or
    -3 (non-finite output).  Displacements are measured from each run's start, as the records are.

    ``recover``: every observed run is driven from the isolators' virgin state (the runs before it
    are not simulated): the rests between shake-table runs, minutes to hours against the seconds
    of a run, let the rubber's history-dependent softening recover (:attr:`rrfrei.laws.effects.
    EffectSpec.memory`).  For a law without such an effect this changes only the hysteretic
    state a run starts from, which the records' zeroed displacements already leave out.
    """
    if recover:
        a_ref = a_ref or max(data.peak_table_accel(o) for o in data.observed)
        out = {}
        for o in data.observed:
            st, one = simulate(spec, law_p, sup, data.alone(o), k_scale=k_scale, zeta=zeta, c_iso=c_iso,
                               soft_exp=soft_exp, a_ref=a_ref, recover=False, tally=tally)
            if st != 0:
                return st, {}
            out.update(one)
        return 0, out
    zeta = sup.zeta if zeta is None else zeta
    out: dict[str, dict[str, np.ndarray]] = {}
    m = sup.masses
    K = kernel(spec)
    solver = solver_settings(True, gamma=0.5, beta=0.25, tol=1e-12, max_iter=50, max_subdivisions=6)
    dev = 0
    lay = Layer(np.ascontiguousarray(law_p, dtype=float), 1.0, 1.0, np.array(spec.initial_state, dtype=float))
    groups: list[tuple[float, list[str]]]
    if soft_exp == 0.0:
        groups = [(1.0, list(data.observed))]
    else:
        ref = a_ref or max(data.peak_table_accel(o) for o in data.observed)
        groups = [((data.peak_table_accel(o) / ref) ** (-soft_exp), [o]) for o in data.observed]
    for factor, obs in groups:
        k = sup.stiffness * k_scale * factor
        cg = np.zeros(m.size)
        cg[0] = c_iso
        chain = Chain(m, k, 2.0 * zeta / sup.omega1(k) * k, cg, np.asarray(sup.heights, dtype=float))
        last = max(data._slices[o].stop for o in obs)
        ag = data._ag[:last]
        hist = Histories.allocate(ag.size, m.size)
        try:
            res = K.integrate(chain, lay, ag, data.dt, solver, hist)
        except NUMERICAL_ERRORS:
            return -98, {}
        dev += int(np.count_nonzero(hist.robust))
        if res.status != 0:
            _tally(tally, dev)
            return int(res.status), {}
        for o in obs:
            s = data._slices[o]
            u = hist.disp[s, 0] - hist.disp[s.start - 1, 0]
            ch = {"isolator_disp": u, "isolator_force": -(hist.accel[s] @ m),
                  "base_shear": -(hist.accel[s, 1:] @ m[1:]), "roof_accel": hist.accel[s, -1].copy()}
            if not all(np.all(np.isfinite(v)) for v in ch.values()):
                return -3, {}
            out[o] = ch
    _tally(tally, dev)
    return 0, out


def _tally(tally: dict | None, steps: int) -> None:
    if tally is not None and steps:
        tally["robust_steps"] = tally.get("robust_steps", 0) + steps
        tally["robust_sims"] = tally.get("robust_sims", 0) + 1

def calibration_test(runs: Sequence[ShakeTableRun], rate_hz: float) -> ShearTest:
    """The isolation tests (d_0 against F) of ``runs``, decimated to ``rate_hz``, joined in order."""
    return concat_tests([isolation_test(r.decimate(rate_hz)) for r in runs],
                        name="+".join(r.name for r in runs))
