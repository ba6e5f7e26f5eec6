"""Validation cases: which effect, form, base law, noise, seed and size make one set of tests.

A :class:`Case` is made into four tests (protocols 1-4 of :mod:`rrfrei.protocols`, protocol 1
to calibrate, 2-4 held out), every one from a fresh specimen: the base law's force, the effect by
one generator form (:mod:`.forms`), plus noise.

* Base law: ``plasticity`` for even seeds, ``bouc_wen`` for odd seeds, both with the nonlinear
  hardening term off (``alpha2 = 0``, held fixed in the fit: it would be stiffening or rollover
  under another name); ``k_init``, ``qd``, ``alpha1`` (and Bouc-Wen's ``gamma``) perturbed by up
  to +-10 % per seed.
* Size: stratified over seeds, small to large: the quantile of the form's size range is
  ``(b + U) / 10`` with ``b = (3 seed + c) mod 10`` (``c`` fixed per form), so any 10 consecutive
  seeds draw every tenth of the range once.
* Noise of an effect case: iid Gaussian, standard deviation drawn in 1-2 % of the peak base force
  of protocol 1 (one instrument for all four tests).  Controls (no effect, a false alarm is any
  effect named on one): iid Gaussian 0.5 % and 3 %, Student-t with 3 degrees of freedom (heavy
  tails, standard deviation 1.5 %), AR(1) with coefficient 0.8 (correlated, standard deviation
  1.5 %).
* Seeds: the data of a case come from ``numpy.random.default_rng([seed, crc32(label)])``, so a
  case is the same whatever else runs, in whatever order or process; the diagnosis gets ``seed``.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from rrfrei.gap.validation.forms import FORMS, Form, Signal, forms_of
from rrfrei.io import ShearTest
from rrfrei.protocols import protocol

__all__ = ["BASES", "CONTROLS", "Case", "FIXED", "cases", "make_case_tests", "effect_gap"]

BASES: dict[str, dict[str, float]] = {
    "plasticity": {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0},
    "bouc_wen": {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0, "eta": 1.0,
                 "beta": 0.5, "gamma": 0.5},
}
"""Base laws of the data and their nominal parameters (kN, m)."""
FIXED = {"alpha2": 0.0, "mu": 2.0}
"""Base-law parameters held fixed in every fit (the hardening term is off in the data)."""
PERTURBED = ("k_init", "qd", "alpha1", "gamma")
CONTROLS: dict[str, tuple[str, float]] = {
    "gaussian_0.5%": ("gaussian", 0.005),
    "gaussian_3%": ("gaussian", 0.03),
    "student_t3": ("student_t3", 0.015),
    "ar1_0.8": ("ar1", 0.015),
}
"""Control name -> (noise kind, standard deviation as a fraction of the peak force)."""
NOISE_RANGE = (0.01, 0.02)
"""Standard deviation of the Gaussian noise of an effect case, fraction of the peak force."""
DD, DM = 0.020, 0.030


def _crc(text: str) -> int:
    return zlib.crc32(text.encode())


@dataclass(frozen=True)
class Case:
    """One validation case: ``effect`` (or ``"control"``), ``form`` (the generator form, or the
    control's noise name), ``seed``; the rest follows from them (see the module docstring)."""

    effect: str
    form: str
    seed: int

    @property
    def label(self) -> str:
        return f"{self.effect}/{self.form}"

    @property
    def key(self) -> str:
        return f"{self.label}/seed{self.seed}"

    @property
    def base(self) -> str:
        return "plasticity" if self.seed % 2 == 0 else "bouc_wen"

    @property
    def is_control(self) -> bool:
        return self.effect == "control"

    def generator(self) -> Form | None:
        if self.is_control:
            return None
        for f in forms_of(self.effect):
            if f.name == self.form:
                return f
        raise ValueError(f"form must be one of {', '.join(f.name for f in forms_of(self.effect))} "
                         f"for {self.effect}, got {self.form!r}")

    def rng(self) -> np.random.Generator:
        return np.random.default_rng([self.seed, _crc(self.label)])

    def size_quantile(self) -> float:
        """Stratified quantile of the size range (see the module docstring); NaN for a control."""
        if self.is_control:
            return float("nan")
        b = (3 * self.seed + _crc(self.label)) % 10
        u = np.random.default_rng([self.seed, _crc(self.label), 1]).uniform()
        return (b + u) / 10.0

    def base_params(self) -> dict[str, float]:
        rng = np.random.default_rng([self.seed, 7])  # same base for every case of a seed
        p = dict(BASES[self.base])
        for k in PERTURBED:
            if k in p:
                p[k] *= 1.0 + 0.1 * rng.uniform(-1.0, 1.0)
        return p


def cases(seeds, *, effects=None, controls=tuple(CONTROLS), forms: str = "all") -> list[Case]:
    """Every (effect, form, seed) case plus the controls.

    Parameters
    ----------
    seeds : a count n (seeds 0..n-1) or a list of seeds.
    effects : effects to include (default: every effect of :data:`.forms.FORMS` that the
        diagnosis's catalogue lists now, :func:`rrfrei.gap.catalogue.catalogue`).
    controls : control names (:data:`CONTROLS`).
    forms : ``"all"`` three forms per effect and seed; ``"rotate"`` one, rotating with the seed
        and the effect (quick runs); ``"first"`` each effect's first form.
    """
    from rrfrei.gap.catalogue import catalogue

    seed_list = list(range(seeds)) if isinstance(seeds, (int, np.integer)) else [int(s) for s in seeds]
    if not seed_list or any(s < 0 for s in seed_list):
        raise ValueError(f"seeds must be a positive count or a non-empty list of seeds >= 0, got {seeds!r}")
    if forms not in ("all", "rotate", "first"):
        raise ValueError(f"forms must be 'all', 'rotate' or 'first', got {forms!r}")
    known = catalogue()
    effects = [e for e in FORMS if e in known] if effects is None else list(effects)
    for e in effects:
        forms_of(e)
        if e not in known:
            raise ValueError(f"effect {e!r} is not in the diagnosis's catalogue ({', '.join(known)})")
    for c in controls:
        if c not in CONTROLS:
            raise ValueError(f"control must be one of {', '.join(CONTROLS)}, got {c!r}")
    out = []
    for seed in seed_list:
        for i, e in enumerate(effects):
            fs = forms_of(e)
            chosen = {"all": fs, "rotate": fs[(seed + i) % len(fs):][:1], "first": fs[:1]}[forms]
            out.extend(Case(e, f.name, seed) for f in chosen)
        out.extend(Case("control", c, seed) for c in controls)
    return out


def _noise(kind: str, sd: float, n: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "gaussian":
        return rng.normal(0.0, sd, n)
    if kind == "student_t3":
        return sd / math.sqrt(3.0) * rng.standard_t(3, n)
    if kind == "ar1":
        phi = 0.8
        e = rng.normal(0.0, sd * math.sqrt(1.0 - phi**2), n)
        out = np.empty(n)
        out[0] = rng.normal(0.0, sd)
        for i in range(1, n):
            out[i] = phi * out[i - 1] + e[i]
        return out
    raise ValueError(f"noise kind must be gaussian, student_t3 or ar1, got {kind!r}")


@dataclass(frozen=True)
class CaseData:
    """The tests of a case and what was drawn for it."""

    tests: list[ShearTest]
    size: float
    size_quantile: float
    noise_sd: float
    noise_kind: str
    effect_gap: float
    """NRMSE of the noise-free effect force against the base force over the held-out tests."""


def effect_gap(f_eff: list[np.ndarray], f_base: list[np.ndarray]) -> float:
    """sqrt(sum (F - F_b)^2 / sum F_b^2) over the given histories (0 for a control)."""
    num = sum(float(np.sum((a - b) ** 2)) for a, b in zip(f_eff, f_base))
    den = sum(float(np.sum(b**2)) for b in f_base)
    return math.sqrt(num / den) if den > 0 else float("nan")


def make_case_tests(case: Case, *, rate: float = 20.0, size_quantile: float | None = None,
                    noise: tuple[str, float] | None = None) -> CaseData:
    """Protocols 1-4 of ``case`` sampled at ``rate`` Hz (see the module docstring).

    ``size_quantile`` overrides the stratified draw (e.g. 0.5 for the middle of the range);
    ``noise`` = (kind, fraction of the peak force) overrides the case's noise.
    """
    from rrfrei.laws import get
    from rrfrei.simulate import simulate_force

    spec = get(case.base)
    params = case.base_params()
    p = spec.pack(params)
    form = case.generator()
    rng = case.rng()
    raw = []
    for k in (1, 2, 3, 4):
        t, u = protocol(k, dd=DD, dm=DM, rate=rate)
        raw.append((t, u, simulate_force(spec, params, u, time=t)))
    t1, u1, fb1 = raw[0]
    f_pk = float(np.max(np.abs(fb1)))
    w1 = float(np.sum(np.abs(0.5 * (fb1[1:] + fb1[:-1]) * np.diff(u1))))
    if case.is_control:
        kind, frac = CONTROLS[case.form]
        q, size = float("nan"), 0.0
    else:
        kind, frac = "gaussian", rng.uniform(*NOISE_RANGE)
        q = case.size_quantile() if size_quantile is None else float(size_quantile)
        size = form.size_at(q)
    if noise is not None:
        kind, frac = noise
    sd = frac * f_pk
    tests, eff, base = [], [], []
    for k, (t, u, fb) in enumerate(raw, start=1):
        if form is None:
            f = fb
        else:
            sig = Signal(t, u, fb, spec.step, p, np.array(spec.initial_state, dtype=float), f_pk, w1, DD, DM,
                         params["k_init"], params["alpha1"] * params["k_init"], params["qd"])
            f = np.asarray(form.force(sig, size), dtype=float)
        if k > 1:
            eff.append(f)
            base.append(fb)
        y = f + _noise(kind, sd, f.size, rng)
        tests.append(ShearTest(f"{case.effect}-{case.form}-seed{case.seed}-protocol{k}", t, u, y,
                               meta={"truth": case.effect, "form": case.form, "seed": case.seed,
                                     "base": case.base, "size": size}))
    return CaseData(tests, size, q, frac, kind, effect_gap(eff, base))
