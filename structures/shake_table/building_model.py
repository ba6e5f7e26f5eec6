"""The shake-table building as a model of the gap engine: output-error calibration (issue 27).

The model is the *building* driven through the runs (:mod:`structures.shake_table.simulation`),
fitted by output error (:mod:`structures.shake_table.output_error`; the fit, its posterior and
residual model in :mod:`structures.shake_table.building_fit`).

Free parameters
---------------
* the law's (those :class:`rrfrei.gap.model.IsolatorModel` fits on the isolation loops, with the
  effects' parameters the catalogue names);
* the superstructure: a stiffness scale ``k_scale`` on every identified story stiffness, and its
  damping ratio ``zeta`` (stiffness-proportional story dashpots c_j = 2 zeta k_j / omega_1);
* system effects (:data:`SYSTEM_EFFECTS`, candidates of the diagnosis like the isolator effects):
  ``isolation_damping``, a linear dashpot ``c_iso`` [kN s/m] across the isolation layer (base slab
  to table), and ``softening``, story stiffness falling with the run's amplitude,
  k_j,run = k_scale k_j (A_run / A_ref)^(-soft_exp) with A the run's peak table acceleration and
  A_ref the largest of the calibration runs (each run is simulated with its own stiffness; the
  runs before it are driven with the same building, so the isolators' carried state is kept).

Memory between runs
-------------------
By default every run starts from the state the run before left (after ``pad_s`` of rest).  An
effect whose state is a damage history (``mullins``, ``scragging``, ``degradation``:
:attr:`rrfrei.laws.effects.EffectSpec.memory`) is also fitted as its ``recovering`` variant
(:meth:`BuildingModel.variants`): every run driven from the virgin state, as when the rests
between shake-table runs (minutes to hours, against the seconds of a run) let the rubber's
softening recover (Mullins 1948; the transient part of scragging, Thompson et al. 2000).  The
engine keeps the variant only when it beats the carried fit on the held-out blocks.  On BNCS the
measured loops show both: at equal amplitude a run's cycles after its largest excursion are
softer than before it, and the next run starts stiffer again (``docs/shake_table.md``).

The effects of a building act on each other's evidence (:attr:`interacting_effects`): output
error carries every missing effect forward in the simulated motion, so the diagnosis's combination
steps also try the effects whose gains pass the rule's rank tests but are alone too small and
every history effect in both forms (carried and recovering), and the named effect's building is
also fitted from scratch, the fit the calibration runs prefer standing for it and starting the
combination (step 5 of :mod:`rrfrei.gap.diagnose`).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence

import numpy as np

from rrfrei.budget import TimeBudget
from rrfrei.gap.catalogue import catalogue
from rrfrei.gap.model import FitResult, GapModel, IsolatorModel, test_scales
from rrfrei.io import ShearTest
from rrfrei.laws import LawSpec, get
from rrfrei.laws.effects import EFFECTS
from structures.shake_table.building_fit import BuildingFit
from structures.shake_table.output_error import GLOBAL_EVALS, MAX_NFEV, REFIT_GLOBAL_EVALS, fit_output_error
from structures.shake_table.simulation import (
    FIT_CHANNELS,
    REPORT_CHANNELS,
    BuildingData,
    Superstructure,
    simulate,
)

__all__ = ["RECOVERING", "SYSTEM_EFFECTS", "BuildingModel"]

SYSTEM_EFFECTS = ("isolation_damping", "softening")
"""System effects the building model adds besides the isolator effects of the catalogue."""
RECOVERING = "recovering"
"""The variant of a history effect (:attr:`rrfrei.laws.effects.EffectSpec.memory`) whose runs each
start from the virgin state (:meth:`BuildingModel.variants`)."""
WINDOW_S = 10.0
"""Length of the time windows that are the blocks of the decision rule [s]."""
K_SCALE_BOX = (0.5, 2.0)
"""Bounds of the superstructure stiffness scale: a factor 2 either way of the identification."""
ZETA_BOX = (0.0, 0.2)
"""Bounds of the superstructure damping ratio (20 %: beyond any reinforced-concrete frame)."""


class _Layout:
    """Where each parameter goes: law vector, k_scale, zeta, c_iso, soft_exp."""

    def __init__(self, spec: LawSpec, law_free: Sequence[str], law_fixed: Mapping[str, float],
                 system: Sequence[str]) -> None:
        self.spec = spec
        self.law_free = tuple(law_free)
        self.law_fixed = dict(law_fixed)
        self.system = tuple(system)
        self.names = self.law_free + self.system
        self.idx = {n: i for i, n in enumerate(spec.param_names)}

    def law_vector(self, values: Mapping[str, float]) -> np.ndarray:
        p = np.zeros(len(self.spec.param_names))
        for q in self.spec.params:
            if q.name in values:
                p[self.idx[q.name]] = values[q.name]
            elif q.name in self.law_fixed:
                p[self.idx[q.name]] = self.law_fixed[q.name]
            elif q.optional:
                p[self.idx[q.name]] = q.default
        return p

# ---------------------------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------------------------
class BuildingModel(GapModel):
    """The building on shake-table runs as a model of :mod:`rrfrei.gap` (module docstring).

    Parameters
    ----------
    law : isolator law name, possibly augmented (``"bouc_wen+rate"``).
    superstructure : :class:`Superstructure` (or an identification / a ShearBuilding).
    start_test : the calibration runs' isolation tests joined in order (a
        :class:`rrfrei.io.ShearTest`: d_0 against F); gives the isolator loop fit that starts the
        search and the effects' scales.
    scales : channel -> normalising scale (RMS of the channel over the calibration runs).
    system : system effects included (subset of :data:`SYSTEM_EFFECTS`).
    draws : posterior draws per fit.
    loop_fit : the isolator loop fit of the base law on ``start_test`` (an
        :class:`rrfrei.gap.model.IsolatorFit`), computed once and shared by augmented models.
    a_ref : reference peak table acceleration of ``softening`` [m/s^2].
    recover : every run is driven from the isolators' virgin state instead of the state the run
        before left (:data:`RECOVERING`; by default the state is carried).
    """

    interacting_effects = True
    """Output error: the simulated motion carries every effect's error forward (a missing damping
    puts it out of phase, hiding what a stiffness effect would close), so the diagnosis tries at
    its combination steps the effects whose gains are consistent but alone too small, too."""

    def __init__(self, law: str | LawSpec, superstructure, start_test: ShearTest, scales: Mapping[str, float],
                 *, system: Sequence[str] = (), draws: int = 30, loop_fit=None, a_ref: float = 1.0,
                 max_nfev: int = MAX_NFEV, global_evals: int = GLOBAL_EVALS,
                 refit_global_evals: int = REFIT_GLOBAL_EVALS, recover: bool = False) -> None:
        self.spec = get(law)
        self.recover = bool(recover)
        self.sup = Superstructure.of(superstructure)
        self.start_test = start_test
        self.scales = {c: float(scales[c]) for c in REPORT_CHANNELS}
        for s in system:
            if s not in SYSTEM_EFFECTS:
                raise ValueError(f"unknown system effect {s!r}; available: {', '.join(SYSTEM_EFFECTS)}")
        self.system = tuple(s for s in SYSTEM_EFFECTS if s in system)
        if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 4:
            raise ValueError(f"draws must be an integer >= 4, got {draws!r}")
        self.draws = int(draws)
        self.loop_fit = loop_fit
        self.a_ref = float(a_ref)
        self.max_nfev = int(max_nfev)
        self.global_evals = int(global_evals)
        self.refit_global_evals = int(refit_global_evals)
        iso = IsolatorModel(self.spec, draws=10)
        free, fixed = iso.free_parameters(start_test)
        sysp = ["k_scale", "zeta"]
        if "isolation_damping" in self.system:
            sysp.append("c_iso")
        if "softening" in self.system:
            sysp.append("soft_exp")
        self.layout = _Layout(self.spec, free, fixed, sysp)
        self._iso = iso

    # --- identity -------------------------------------------------------------------------
    @property
    def name(self) -> str:  # type: ignore[override]
        # the marker follows the isolator law it concerns (its memory effects), before the system
        # effects: "bouc_wen+mullins (recovering)+isolation_damping"
        law = self.spec.name + (f" ({RECOVERING})" if self.recover else "")
        return "+".join([law, *self.system])

    @property
    def effects(self) -> tuple[str, ...]:
        return tuple(self.spec.effects) + self.system

    def variants(self, effect: str) -> tuple[str, ...]:
        """``("recovering",)`` for an effect whose state is a damage history
        (:attr:`rrfrei.laws.effects.EffectSpec.memory`): the same effect with every run driven
        from the virgin state, as if the rests between runs let the rubber recover."""
        spec = EFFECTS.get(effect)
        return (RECOVERING,) if spec is not None and spec.memory else ()

    def shape_variant(self, effect: str, variant: str) -> bool:
        """The recovering variant changes what is simulated, not the effect's shape."""
        return variant != RECOVERING

    def augment(self, effects: Sequence[str], variants: Mapping[str, str] | None = None) -> BuildingModel:
        for effect, v in (variants or {}).items():
            if v != RECOVERING or effect not in effects or RECOVERING not in self.variants(effect):
                raise ValueError(f"unknown variant {v!r} of {effect!r} for the building model; expected "
                                 f"{RECOVERING!r} of an effect being added with a damage history "
                                 f"({', '.join(e for e in EFFECTS if EFFECTS[e].memory)})")
        recover = self.recover or bool(variants)
        iso = [e for e in effects if e not in SYSTEM_EFFECTS]
        sysx = [e for e in effects if e in SYSTEM_EFFECTS]
        base = self.spec.name.split("+")[0]
        law = "+".join([base, *self.spec.effects, *iso])
        return BuildingModel(law, self.sup, self.start_test, self.scales, system=[*self.system, *sysx],
                             draws=self.draws, loop_fit=self.loop_fit, a_ref=self.a_ref,
                             max_nfev=self.max_nfev, global_evals=self.global_evals,
                             refit_global_evals=self.refit_global_evals, recover=recover)

    @property
    def candidate_effects(self) -> tuple[str, ...]:
        """Every catalogue effect and every system effect."""
        return tuple(catalogue()) + SYSTEM_EFFECTS

    # --- data -----------------------------------------------------------------------------
    def stack(self, out: Mapping[str, Mapping[str, np.ndarray]], data: BuildingData) -> np.ndarray:
        """The fitted channels of the observed runs, normalised, as one vector (run-major)."""
        return np.concatenate([out[o][c] / self.scales[c] for o in data.observed for c in FIT_CHANNELS])

    def observed(self, data: BuildingData) -> np.ndarray:
        return self.stack({o: data.measured(o) for o in data.observed}, data)

    def sigma_vector(self, per_channel: Mapping[str, float], data: BuildingData) -> np.ndarray:
        return np.concatenate([np.full(data.measured(o)["isolator_disp"].size, float(per_channel[c]))
                               for o in data.observed for c in FIT_CHANNELS])

    def groups(self, data: BuildingData) -> np.ndarray:
        """Blocks: ``WINDOW_S`` time windows of each observed run, all fitted channels together."""
        labels, g0 = [], 0
        for o in data.observed:
            t = data.time(o)
            w = np.minimum((t // WINDOW_S).astype(np.int64), max(int(t[-1] // WINDOW_S) - 1, 0))
            nb = int(w.max()) + 1
            for _ in FIT_CHANNELS:
                labels.append(w + g0)
            g0 += nb
        return np.concatenate(labels)

    def extra_sigma(self, fit: BuildingFit, channel: str) -> float:
        """Residual sd of a channel that is not fitted (story-1 shear): from the optimum on the
        calibration runs."""
        return fit.sigma_c.get(channel, float("nan"))

    # --- parameters -------------------------------------------------------------------------
    def scaled_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sc = test_scales(self.start_test)
        lay = self.layout
        scale, box = {}, {}
        base = self._base_values()
        for n in lay.law_free:
            scale[n] = max(abs(base.get(n, 0.0)), 1e-3)
        for eff in self.spec.effects:
            info = self._iso.effect_hints(eff)
            scale.update({k: v for k, v in info.scales(sc).items() if k in lay.law_free})
            box.update(info.box(sc))
        for n in ("alpha1", "alpha2", "eta", "beta", "gamma", "mu"):
            if n in scale:
                scale[n] = max(scale[n], 0.3)
        sys_scale = {"k_scale": 1.0, "zeta": 0.05, "c_iso": 0.05 * sc.force / sc.vel, "soft_exp": 0.1}
        sys_box = {"k_scale": K_SCALE_BOX, "zeta": ZETA_BOX, "c_iso": (0.0, 2.0 * sc.force / sc.vel),
                   "soft_exp": (0.0, 1.0)}
        s, lb, ub = [], [], []
        for n in lay.law_free:
            q = self.spec.param(n)
            lo, hi = q.lower, q.upper
            if n in box:
                lo, hi = max(lo, box[n][0]), min(hi, box[n][1])
            s.append(scale.get(n, 1.0))
            lb.append(lo)
            ub.append(hi)
        for n in lay.system:
            s.append(sys_scale[n])
            lb.append(sys_box[n][0])
            ub.append(sys_box[n][1])
        s = np.array(s)
        return s, np.array(lb) / s, np.array(ub) / s

    def _base_values(self) -> dict[str, float]:
        return dict(self.loop_fit.params) if self.loop_fit is not None else {}

    def simulate(self, x: np.ndarray, data: BuildingData, tally: dict | None = None):
        """(status, run -> channel -> (n,)) at parameters ``x`` (:attr:`layout` names, units);
        ``tally``: counts of the robust local solve's deviations (:func:`simulate`)."""
        lay = self.layout
        vals = dict(zip(lay.names, np.asarray(x, float)))
        p = lay.law_vector(vals)
        if self.spec.check is not None:
            try:
                self.spec.check(p)
            except ValueError:
                return -97, {}
        return simulate(self.spec, p, self.sup, data, k_scale=vals["k_scale"], zeta=vals["zeta"],
                        c_iso=vals.get("c_iso", 0.0), soft_exp=vals.get("soft_exp", 0.0), a_ref=self.a_ref,
                        recover=self.recover, tally=tally)

    def starts(self, start) -> list[dict[str, float]]:
        """Start points (dicts of parameter values): from fits given (their parameters, with each
        added effect at the catalogue's start and, when no global search follows, also at its
        neutral value: the global search's box holds both), else from the loop fit."""
        sc = test_scales(self.start_test)
        bases: list[dict[str, float]] = []
        for s in ([start] if isinstance(start, FitResult) else list(start or [])):
            bases.append(dict(s.params) if isinstance(s, BuildingFit) else dict(s.params))
        if not bases:
            b = dict(self._base_values())
            b.update({"k_scale": 1.0, "zeta": self.sup.zeta})
            bases = [b, dict(b, k_scale=1.2, zeta=min(3 * self.sup.zeta, 0.25))]
        alternatives = start is None or self.refit_global_evals <= 0
        c_iso_new = not all("c_iso" in b for b in bases)
        out = []
        for b in bases:
            b = dict(b)
            b.setdefault("k_scale", 1.0)
            b.setdefault("zeta", self.sup.zeta)
            b.setdefault("c_iso", 0.0)
            b.setdefault("soft_exp", 0.0)
            opts = [{}]
            for eff in self.spec.effects:
                info = self._iso.effect_hints(eff)
                es = info.scales(sc)
                if any(k not in b for k in es):
                    neutral = dict(zip([q.name for q in info.spec.params], info.spec.neutral))
                    alts = [*info.starts(sc)[:1], neutral] if alternatives else info.starts(sc)[:1]
                    opts = [dict(o, **e) for o in opts for e in alts]
            if "c_iso" in self.layout.system and c_iso_new:
                c0 = 0.02 * sc.force / sc.vel
                opts = [dict(o, c_iso=v) for o in opts for v in ((0.0, c0) if alternatives else (c0,))]
            out.extend(dict(b, **o) for o in opts)
        return out

    # --- fitting -------------------------------------------------------------------------------
    def fit(self, data: BuildingData, *, seed: int = 0, start=None,
            budget: TimeBudget | None = None) -> BuildingFit:
        """Output-error fit on ``data`` (:func:`structures.shake_table.output_error.fit_output_error`).

        Raises NumericalFailure when every start fails (the message names the model and data).
        """
        if not isinstance(data, BuildingData):
            raise ValueError(f"data must be a BuildingData, got {type(data).__name__}")
        return fit_output_error(self, data, seed=seed, start=start, budget=budget)

    # --- checkpoints -----------------------------------------------------------------------------
    def checkpoint_key(self, data: BuildingData) -> str:
        h = hashlib.sha256()
        for r in data.runs:
            for a in (r.table_accel, r.accel, r.disp):
                h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
        settings = {"law": self.spec.name, "system": list(self.system), "draws": self.draws,
                    "observed": list(data.observed), "pad": data.pad_s, "format": 1,
                    "sup": [self.sup.masses.tolist(), self.sup.stiffness.tolist(), self.sup.zeta],
                    "scales": self.scales, "max_nfev": self.max_nfev, "format_fit": 2,
                    "global": [self.global_evals, self.refit_global_evals],
                    "start": None if self.loop_fit is None else sorted(self.loop_fit.params.items())}
        if self.recover:
            settings["recover"] = True
        h.update(json.dumps(settings, sort_keys=True, default=str).encode())
        return h.hexdigest()

    def fit_state(self, fit: BuildingFit) -> dict[str, np.ndarray]:
        return {"x_opt": fit.x_opt, "X": fit.X, "names": np.array(fit.names, dtype=str),
                "sigma": np.array([fit.sigma_c[c] for c in REPORT_CHANNELS]),
                "rho": np.array([fit.rho_c[c] for c in FIT_CHANNELS]), "ess": np.array(fit.ess),
                "nfev": np.array(fit.nfev), "failed": np.array(fit.failed), "seed": np.array(fit.seed),
                "note": np.array(fit.note), "robust_sims": np.array(fit.robust_sims)}

    def restore(self, state: Mapping[str, np.ndarray]) -> BuildingFit:
        names = tuple(str(x) for x in state["names"])
        if names != self.layout.names:
            raise ValueError("checkpoint of another parameter layout")
        return BuildingFit(model=self, x_opt=np.asarray(state["x_opt"], float),
                           X=np.asarray(state["X"], float),
                           sigma_c=dict(zip(REPORT_CHANNELS, map(float, state["sigma"]))),
                           rho_c=dict(zip(FIT_CHANNELS, map(float, state["rho"]))), ess=float(state["ess"]),
                           nfev=int(state["nfev"]), failed=int(state["failed"]), seed=int(state["seed"]),
                           note=str(state["note"]),
                           robust_sims=int(state["robust_sims"]) if "robust_sims" in state else 0)

