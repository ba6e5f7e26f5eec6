"""Validation of the diagnosis on withheld effects (issue 7, item 4).

For every catalogue effect and a no-effect control, tests are MADE from a base law plus that
effect plus Gaussian noise (protocol 1 to calibrate, protocols 2-4 held out, from
:mod:`rrfrei.protocols`), the effect is withheld from the model, and :func:`diagnose` must name it.

The effect forms that make the data are written here, independently of the catalogue kernels
(:mod:`rrfrei.laws.effects`): different functions of the same physics, computed by post-processing
the base law's force (or, for slip, by a separate series solve), so the check is not circular.

=============  ===============================================================================
effect         data-generating form (catalogue form in brackets)
=============  ===============================================================================
degradation    F = F_b (1 - D (1 - exp(-W / W0))), W = int |F_b du|  [1 / (1 + c max int F_b du)]
mullins        F = F_b (1 - m sin(pi/2 (1 - |u| / u_max)))           [linear in |u| / u_max]
rollover       F = F_b + K sgn(u) e log(1 + exp((|u| - u_r) / e)), e = 1 mm  [kinked hinge]
rate           F = F_b + c sgn(v) |v|^0.8, central-difference v      [linear viscous, backward v]
asymmetry      F = F_b (1 + a tanh(u / 2 mm))                          [1 + a sgn(F_b)]
slip           elastic-plastic slider of stiffness 1e3 k_init in series, bisection per sample
               [rigid-plastic slider, Newton]
=============  ===============================================================================

Base law: ``plasticity`` with the nonlinear hardening term off (``alpha2 = 0``; it would be
rollover under another name); the model fitted keeps it off (``fixed``).  Noise: iid Gaussian,
1.5 % of the peak force of protocol 1 (the same instrument for every protocol).  ``seed`` varies
the noise and perturbs the base parameters (+-10 %) and effect sizes (+-20 %).

Reduced mode (``reduced=True``, the default test suite): every test downsampled to 10 Hz (every
second sample: 100 samples per 10 s cycle) and 100 posterior draws per fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from rrfrei.io import ShearTest
from rrfrei.laws import plasticity
from rrfrei.protocols import protocol
from rrfrei.simulate import simulate_force

__all__ = ["CASES", "make_tests", "ValidationResult", "validate", "BASE_LAW", "BASE_PARAMS", "FIXED"]

BASE_LAW = "plasticity"
BASE_PARAMS = {"k_init": 120.0, "qd": 0.6, "alpha1": 0.2, "alpha2": 0.0, "mu": 2.0}
FIXED = {"alpha2": 0.0, "mu": 2.0}
CASES = ("control", "degradation", "mullins", "rollover", "rate", "asymmetry", "slip")
NOISE_FRAC = 0.015


def _degradation(u, t, fb, size, w0):
    w = np.concatenate([[0.0], np.cumsum(np.abs(0.5 * (fb[1:] + fb[:-1]) * np.diff(u)))])
    return fb * (1.0 - size * (1.0 - np.exp(-w / w0)))


def _mullins(u, t, fb, size):
    prev = np.concatenate([[0.0], np.maximum.accumulate(np.abs(u))[:-1]])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(prev > 0, np.abs(u) / prev, 1.0)
    soft = np.where(r < 1.0, size * np.sin(0.5 * math.pi * (1.0 - np.clip(r, 0, 1))), 0.0)
    return fb * (1.0 - soft)


def _rollover(u, t, fb, size, onset):
    e = 1e-3
    s = (np.abs(u) - onset) / e
    hinge = e * np.logaddexp(0.0, s)
    return fb + size * np.sign(u) * hinge


def _rate(u, t, fb, size):
    v = np.gradient(u, t)
    return fb + size * np.sign(v) * np.abs(v) ** 0.8


def _asymmetry(u, t, fb, size):
    return fb * (1.0 + size * np.tanh(u / 2e-3))


def _slip(u, t, p, fs, ks):
    """Base law in series with an elastic-plastic slider (stiffness ks, capacity fs)."""
    n = u.size
    out = np.empty(n)
    sc = np.zeros(1)
    st = np.zeros(1)
    us_c = 0.0  # slider displacement
    up_c = 0.0  # slider plastic displacement
    for i in range(n):
        def gap(us, ui=u[i], upc=up_c):
            st[:] = sc  # the plasticity kernel keeps a sticky trial u_p: start every trial fresh
            fb, _, _ = plasticity.step(p, sc, ui - us, 0.0, 1.0, st)
            fsl = min(max(ks * (us - upc), -fs), fs)
            return fb - fsl
        # F_b decreases and F_slider increases with us: bracket the root around us_c
        lo, hi, w = us_c, us_c, 1e-6
        while gap(lo) < 0:
            lo -= w
            w *= 2
        w = 1e-6
        while gap(hi) > 0:
            hi += w
            w *= 2
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if gap(mid) > 0:
                lo = mid
            else:
                hi = mid
        us = 0.5 * (lo + hi)
        st[:] = sc
        fb, _, _ = plasticity.step(p, sc, u[i] - us, 0.0, 1.0, st)
        sc[:] = st
        q = ks * (us - up_c)
        if abs(q) > fs:
            up_c = us - math.copysign(fs, q) / ks
        us_c = us
        out[i] = fb
    return out


@dataclass(frozen=True)
class _Truth:
    base: dict
    size: float
    extra: float


def _truth(case: str, seed: int) -> _Truth:
    rng = np.random.default_rng([seed, CASES.index(case)])
    base = dict(BASE_PARAMS)
    if seed:
        for k in ("k_init", "qd", "alpha1"):
            base[k] *= 1.0 + 0.1 * rng.uniform(-1, 1)
    f = 1.0 + (0.2 * rng.uniform(-1, 1) if seed else 0.0)
    sizes = {"control": 0.0, "degradation": 0.3, "mullins": 0.3, "rollover": -20.0, "rate": 6.0,
             "asymmetry": 0.15, "slip": 1.12}
    extra = {"rollover": 0.012}.get(case, 0.0)
    size = sizes[case] * (f if case != "slip" else 1.0)
    if case == "slip":
        size = sizes[case] * (1.0 + 0.03 * rng.uniform(-1, 1) if seed else 1.0)
    return _Truth(base, size, extra)


def make_tests(case: str, seed: int = 0, *, reduced: bool = False) -> list[ShearTest]:
    """Protocols 1-4 made from the base law plus ``case`` (an effect or ``"control"``) plus noise."""
    if case not in CASES:
        raise ValueError(f"case must be one of {', '.join(CASES)}, got {case!r}")
    tr = _truth(case, seed)
    p = np.array([tr.base[k] for k in ("k_init", "qd", "alpha1", "alpha2", "mu")])
    raw = []
    for k in (1, 2, 3, 4):
        t, u = protocol(k)
        fb = simulate_force(BASE_LAW, tr.base, u, time=t)
        raw.append((t, u, fb))
    t1, u1, fb1 = raw[0]
    w0 = 0.5 * float(np.sum(np.abs(0.5 * (fb1[1:] + fb1[:-1]) * np.diff(u1))))
    sigma = NOISE_FRAC * float(np.max(np.abs(fb1)))
    rng = np.random.default_rng([seed, 100 + CASES.index(case)])
    out = []
    for k, (t, u, fb) in enumerate(raw, start=1):
        if case == "control":
            f = fb
        elif case == "degradation":
            f = _degradation(u, t, fb, tr.size, w0)
        elif case == "mullins":
            f = _mullins(u, t, fb, tr.size)
        elif case == "rollover":
            f = _rollover(u, t, fb, tr.size, tr.extra)
        elif case == "rate":
            f = _rate(u, t, fb, tr.size)
        elif case == "asymmetry":
            f = _asymmetry(u, t, fb, tr.size)
        else:
            f = _slip(u, t, p, tr.size, 1e3 * tr.base["k_init"])
        f = f + rng.normal(0.0, sigma, f.size)
        if reduced:
            t, u, f = t[::2], u[::2], f[::2]
        out.append(ShearTest(f"{case}-protocol{k}", t, u, f, meta={"truth": case, "seed": seed}))
    return out


@dataclass(frozen=True)
class ValidationResult:
    """Per-case table, confusion matrix, accuracy and false-alarm rate."""

    cases: pd.DataFrame  # case, seed, diagnosed, combination, shrink_holdout, seconds
    confusion: pd.DataFrame

    @property
    def accuracy(self) -> float:
        eff = self.cases[self.cases.case != "control"]
        return float((eff.case == eff.diagnosed).mean()) if len(eff) else float("nan")

    @property
    def false_alarms(self) -> int:
        ctl = self.cases[self.cases.case == "control"]
        return int((ctl.diagnosed != "none").sum())

    @property
    def false_alarm_rate(self) -> float:
        ctl = self.cases[self.cases.case == "control"]
        return float((ctl.diagnosed != "none").mean()) if len(ctl) else float("nan")

    def as_dict(self) -> dict:
        return {"accuracy": self.accuracy, "false_alarms": self.false_alarms,
                "false_alarm_rate": self.false_alarm_rate,
                "cases": self.cases.to_dict(orient="records"),
                "confusion": {str(k): {str(c): int(v) for c, v in row.items()}
                              for k, row in self.confusion.iterrows()}}


def validate(seeds: int | list[int] = 1, *, cases=CASES, reduced: bool = False, draws: int | None = None,
             combine: bool = True, progress=None) -> ValidationResult:
    """Run the diagnosis on every case x seed and tabulate (see the module docstring)."""
    import time

    from rrfrei.gap.diagnose import diagnose_gap

    seed_list = list(range(seeds)) if isinstance(seeds, (int, np.integer)) else list(seeds)
    if not seed_list:
        raise ValueError("seeds must be a positive count or a non-empty list")
    draws = draws or (100 if reduced else 200)
    rows = []
    for seed in seed_list:
        for case in cases:
            t0 = time.perf_counter()
            tests = make_tests(case, seed, reduced=reduced)
            rep = diagnose_gap(tests[0], BASE_LAW, holdout=tests[1:], fixed=FIXED, draws=draws,
                               seed=seed, combine=combine, progress=False)
            named = next((s for s in rep.ranking if s.effect == rep.diagnosis), None)
            rows.append({"case": case, "seed": seed, "diagnosed": rep.diagnosis,
                         "combination": "+".join(rep.combination) or "none",
                         "shrink_holdout": named.shrink_holdout if named else float("nan"),
                         "gap_before": rep.baseline[1].gap, "gap_after": rep.final[1].gap,
                         "seconds": time.perf_counter() - t0})
            if progress:
                progress(rows[-1])
    df = pd.DataFrame(rows)
    cols = [c for c in cases if c != "control"] + ["none"]
    conf = pd.crosstab(df.case, df.diagnosed).reindex(index=list(cases), columns=cols, fill_value=0)
    conf.index.name = "true"
    conf.columns.name = "diagnosed"
    return ValidationResult(df, conf)
