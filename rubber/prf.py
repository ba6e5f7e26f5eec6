"""Parallel rheological framework (PRF) for rubber-like solids: uniaxial, incompressible.

An equilibrium Yeoh chain (Neo-Hookean when C20 = C30 = 0) in parallel with any number of
Bergstrom-Boyce chains, each an Eight-Chain spring (five-term series, a3 = 11/1050) in series with
the flow rule gamma_dot = C1 (lam_ch - 1 + xi)^C2 tau^C3 (MSC Marc notation; lam_ch of the viscous
part).  Units: MPa, s.  Equations and sources: ``docs/reference/prf_model.md`` sections 1-4.

Composition: ``Yeoh(...) & BBChain(...) & BBChain(...)`` gives a :class:`PRFModel`; each chain
keeps its own state u_k = ln(lambda_v,k).  :class:`PRFParams` is the study's flat 14-name form.

``simulate`` is the single entry point; effects such as Mullins damage or permanent set can wrap it
(they receive the :class:`SimResult`, whose arrays are per chain, and return a modified copy).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from rrfrei.errors import NumericalFailure

from . import integrate as _k

TAU_DEFS = ("frobenius", "mises")


def _check(name: str, value: float, lo: float | None = None, hi: float | None = None, *,
           open_lo: bool = False) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} = {value!r}: expected a finite number")
    if lo is not None and (value < lo or (open_lo and value == lo)):
        raise ValueError(f"{name} = {value!r}: expected {'>' if open_lo else '>='} {lo}")
    if hi is not None and value > hi:
        raise ValueError(f"{name} = {value!r}: expected <= {hi}")


@dataclass(frozen=True)
class Yeoh:
    """Equilibrium Yeoh spring W = C10 x + C20 x^2 + C30 x^3, x = I1 - 3 (MPa)."""

    C10: float
    C20: float = 0.0
    C30: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            _check(f.name, getattr(self, f.name))

    @property
    def mu0(self) -> float:
        """Small-strain shear modulus 2 C10 (MPa)."""
        return 2.0 * self.C10

    def __and__(self, other: BBChain | PRFModel) -> PRFModel:
        return PRFModel(self) & other


def NeoHookean(C10: float) -> Yeoh:  # noqa: N802 (a model name)
    """Neo-Hookean spring W = C10 (I1 - 3): the Yeoh model with C20 = C30 = 0."""
    return Yeoh(C10, 0.0, 0.0)


@dataclass(frozen=True)
class BBChain:
    """Eight-Chain spring (nkt MPa, N = lambda_lock^2) in series with a Bergstrom-Boyce dashpot.

    Flow (Marc notation): gamma_dot = C1 (lam_ch - 1 + xi)^C2 tau^C3, C1 in MPa^-C3 s^-1;
    C1 = 0 is a purely elastic chain.
    """

    nkt: float
    N: float
    C1: float
    C2: float = -1.0
    C3: float = 1.0
    xi: float = 5e-3

    def __post_init__(self) -> None:
        _check("nkt", self.nkt, 0.0, open_lo=True)
        _check("N", self.N, 0.0, open_lo=True)
        _check("C1", self.C1, 0.0)
        _check("C2", self.C2)
        _check("C3", self.C3, 1.0)
        _check("xi", self.xi, 0.0, open_lo=True)

    @property
    def mu0(self) -> float:
        """Small-strain shear modulus nkt (1 + 3/(5N) + 99/(175N^2) + 513/(875N^3) + 42039/(67375N^4))."""
        n = self.N
        return self.nkt * (1 + 3 / (5 * n) + 99 / (175 * n**2) + 513 / (875 * n**3) + 42039 / (67375 * n**4))

    def rate_factor(self, tau: str = "frobenius") -> float:
        """A of du/dt = A g(lam_ch) |Delta|^C3 sign(Delta): C1 (mises) or C1 (2/3)^((C3+1)/2)."""
        if tau == "mises":
            return self.C1
        return self.C1 * (2.0 / 3.0) ** ((self.C3 + 1.0) / 2.0)

    def flow_threshold(self, rate: float = 0.093, tau: str = "frobenius") -> float:
        """|Delta| (MPa) at which the virgin chain (lambda_v = 1) flows at du/dt = ``rate`` (1/s)."""
        a = self.rate_factor(tau) * self.xi**self.C2
        if a <= 0.0:
            return math.inf
        return (rate / a) ** (1.0 / self.C3)

    def __and__(self, other: BBChain | PRFModel) -> PRFModel:
        raise TypeError("start a composition with the equilibrium chain: Yeoh(...) & BBChain(...)")


@dataclass(frozen=True)
class PRFModel:
    """General PRF model: one equilibrium Yeoh chain and any number of :class:`BBChain` in parallel."""

    equilibrium: Yeoh
    chains: tuple[BBChain, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not isinstance(self.equilibrium, Yeoh):
            raise ValueError(f"equilibrium = {self.equilibrium!r}: expected a Yeoh spring")
        for c in self.chains:
            if not isinstance(c, BBChain):
                raise ValueError(f"chain {c!r}: expected a BBChain")

    def __and__(self, other: BBChain | PRFModel) -> PRFModel:
        if isinstance(other, BBChain):
            return PRFModel(self.equilibrium, (*self.chains, other))
        if isinstance(other, PRFModel):
            if other.equilibrium != Yeoh(0.0):
                raise ValueError("only one equilibrium chain: compose PRFModel(Yeoh(0)) for extra chains")
            return PRFModel(self.equilibrium, self.chains + other.chains)
        raise TypeError(f"cannot compose PRFModel with {type(other).__name__}")

    def arrays(self, tau: str = "frobenius") -> tuple[np.ndarray, np.ndarray]:
        eq = np.array([self.equilibrium.C10, self.equilibrium.C20, self.equilibrium.C30])
        ch = np.array([[c.nkt, c.N, c.rate_factor(tau), c.C2, c.C3, c.xi] for c in self.chains],
                      dtype=float).reshape(len(self.chains), 6)
        return eq, ch

    @property
    def mu0(self) -> tuple[float, ...]:
        """Small-strain shear moduli (MPa) per chain, equilibrium first."""
        return (self.equilibrium.mu0, *(c.mu0 for c in self.chains))


@dataclass(frozen=True)
class PRFParams:
    """The study's three-chain parameter set (Yeoh A, chains B and C; MPa, s; Marc flow notation)."""

    C10: float
    C20: float
    C30: float
    nkt_B: float
    N_B: float
    C1_B: float
    C2_B: float
    C3_B: float
    nkt_C: float
    N_C: float
    C1_C: float
    C2_C: float
    C3_C: float
    xi: float = 5e-3

    def __post_init__(self) -> None:
        self.to_model()  # validates every field

    def to_model(self) -> PRFModel:
        return PRFModel(Yeoh(self.C10, self.C20, self.C30), (
            BBChain(self.nkt_B, self.N_B, self.C1_B, self.C2_B, self.C3_B, self.xi),
            BBChain(self.nkt_C, self.N_C, self.C1_C, self.C2_C, self.C3_C, self.xi),
        ))

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    def replace(self, **kw: float) -> PRFParams:
        return replace(self, **kw)

    @classmethod
    def from_dict(cls, d: dict) -> PRFParams:
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}: expected names from {names}")
        missing = [n for n in names if n not in d and n != "xi"]
        if missing:
            raise ValueError(f"missing parameter(s) {missing}")
        return cls(**{k: float(v) for k, v in d.items()})


