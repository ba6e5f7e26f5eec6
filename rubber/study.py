"""The cross-prediction study (the study's Table 1): fit to protocol 1 (case A), to protocol 2 (case B)
and to both (case C), then evaluate every fit on every protocol.

RECONSTRUCTED PRESETS.  The paper ("Effects of two testing protocols on the material model parameter
identification for rubber-like materials") could not be found with the search tool, so its Table 1
is not reproduced here.  ``PRESETS`` are reconstructions consistent with every fact recorded in
``docs/reference/prf_model.md``: small-strain moduli per chain (case A 3.76/3.13/14.47,
B 2.00/4.90/4.28, C 3.62/3.25/12.47 MPa), bound-active values (A: N_B = 5, C1_C = 5; B: C10 = 1,
N_B = 1), C3_C = 7.4 for A, C20 < 0 < C30 for A and C, C20 = +1.1 for B, the flow thresholds of case A
(0.978 and 0.359 MPa at 0.093/s), W1_Yeoh min ~ 1.5 MPa with its inflection at I1 - 3 ~ 0.7, the
case-A relaxation values (2.09 -> 1.26, 2.90 -> 2.08, 3.46 -> 2.70 MPa; ours 2.09 -> 1.25,
2.89 -> 2.08, 3.46 -> 2.69) and first protocol-1 peak 3.64 MPa.  The remaining flow parameters of
cases B and C were set by a least-squares fit to the case-A response (B: protocol 2 only; C: both),
with N_C chosen freely (it is not identifiable).  Treat them as plausible sets, not as the paper's.

``BOX`` is likewise reconstructed: N in [1, 5], C1 in [1e-6, 5] (the paper allows C1 = 0; zero is
excluded for the log scaling), C3 in [1, 10], nkT in [0.01, 20], C10 >= 1; the C20/C30 limits are
guesses that contain every fact of the notes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .io import Test
from .prf import PRFParams

PRESETS: dict[str, PRFParams] = {
    "A": PRFParams(C10=1.88, C20=-0.525, C30=0.25,
                   nkt_B=2.725728, N_B=5.0, C1_B=1.2516e-3, C2_B=-1.0, C3_B=3.5,
                   nkt_C=9.313183, N_C=2.0, C1_C=5.0, C2_C=-1.0, C3_C=7.4, xi=5e-3),
    "B": PRFParams(C10=1.0, C20=1.1, C30=0.05,
                   nkt_B=1.451441, N_B=1.0, C1_B=1.4204e-3, C2_B=-1.0, C3_B=10.0,
                   nkt_C=3.311990, N_C=3.0, C1_C=3.2766, C2_C=-1.0, C3_C=9.2222, xi=5e-3),
    "C": PRFParams(C10=1.81, C20=-0.50, C30=0.24,
                   nkt_B=2.715223, N_B=4.0, C1_B=8.0388e-4, C2_B=-1.0, C3_B=4.1828,
                   nkt_C=9.010052, N_C=2.5, C1_C=0.88694, C2_C=-1.0, C3_C=5.6995, xi=5e-3),
}

#: search box (lower, upper) of every parameter; reconstructed (see module docstring)
BOX: dict[str, tuple[float, float]] = {
    "C10": (1.0, 5.0), "C20": (-1.0, 2.0), "C30": (0.0, 1.0),
    "nkt_B": (0.01, 20.0), "N_B": (1.0, 5.0), "C1_B": (1e-6, 5.0), "C2_B": (-1.0, 0.0), "C3_B": (1.0, 10.0),
    "nkt_C": (0.01, 20.0), "N_C": (1.0, 5.0), "C1_C": (1e-6, 5.0), "C2_C": (-1.0, 0.0), "C3_C": (1.0, 10.0),
    "xi": (1e-4, 0.1),
}


@dataclass(frozen=True)
class CaseStudy:
    """Fits of the three cases and the error f of each on each protocol (and in total)."""

    fits: dict            # case -> FitResult
    f: dict               # case -> {protocol name: f}
    protocols: tuple[str, str]

    def table(self) -> str:
        from .prf import PARAM_NAMES

        cases = list(self.fits)
        head = f"{'':10s}" + "".join(f"{c:>13s}" for c in cases)
        lines = [head]
        for n in PARAM_NAMES:
            lines.append(f"{n:10s}" + "".join(f"{self.fits[c].params.as_dict()[n]:13.5g}" for c in cases))
        for p in self.protocols:
            lines.append(f"{'f ' + p:10.10s}" + "".join(f"{self.f[c][p]:13.3e}" for c in cases))
        lines.append(f"{'f total':10s}" + "".join(f"{sum(self.f[c].values()):13.3e}" for c in cases))
        return "\n".join(lines)


def cases(p1: Test, p2: Test, **fit_kw) -> CaseStudy:
    """Fit case A (protocol 1), B (protocol 2), C (both); evaluate each on both protocols.

    ``fit_kw`` go to :func:`rubber.fit` (seed, restarts, max_evals, ...).
    """
    from .fit import fit, objective

    fits = {"A": fit([p1], **fit_kw), "B": fit([p2], **fit_kw), "C": fit([p1, p2], **fit_kw)}
    tau = fit_kw.get("tau", "frobenius")
    f = {c: {t.name: float(objective(r.params, [t], tau=tau)[0]) for t in (p1, p2)} for c, r in fits.items()}
    return CaseStudy(fits, f, (p1.name, p2.name))


def synthetic_test(params: PRFParams, protocol: str = "p1", *, noise: float = 0.0, seed: int = 0,
                   dt: float = 0.1) -> Test:
    """A synthetic test from a parameter set under protocol 1 or 2 (optional Gaussian noise, MPa)."""
    from .prf import simulate
    from .protocols import protocol1, protocol2

    t, lam = (protocol1 if protocol == "p1" else protocol2)(dt=dt)
    p = simulate(params, t, lam, rtol=1e-9).nominal
    if noise:
        p = p + np.random.default_rng(seed).normal(0.0, noise, p.size)
    return Test(f"synthetic_{protocol}", t, lam, p)


#: a soft acrylic-elastomer-like parameter set (kPa-scale stresses) for the multi-rate data set; chains
#: ordered C1_B <= C1_C as the fit orders them.  Flow thresholds at 0.0311 /s: 2.07 kPa (B, C3 = 2)
#: and 7.09 kPa (C, C3 = 4); small-strain moduli 16.0 / 26.2 / 13.0 kPa (A / B / C).
ACRYLIC = PRFParams(C10=0.008, C20=-1.0e-4, C30=1.0e-5,
                    nkt_B=0.025, N_B=15.0, C1_B=70.0, C2_B=-1.0, C3_B=2.0,
                    nkt_C=0.012, N_C=8.0, C1_C=1.7e5, C2_C=-1.0, C3_C=4.0, xi=5e-3)


def multirate_tests(params: PRFParams = ACRYLIC, rates: tuple[float, ...] = (0.01, 0.03, 0.1),
                    stretches: tuple[float, ...] = (1.5, 2.0, 2.5, 3.0), *, noise: float = 0.01,
                    seed: int = 0, dlam: float = 0.02) -> list[Test]:
    """Load-unload tests at every (rate, maximum stretch): ``len(rates) x len(stretches)`` tests.

    Nominal stress from :func:`rubber.simulate` (rtol 1e-9) plus Gaussian noise of standard deviation
    ``noise`` times each test's peak stress (seeded: test i uses ``seed + i``).  Names
    ``r{rate}_l{stretch}``.
    """
    from .prf import simulate
    from .protocols import load_unload

    out = []
    for r in rates:
        for lm in stretches:
            t, lam = load_unload(lm, r, dlam=dlam)
            p = simulate(params, t, lam, rtol=1e-9).nominal
            if noise:
                rng = np.random.default_rng(seed + len(out))
                p = p + rng.normal(0.0, noise * float(np.max(np.abs(p))), p.size)
            out.append(Test(f"r{r:g}_l{lm:g}", t, lam, p))
    return out

