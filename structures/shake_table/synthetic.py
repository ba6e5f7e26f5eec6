"""Synthetic shake-table runs of a building on isolators, by an independent integrator.

Validation that cannot be tuned to (issue 27.7) needs buildings whose truth is known and whose
equations are *not* the project's: this module simulates a shear building on a hysteretic
isolation layer in plain NumPy (fixed-step classical Runge-Kutta on the equations of motion, the
isolator's hysteretic variable as one more state), with no call to :mod:`structures.dynamics.newmark`,
the law kernels or any project integrator, and returns :class:`structures.shake_table.ShakeTableRun`
objects as the readers do, so the whole shake-table pipeline runs on them unchanged.

Model (kN, m, s, t)
-------------------
Levels 0..N bottom-up (0 = the base slab on the isolators), masses m_i; displacements x_i
relative to the table, table acceleration a_g(t)::

    M x'' + C_s x' + K_s(x) + e_0 F_iso(x_0, x_0', z, E) = -M 1 a_g

K_s, C_s: story j (between levels j-1 and j, j = 1..N) with stiffness k_j and dashpot
c_j = 2 zeta k_j / omega_1 (omega_1 the fixed-base fundamental circular frequency).  The
isolation layer (Wen 1976, Bouc-Wen, continuous form)::

    F_iso = g(E) [qd z + k2 x_0] + F_w(x_0, x_0'),   k2 = alpha k_init,  u_y = qd / ((1 - alpha) k_init)
    z'    = (x_0' / u_y) [1 - |z|^eta (gamma + beta sgn(z x_0'))]
    E'    = qd z x_0'  (work of the hysteretic force, used by the ``degradation`` form)

The *withheld effects* (forms the project's catalogue does not hold verbatim), ``effect=``:

* ``"none"`` (a control): F_w = 0, g = 1, linear stories;
* ``"viscous_power"``: isolation-layer damping with a power law, F_w = c_v sgn(v) |v|^a
  (a = 0.4, the fluid-damper form; c_v from ``strength`` as a share of qd at 0.3 m/s);
* ``"softening"``: superstructure softening with amplitude, every story a smooth saturating
  spring, V_j = k_j d / sqrt(1 + (d / d_s)^2) (d the drift; secant stiffness falls with it);
* ``"stiffening"``: isolator stiffening by an exponential, F_w = k_h d_h (exp(|x_0| / d_h) - 1 -
  |x_0| / d_h) sgn(x_0) (smooth from zero, grows faster than any power);
* ``"degradation"``: strength and stiffness fade with hysteretic energy, g = exp(-max E / E_0);
* ``"recovering_softening"``: strength and stiffness soften after large excursions and recover at
  rest, g = 1 - s D with a damage D that rises quickly towards tanh(|x_0| / x_r) whenever that is
  larger (D' = (tanh(|x_0| / x_r) - D) / tau_on) and otherwise recovers slowly (D' = -D / tau_rec,
  tau_rec = 300 s, long against a run's strong motion), and between runs over ``gap_s`` = 1 h of
  unrecorded rest (D times exp(-gap_s / tau_rec)): the Mullins softening of a filled rubber and its
  recovery with time (Mullins 1948), the transient part of an HDR bearing's scragging.  No
  catalogue kernel has this form: ``mullins`` softens only below the largest past displacement and
  ``scragging`` by the largest displacement ever, neither recovers in time.

Integration: classical RK4 at ``substeps`` sub-steps per output sample, the table acceleration
linear between samples.  The absolute level accelerations are the equation's right-hand side
divided by the masses (a_i = x_i'' + a_g), so -sum m_i a_i is the isolation-layer force exactly.
Every channel then gets white Gaussian noise, independent per channel, in the form of its
instrument (the truth is kept in ``run.meta["truth"]``):

* accelerations (table and levels): standard deviation ``noise`` times the channel's RMS (2 % by
  default, 0.2-1 mg on the validation runs: at or above the 0.1-1 mg floor of a force-balance
  or MEMS accelerometer over 25 Hz);
* displacements (every level, relative to the table): a fixed standard deviation ``disp_noise``
  [m], the same on every level and every run.  A displacement transducer (string potentiometer,
  LVDT) has a noise set by its range and its acquisition channel, not by the motion it measures:
  each level's transducer spans the isolation layer's stroke (the levels ride on it), and a
  fraction of a per mil of that span is electrical noise.  The default 0.05 mm is 1/6000 of the
  300 mm span of a +-150 mm transducer (a few millivolts on a +-10 V channel).  Noise in
  proportion to each level's RMS (the earlier model) made the roof's noise grow with the
  isolator's motion, so the largest runs had the noisiest drifts, the reverse of a real table.

Run length: real shake-table runs are long (tens of seconds of strong motion, then the building's
free vibration recorded before the table stops); :func:`synthetic_sequence` records ``duration``
seconds of table motion and ``tail_s`` seconds of free vibration per run.

Table motions: :func:`table_motion` is a filtered, enveloped white noise (a Kanai-Tajimi-like
ground motion, seeded); :func:`synthetic_sequence` scales one motion to increasing peaks and
runs the building through them in order with its state carried (as a real test sequence).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.signal

from structures.shake_table import ShakeTableRun

__all__ = ["DISP_NOISE_M", "EFFECTS", "SyntheticBuilding", "energy_balance", "simulate_building",
           "synthetic_sequence", "table_motion", "with_effect"]

EFFECTS = ("none", "viscous_power", "softening", "stiffening", "degradation", "recovering_softening")
"""The withheld effects (module docstring); ``"none"`` is the control."""


@dataclass(frozen=True)
class SyntheticBuilding:
    """A shear building on an isolation layer (units kN, m, s, t).

    Attributes
    ----------
    masses : (L,) level masses [t], bottom-up (0 = base slab).
    stiffness : (L-1,) story stiffnesses [kN/m] (story j between levels j-1 and j).
    zeta : superstructure damping ratio (stiffness-proportional at the fixed-base mode 1).
    k_init, qd, alpha, eta, beta, gamma : the isolation layer's Bouc-Wen law: initial stiffness
        [kN/m], characteristic strength [kN] (0: a linear layer of stiffness alpha k_init),
        post-yield ratio, exponent and shape coefficients.
    effect : withheld effect (:data:`EFFECTS`).
    strength : size of the effect (dimensionless, see :meth:`effect_params`); 0 = none.
    c_iso : a linear dashpot across the isolators [kN s/m] (0: none), part of the truth.
    """

    masses: tuple[float, ...] = (60.0, 25.0, 25.0, 20.0)
    stiffness: tuple[float, ...] = (6.0e4, 5.0e4, 4.0e4)
    zeta: float = 0.03
    k_init: float = 2.0e4
    qd: float = 50.0
    alpha: float = 0.1
    eta: float = 1.0
    beta: float = 0.5
    gamma: float = 0.5
    effect: str = "none"
    strength: float = 0.0
    c_iso: float = 0.0
    effect_kw: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        m = np.asarray(self.masses, dtype=float)
        k = np.asarray(self.stiffness, dtype=float)
        if m.ndim != 1 or m.size < 2 or not np.all(m > 0):
            raise ValueError(f"masses = {self.masses!r}: expected at least two positive masses [t]")
        if k.shape != (m.size - 1,) or not np.all(k > 0):
            raise ValueError(f"stiffness = {self.stiffness!r}: expected {m.size - 1} positive story "
                             "stiffnesses [kN/m]")
        if self.effect not in EFFECTS:
            raise ValueError(f"effect = {self.effect!r} is unknown; expected one of {EFFECTS}")
        if not (self.k_init > 0 and self.qd >= 0 and 0 <= self.alpha < 1 and self.eta > 0
                and self.beta + self.gamma > 0 and self.strength >= 0 and self.zeta >= 0
                and self.c_iso >= 0):
            raise ValueError(f"invalid isolator or damping parameters in {self!r}")

    @property
    def total_mass(self) -> float:
        return float(sum(self.masses))

    @property
    def u_y(self) -> float:
        """Yield displacement of the isolation layer [m]."""
        return self.qd / ((1.0 - self.alpha) * self.k_init)

    def omega1(self) -> float:
        """Fixed-base fundamental circular frequency of the superstructure [rad/s]."""
        m = np.asarray(self.masses[1:], dtype=float)
        k = np.asarray(self.stiffness, dtype=float)
        n = m.size
        K = np.zeros((n, n))
        for j in range(n):  # story j below level j+1 (fixed base)
            K[j, j] += k[j]
            if j > 0:
                K[j - 1, j - 1] += k[j]
                K[j - 1, j] -= k[j]
                K[j, j - 1] -= k[j]
        w2 = np.linalg.eigvals(K / m[:, None])  # of M^-1 K
        return float(math.sqrt(float(np.min(np.real(w2)))))

    def effect_params(self) -> dict[str, float]:
        """The withheld effect's parameters from ``strength`` (and ``effect_kw`` overrides)."""
        s = self.strength
        base = {
            "none": {},
            "viscous_power": {"c_v": s * self.qd / 0.3**0.4, "a": 0.4},
            "softening": {"d_s": 0.004 / max(s, 1e-12)},
            "stiffening": {"k_h": s * self.alpha * self.k_init, "d_h": 0.03},
            "degradation": {"E_0": self.qd * 2.0 / max(s, 1e-12)},
            "recovering_softening": {"s": s, "x_r": 0.06, "tau_on": 1.0, "tau_rec": 300.0, "gap_s": 3600.0},
        }[self.effect]
        return {**base, **self.effect_kw}