PARAM_NAMES = tuple(f.name for f in fields(PRFParams))


@dataclass(frozen=True)
class SimResult:
    """Response of a PRF model to a stretch history (MPa, s, MJ/m^3).

    chain_cauchy : (k+1, m) Delta = sigma11 - sigma22 of each chain (equilibrium first); their sum is
    the Cauchy stress.  viscous_stretch : (k, m).  dissipated : (k, m) cumulative per chain.
    """

    time: np.ndarray
    stretch: np.ndarray
    nominal: np.ndarray
    cauchy: np.ndarray
    chain_cauchy: np.ndarray
    viscous_stretch: np.ndarray
    dissipated: np.ndarray
    stored: np.ndarray
    steps: int
    rejected: int

    @property
    def dissipated_total(self) -> np.ndarray:
        return self.dissipated.sum(axis=0)


def _as_model(params: PRFParams | PRFModel) -> PRFModel:
    if isinstance(params, PRFParams):
        return params.to_model()
    if isinstance(params, PRFModel):
        return params
    if isinstance(params, Yeoh):
        return PRFModel(params)
    raise ValueError(f"params: expected PRFParams or PRFModel, got {type(params).__name__}")


def check_history(time, stretch) -> tuple[np.ndarray, np.ndarray]:
    t = np.ascontiguousarray(time, dtype=float)
    lam = np.ascontiguousarray(stretch, dtype=float)
    if t.ndim != 1 or lam.shape != t.shape or t.size < 2:
        raise ValueError(f"time {t.shape} and stretch {lam.shape}: expected equal 1-D arrays of >= 2 samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(lam))):
        raise ValueError("time/stretch: non-finite value")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        raise ValueError(f"time: not strictly increasing at sample {bad[0] + 1} (t = {t[bad[0] + 1]})")
    if np.any(lam <= 0):
        raise ValueError(f"stretch: non-positive value at sample {int(np.argmax(lam <= 0))}")
    return t, lam


def simulate(params: PRFParams | PRFModel, time, stretch, *, tau: str = "frobenius",
             rtol: float = 1e-6) -> SimResult:
    """Stress response to a piecewise-linear stretch history lambda(t), starting virgin (lambda_v = 1).

    Parameters
    ----------
    params : PRFParams or PRFModel.
    time, stretch : sample times (s, strictly increasing) and stretches; linear in between, so every
        sample is a step boundary (kinks are landed on).
    tau : "frobenius" (tau = ||dev sigma||, Bergstrom's code, default) or "mises".
    rtol : local error tolerance on ln(lambda_v) per step (TR-BDF2). 1e-6 gives max|P - P_ref| /
        max|P_ref| ~ 1e-5 on the study's protocols.

    Returns
    -------
    SimResult with nominal stress P = sigma / lambda and Cauchy stress sigma (MPa).
    """
    if tau not in TAU_DEFS:
        raise ValueError(f"tau = {tau!r}: expected one of {TAU_DEFS}")
    _check("rtol", rtol, 0.0, open_lo=True)
    model = _as_model(params)
    t, lam = check_history(time, stretch)
    eq, ch = model.arrays(tau)
    k, m = ch.shape[0], t.size
    u = np.zeros((k, m))
    dch = np.zeros((k + 1, m))
    diss = np.zeros((k, m))
    st, na, nr = _k.simulate_kernel(t, lam, eq, ch, float(rtol), u, dch, diss)
    if st != _k.OK:
        raise NumericalFailure(f"integration failed: {_k.STATUS_TEXT[st]} (model {model})")
    cauchy = dch.sum(axis=0)
    lv = np.exp(u)
    stored = np.array([_k.yeoh_energy(x, *eq) for x in lam])
    for c in range(k):
        stored += np.array([_k.ec_energy(lam[j] / lv[c, j], ch[c, 0], ch[c, 1]) for j in range(m)])
    return SimResult(t, lam, cauchy / lam, cauchy, dch, lv, diss, stored, int(na), int(nr))


def equilibrium_stress(params: PRFParams | PRFModel, stretch) -> np.ndarray:
    """Nominal stress of the equilibrium chain alone (the fully relaxed curve), MPa."""
    m = _as_model(params)
    lam = np.asarray(stretch, dtype=float)
    e = m.equilibrium
    x = lam**2 + 2 / lam - 3
    return 2 * (e.C10 + 2 * e.C20 * x + 3 * e.C30 * x**2) * (lam - lam**-2)


def instantaneous_stress(params: PRFParams | PRFModel, stretch) -> np.ndarray:
    """Nominal stress with every dashpot locked (lambda_v = 1): the instantaneous curve, MPa."""
    m = _as_model(params)
    lam = np.asarray(stretch, dtype=float)
    p = equilibrium_stress(m, lam)
    for c in m.chains:
        p = p + np.array([_k.ec_delta(x, c.nkt, c.N)[0] for x in lam.ravel()]).reshape(lam.shape) / lam
    return p