def table_motion(duration: float = 20.0, rate_hz: float = 50.0, *, seed: int = 0,
                 f_g: float = 1.5, zeta_g: float = 0.4, f_hp: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """A table acceleration record [m/s^2] of unit peak and its time [s].

    White noise through a Kanai-Tajimi filter (ground frequency ``f_g`` [Hz], damping
    ``zeta_g``), a high-pass at ``f_hp`` [Hz] (a table's stroke), and a trapezoidal envelope
    (rise 15 %, decay over the last 35 %), normalised to a peak of 1.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    w = rng.normal(size=n)
    wg = 2 * math.pi * f_g
    b, a = scipy.signal.bilinear([2 * zeta_g * wg, wg**2], [1.0, 2 * zeta_g * wg, wg**2], fs=rate_hz)
    x = scipy.signal.lfilter(b, a, w)
    sos = scipy.signal.butter(2, f_hp, "highpass", fs=rate_hz, output="sos")
    x = scipy.signal.sosfiltfilt(sos, x)
    env = np.clip(np.minimum(t / (0.15 * duration), (duration - t) / (0.35 * duration)), 0.0, 1.0)
    x = x * env
    return x / np.max(np.abs(x)), t


def _story_forces(b: SyntheticBuilding, d: np.ndarray, kp: dict) -> np.ndarray:
    """(L-1,) story restoring forces [kN] at drifts ``d`` [m]."""
    k = np.asarray(b.stiffness)
    if b.effect == "softening":
        return k * d / np.sqrt(1.0 + (d / kp["d_s"]) ** 2)
    return k * d


def _rhs(b: SyntheticBuilding, kp: dict, y: np.ndarray, ag: float, m: np.ndarray, cst: np.ndarray):
    """Time derivative of the state y = [x (L), v (L), z, E, E_max, D] and the level forces."""
    L = m.size
    x = y[:L]
    v = y[L:2 * L]
    z = y[2 * L]
    E = y[2 * L + 1]
    emax = y[2 * L + 2]
    uy = b.u_y
    v0 = v[0]
    x0 = x[0]
    zv = z * v0
    sg = 1.0 if zv > 0.0 else (-1.0 if zv < 0.0 else 0.0)
    dz = (v0 / uy) * (1.0 - abs(z) ** b.eta * (b.gamma + b.beta * sg)) if b.qd > 0.0 else 0.0
    dD = 0.0
    if b.effect == "degradation":
        g = math.exp(-emax / kp["E_0"])
    elif b.effect == "recovering_softening":
        D = y[2 * L + 3]
        target = math.tanh(abs(x0) / kp["x_r"])
        dD = (target - D) / kp["tau_on"] if target > D else -D / kp["tau_rec"]
        g = 1.0 - kp["s"] * D
    else:
        g = 1.0
    f_iso = g * (b.qd * z + b.alpha * b.k_init * x0) + b.c_iso * v0
    if b.effect == "viscous_power":
        f_iso += kp["c_v"] * math.copysign(abs(v0) ** kp["a"], v0)
    elif b.effect == "stiffening":
        r = abs(x0) / kp["d_h"]
        f_iso += kp["k_h"] * kp["d_h"] * math.copysign(math.expm1(r) - r, x0)
    drift = x[1:] - x[:-1]
    dv = v[1:] - v[:-1]
    vs = _story_forces(b, drift, kp) + cst * dv  # story j's shear, resisting its drift
    force = np.zeros(L)  # story and isolator forces on each level
    force[1:] -= vs  # on the level above the story
    force[:-1] += vs  # on the level below
    force[0] -= f_iso
    acc_abs = force / m  # absolute accelerations a_i = x_i'' + a_g
    dE = b.qd * z * v0
    dEmax = max(dE, 0.0) if E >= emax else 0.0
    out = np.empty_like(y)
    out[:L] = v
    out[L:2 * L] = acc_abs - ag
    out[2 * L] = dz
    out[2 * L + 1] = dE
    out[2 * L + 2] = dEmax
    out[2 * L + 3] = dD
    return out, acc_abs, f_iso


def simulate_building(b: SyntheticBuilding, table_accel: np.ndarray, dt: float, *,
                      substeps: int = 10, state: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Response of ``b`` to ``table_accel`` [m/s^2] sampled at ``dt`` [s], noise-free.

    Returns ``(disp (n, L) relative to the table [m], accel (n, L) absolute [m/s^2],
    isolator force (n,) [kN], final state)``; ``state`` (from a previous call) carries the
    building's state (displacements, velocities, z, energies) into this record.
    """
    disp, _, acc, fiso, y = _simulate(b, table_accel, dt, substeps, state)
    return disp, acc, fiso, y


def _simulate(b, table_accel, dt, substeps, state):
    """:func:`simulate_building` with the velocities (n, L) [m/s] as well."""
    m = np.asarray(b.masses, dtype=float)
    L = m.size
    kp = b.effect_params()
    cst = 2.0 * b.zeta * np.asarray(b.stiffness) / b.omega1()
    y = np.zeros(2 * L + 4) if state is None else np.array(state, dtype=float)
    ag = np.asarray(table_accel, dtype=float)
    n = ag.size
    disp = np.empty((n, L))
    vel = np.empty((n, L))
    acc = np.empty((n, L))
    fiso = np.empty(n)
    h = dt / substeps
    _, a0, f0 = _rhs(b, kp, y, ag[0], m, cst)
    disp[0] = y[:L]
    vel[0] = y[L:2 * L]
    acc[0] = a0
    fiso[0] = f0
    for i in range(1, n):
        g0 = ag[i - 1]
        dg = (ag[i] - g0) / substeps
        for s in range(substeps):
            ga = g0 + dg * s
            k1 = _rhs(b, kp, y, ga, m, cst)[0]
            k2 = _rhs(b, kp, y + 0.5 * h * k1, ga + 0.5 * dg, m, cst)[0]
            k3 = _rhs(b, kp, y + 0.5 * h * k2, ga + 0.5 * dg, m, cst)[0]
            k4 = _rhs(b, kp, y + h * k3, ga + dg, m, cst)[0]
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        _, a_i, f_i = _rhs(b, kp, y, ag[i], m, cst)
        disp[i] = y[:L]
        vel[i] = y[L:2 * L]
        acc[i] = a_i
        fiso[i] = f_i
    return disp, vel, acc, fiso, y


DISP_NOISE_M = 5.0e-5
"""Default standard deviation of the displacement transducers' noise [m] (module docstring)."""


def synthetic_sequence(b: SyntheticBuilding, peaks: Sequence[float] = (1.0, 2.0, 3.0, 4.5), *,
                       seed: int = 0, noise: float = 0.02, disp_noise: float = DISP_NOISE_M,
                       duration: float = 80.0, tail_s: float = 10.0,
                       rate_hz: float = 50.0, substeps: int = 10, rest_s: float = 5.0,
                       motion_seed: int | None = None, prefix: str = "SYN") -> list[ShakeTableRun]:
    """Runs of ``b`` under one table motion scaled to ``peaks`` [m/s^2], in order, state carried.

    Each run records ``duration`` seconds [s] of table motion and then ``tail_s`` seconds of the
    building's free vibration (table at rest); between runs the building rests ``rest_s`` more
    seconds, unrecorded, as on a real table.  ``seed`` draws the noise of every channel
    (accelerations: ``noise`` x the channel's RMS; displacements: ``disp_noise`` [m], module
    docstring); ``motion_seed`` (default ``seed``) the table motion.  Each run's ``meta["truth"]``
    holds the building, the effect and its parameters.
    """
    if not peaks or any(not p > 0 for p in peaks):
        raise ValueError(f"peaks = {peaks!r}: expected positive table-acceleration peaks [m/s^2]")
    if not noise >= 0:
        raise ValueError(f"noise = {noise!r}: expected a fraction >= 0 of each acceleration channel's RMS")
    if not disp_noise >= 0:
        raise ValueError(f"disp_noise = {disp_noise!r}: expected a standard deviation >= 0 [m]")
    if not duration > 0 or not tail_s >= 0 or not rest_s >= 0:
        raise ValueError(f"duration = {duration!r}, tail_s = {tail_s!r}, rest_s = {rest_s!r}: expected "
                         "a duration > 0 and a tail and a rest >= 0 [s]")
    shape, t = table_motion(duration, rate_hz, seed=seed if motion_seed is None else motion_seed)
    n_tail = int(round(tail_s * rate_hz))
    if n_tail:
        shape = np.concatenate([shape, np.zeros(n_tail)])
        t = np.arange(shape.size) / rate_hz
    dt = 1.0 / rate_hz
    rng = np.random.default_rng([seed, 7])
    state = None
    runs = []
    n_rest = int(round(rest_s * rate_hz))
    L = len(b.masses)
    truth = {"effect": b.effect, "strength": b.strength, "params": b.effect_params(),
             "building": {k: v for k, v in b.__dict__.items() if k != "effect_kw"}}
    for k, peak in enumerate(peaks):
        ag = peak * shape
        disp, acc, fiso, state = simulate_building(b, ag, dt, substeps=substeps, state=state)
        if n_rest:
            _, _, _, state = simulate_building(b, np.zeros(n_rest), dt, substeps=substeps, state=state)
        if b.effect == "recovering_softening":  # the unrecorded hour between runs, at rest
            kp = b.effect_params()
            state[-1] *= math.exp(-kp["gap_s"] / kp["tau_rec"])
        # each run's displacements are measured from its own start (as the table's sensors)
        disp = disp - disp[0]

        def noisy(x):
            x = np.asarray(x, dtype=float)
            rms = np.sqrt(np.mean(x**2, axis=0))
            return x + noise * rms * rng.normal(size=x.shape)

        runs.append(ShakeTableRun(
            name=f"{prefix}{k + 1}", time=t.copy(), table_accel=noisy(ag), accel=noisy(acc),
            disp=disp + disp_noise * rng.normal(size=disp.shape), masses=np.asarray(b.masses, dtype=float),
            level_names=tuple(["base"] + [f"floor{j}" for j in range(1, L - 1)] + ["roof"]),
            source="", meta={"synthetic": True, "seed": seed, "noise": noise, "disp_noise_m": disp_noise,
                             "peak_table_accel": peak, "truth": truth, "isolator_force_true": fiso}))
    return runs


def energy_balance(b: SyntheticBuilding, table_accel: np.ndarray, dt: float, *, substeps: int = 10
                   ) -> dict[str, float]:
    """Energy terms [kN m] of a run from rest, by the trapezoidal rule on the outputs.

    Input E_in = -int a_g sum_i m_i x_i' dt; stored E_k + E_s (kinetic relative to the table,
    strain of the stories and of the isolators' elastic part); dissipated by the story dashpots
    and the whole isolation layer (int F_iso x_0' dt minus its stored elastic part).  The
    balance error is (E_in - E_k - E_s - E_d) / E_in.  Only for effects with a conservative
    superstructure (``none``, ``viscous_power``, ``stiffening``).
    """
    if b.effect in ("softening", "degradation"):
        raise ValueError(f"energy_balance: effect {b.effect!r} is not supported (its stored energy "
                         "is not the plain spring form)")
    disp, v, acc, fiso, _ = _simulate(b, table_accel, dt, substeps, None)
    m = np.asarray(b.masses, dtype=float)
    ag = np.asarray(table_accel, dtype=float)
    e_in = -np.trapezoid(ag * (v @ m), dx=dt)
    e_k = 0.5 * float(m @ v[-1] ** 2)
    k = np.asarray(b.stiffness)
    drift = np.diff(disp, axis=1)
    e_s = 0.5 * float(k @ drift[-1] ** 2)
    cst = 2.0 * b.zeta * k / b.omega1()
    e_d = float(np.trapezoid((np.diff(v, axis=1) ** 2) @ cst, dx=dt))
    e_iso = float(np.trapezoid(fiso * v[:, 0], dx=dt))
    return {"input": e_in, "kinetic": e_k, "strain": e_s, "story_damping": e_d,
            "isolation": e_iso, "error": (e_in - e_k - e_s - e_d - e_iso) / e_in}


def with_effect(b: SyntheticBuilding, effect: str, strength: float, **kw) -> SyntheticBuilding:
    """``b`` with another withheld effect."""
    return replace(b, effect=effect, strength=strength, effect_kw=dict(kw))
