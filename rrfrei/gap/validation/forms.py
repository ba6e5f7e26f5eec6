"""Generator forms: each unmodelled effect written three ways, independently of the catalogue.

Every form turns the base law's response on one protocol into the response of a bearing that has
the effect, in plain NumPy (no catalogue kernel): most post-process the base force ``F_b(t)``,
the series forms (``slip``, pinching by ``slip_lock``) solve the base law in series with an
element of their own by bisection, sample by sample.  The three forms of an effect differ from
the catalogue kernel (:mod:`rrfrei.laws.effects`) and from each other in functional shape, onset
and rate, so a diagnosis that was tuned to the catalogue's shapes does not pass by construction.

Scales of a :class:`Signal` (all from the base law on protocol 1, the calibration protocol):
``F_pk`` peak |F_b| [kN], ``W_1`` its cumulative absolute work [kN m], ``DD``/``DM`` design and
maximum displacement [m], ``v_ref = 2 pi DM / 10 s`` the peak velocity of its largest cycle
[m/s], ``k2 = alpha1 k_init`` the post-yield stiffness [kN/m]; ``q_h = F_b - k2 u`` is the
hysteretic part of the base force (``|q_h| <= qd``, both base laws have ``alpha2 = 0``),
``u_max`` the largest |u| before the current sample, ``W`` the cumulative absolute work
``int |F_b du|`` [kN m], ``v`` the central-difference velocity [m/s].  ``size`` is the form's one
magnitude, drawn per seed over the range below (small to large).

============  ==================  ==========================================================  ===============
effect        form                force of the bearing with the effect                        size range
============  ==================  ==========================================================  ===============
degradation   energy_exp          F_b (1 - D (1 - exp(-W / (0.5 W_1))))                       D 0.10-0.40
degradation   energy_sqrt         F_b max(1 - D sqrt(W / W_1), 0.2)  (infinite initial rate)  D 0.08-0.30
degradation   cycle_count         F_b (1 - D (1 - exp(-N / 6))), N cycles run (any amplitude) D 0.10-0.40
mullins       sine                F_b (1 - m sin(pi/2 (1 - r))), r = |u| / u_max < 1          m 0.15-0.45
mullins       quadratic           F_b (1 - m (1 - r)^2), r < 1 (softening only near u = 0)    m 0.30-0.70
mullins       erf_energy          F_b (1 - m erf((1 - r^2) / 0.5)), r < 1 (Ogden-Roxburgh)    m 0.10-0.35
rollover      smooth_hinge        F_b - s F_pk sgn(u) h,  h = softplus((|u|-12 mm)/3 mm)      s 0.05-0.25
rollover      quadratic           F_b - s F_pk sgn(u) ((|u| - DD/2)_+ / (DM - DD/2))^2        s 0.05-0.25
rollover      cubic               F_b - s F_pk (u / DM)^3  (no onset)                         s 0.05-0.25
rate          maxwell             F_b + q,  dq/dt = k_m (v - q / c), c / k_m = 0.3 s (memory) s 0.08-0.30
rate          tanh_friction       F_b + s F_pk tanh(v / (0.3 v_ref))  (saturating)            s 0.04-0.16
rate          friction_velocity   k2 u + q_h (1 + s (1 - exp(-|v| / (0.3 v_ref))))            s 0.10-0.40
asymmetry     tanh_disp           F_b (1 + a tanh(u / 2 mm))                                  a 0.05-0.20
asymmetry     sided_stiffness     F_b + a (F_pk / DM) max(u, 0)  (stiffer for u > 0 only)     a 0.05-0.30
asymmetry     sided_strength      k2 u + q_h (1 + a [q_h > 0])  (stronger for F > 0 only)     a 0.10-0.40
slip          elastic_plastic     base in series with an elastic-plastic slider (20 k_init)   c 0.70-0.92
slip          smooth_slider       base in series with a smooth (Bouc-Wen n = 1) slider,       c 0.70-0.92
                                  yield displacement F_s / (5 k_init)
slip          stick_slip          elastic-plastic slider, static capacity 1.2 x kinetic,      c 0.60-0.78
                                  decaying over 1 mm of slip, reset at each stick
stiffening    cubic               F_b + s F_pk (u / DM)^3                                     s 0.05-0.25
stiffening    exponential         F_b + s F_pk sgn(u) (e^x - 1 - x) / norm, x = |u| / 0.25 DM s 0.05-0.25
stiffening    smooth_knee         F_b + s F_pk sgn(u) h, h = softplus((|u| - 12 mm) / 3 mm)   s 0.05-0.25
pinching      gaussian_slack      F_b (1 - p exp(-(u / 0.2 u_max)^2 / 2)) once u_max > 0      p 0.30-0.70
pinching      slip_lock           base in series with an elastic gap: soft (0.05 k_init) for  g 0.05-0.20
                                  |x| < g DD, stiff (50 k_init) beyond
pinching      bwbn_like           k2 u + qd z (1 - p exp(-(z / 0.6)^2 )), z = q_h / qd        p 0.60-0.95
scragging     power               F_b (1 - s (min(u_max, 1.5 DM) / DM)^2), u_max incl. now    s 0.08-0.25
scragging     linear_saturating   F_b (1 - s min(u_max / DD, 1))                              s 0.08-0.25
scragging     first_large_cycle   F_b (1 - s / (1 + exp(-(u_max - 0.8 DD) / 0.05 DD)))        s 0.08-0.25
============  ==================  ==========================================================  ===============

(F_pk etc.: the ``Signal`` scales; the catalogue's shapes are, for comparison: degradation
``1 / (1 + c E_max)`` in the base law's cumulative work, mullins linear in ``1 - r``, rollover a
kinked linear hinge, rate ``c sgn(v) |v|^a``, asymmetry ``1 + a sgn(F_b)``, slip a rigid-plastic
slider solved by Newton; the new effects of issue 12 (stiffening, pinching, scragging) have their
own kernels, and these forms were written from the issue's physics, not from them.  The kernels
have since grown shape parameters and the diagnosis fits some of them as *variants*
(:class:`rrfrei.laws.effects.Variant`); how far each form stays from the catalogue as fitted is
measured in docs/gap/validation.md, and the forms were not changed.)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.special import erf

__all__ = ["EPSlider", "Form", "FORMS", "Signal", "forms_of", "series_solve"]


@dataclass(frozen=True)
class Signal:
    """The base law's response on one protocol and the scales the forms use (see module docstring).

    Attributes
    ----------
    t, u, fb : time [s], displacement [m], base-law force [kN] (equal length).
    step : the base law's jitted step kernel ``step(p, sc, u, v, dt, st)``; ``p`` its packed
        parameters; ``state0`` its virgin state (for the series forms).
    f_pk : peak |F_b| on protocol 1 [kN]; ``w1`` : cumulative |work| of F_b on protocol 1 [kN m].
    dd, dm : design and maximum displacement [m]; ``k_init``, ``k2``, ``qd`` : base stiffnesses
        [kN/m] and characteristic strength [kN].
    """

    t: np.ndarray
    u: np.ndarray
    fb: np.ndarray
    step: Callable
    p: np.ndarray
    state0: np.ndarray
    f_pk: float
    w1: float
    dd: float
    dm: float
    k_init: float
    k2: float
    qd: float

    @property
    def v_ref(self) -> float:
        """Peak velocity of the largest cycle of protocol 1 [m/s] (period 10 s)."""
        return 2.0 * math.pi * self.dm / 10.0

    @property
    def qh(self) -> np.ndarray:
        """Hysteretic part of the base force, F_b - k2 u [kN]."""
        return self.fb - self.k2 * self.u


@dataclass(frozen=True)
class Form:
    """One data-generating form of an effect: ``force(signal, size) -> F`` [kN]."""

    effect: str
    name: str
    equation: str
    size_range: tuple[float, float]
    force: Callable[[Signal, float], np.ndarray]

    @property
    def label(self) -> str:
        return f"{self.effect}/{self.name}"

    def size_at(self, q: float) -> float:
        """The size at quantile ``q`` in [0, 1] of the range (linear)."""
        lo, hi = self.size_range
        return lo + float(q) * (hi - lo)


# --- history helpers ------------------------------------------------------------------------------
def _work(u: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Cumulative absolute work int |F du| [kN m] (trapezoid), 0 at the first sample."""
    return np.concatenate([[0.0], np.cumsum(np.abs(0.5 * (f[1:] + f[:-1]) * np.diff(u)))])


def _prev_max(u: np.ndarray) -> np.ndarray:
    """Largest |u| strictly before each sample (0 at the first)."""
    return np.concatenate([[0.0], np.maximum.accumulate(np.abs(u))[:-1]])


def _velocity(t: np.ndarray, u: np.ndarray) -> np.ndarray:
    return np.gradient(u, t)


def _cycle_count(u: np.ndarray, floor: float) -> np.ndarray:
    """Continuous count of cycles run: each half-cycle adds its travel / (2 x its amplitude), so
    every cycle counts one whatever its amplitude (the amplitude is the last peak, or |u| while
    it grows, at least ``floor``)."""
    n = np.zeros(u.size)
    amp = floor
    peak = floor
    for i in range(1, u.size):
        du = u[i] - u[i - 1]
        peak = max(peak, abs(u[i]))
        if i + 1 < u.size and (u[i + 1] - u[i]) * du < 0.0:  # a reversal at sample i
            amp = max(peak, floor)
            peak = floor
        n[i] = n[i - 1] + abs(du) / (4.0 * max(amp, peak))
    return n


def _softplus_hinge(x: np.ndarray, onset: float, width: float) -> np.ndarray:
    return width * np.logaddexp(0.0, (x - onset) / width)


# --- series solves ---------------------------------------------------------------------------------
class EPSlider:
    """Elastic-plastic slider: stiffness ``k``, capacity ``cap(slip travel)`` [kN]."""

    def __init__(self, k: float, fs: float, static: float = 1.0, decay: float = 1e-3) -> None:
        self.k, self.fs, self.static, self.decay = k, fs, static, decay
        self.xp = 0.0  # plastic slip [m]
        self.travel = 0.0  # slip travel since the last stick [m]

    def capacity(self) -> float:
        return self.fs * (1.0 + (self.static - 1.0) * math.exp(-self.travel / self.decay))

    def force(self, x: float) -> float:
        c = self.capacity()
        return min(max(self.k * (x - self.xp), -c), c)

    def commit(self, x: float) -> None:
        c = self.capacity()
        q = self.k * (x - self.xp)
        if abs(q) > c:
            new = x - math.copysign(c, q) / self.k
            self.travel += abs(new - self.xp)
            self.xp = new
        else:
            self.travel = 0.0  # stuck: the static capacity recovers


class _SmoothSlider:
    """Rate-independent Bouc-Wen slider with n = 1, beta = gamma = 1/2 (closed form per step):
    F = F_s z, dz/dx = (1 - |z| [z dx > 0]) / y_s."""

    def __init__(self, fs: float, ys: float) -> None:
        self.fs, self.ys = fs, ys
        self.xc = 0.0
        self.zc = 0.0

    def _z(self, x: float) -> float:
        dx = x - self.xc
        if dx == 0.0:
            return self.zc
        s = 1.0 if dx > 0 else -1.0
        z0, d = s * self.zc, abs(dx)  # in the frame of the motion
        if z0 < 0.0:  # unloading: linear until z = 0
            d0 = -z0 * self.ys
            if d <= d0:
                return s * (z0 + d / self.ys)
            d -= d0
            z0 = 0.0
        return s * (1.0 - (1.0 - z0) * math.exp(-d / self.ys))

    def force(self, x: float) -> float:
        return self.fs * self._z(x)

    def commit(self, x: float) -> None:
        self.zc = self._z(x)
        self.xc = x


class _Gap:
    """Elastic gap (slip-lock): stiffness ``k_soft`` for |x| < g, ``k_hard`` beyond (no memory)."""

    def __init__(self, g: float, k_soft: float, k_hard: float) -> None:
        self.g, self.k_soft, self.k_hard = g, k_soft, k_hard

    def force(self, x: float) -> float:
        a = abs(x)
        f = self.k_soft * min(a, self.g) + self.k_hard * max(a - self.g, 0.0)
        return math.copysign(f, x)

    def commit(self, x: float) -> None:
        pass


def series_solve(sig: Signal, element) -> np.ndarray:
    """Force of the base law in series with ``element`` (``force(x)``, ``commit(x)``, force
    non-decreasing in its displacement x): per sample, bisection on x for
    ``F_b(u - x) = F_e(x)`` (the base law evaluated from its committed state at every trial, so a
    law with a sticky trial variable starts each trial fresh); quasi-static (v = 0, dt = 1)."""
    n = sig.u.size
    out = np.empty(n)
    sc = np.array(sig.state0, dtype=float)
    st = sc.copy()
    p = sig.p
    step = sig.step
    xc = 0.0

    def base(y: float) -> float:
        st[:] = sc
        f, _, status = step(p, sc, y, 0.0, 1.0, st)
        if status != 0:
            raise ArithmeticError(f"base law failed in the series solve (status {status})")
        return f

    for i in range(n):
        ui = float(sig.u[i])

        def gap(x: float, ui: float = ui) -> float:
            return base(ui - x) - element.force(x)

        lo = hi = xc
        w = 1e-6
        while gap(lo) < 0.0:
            lo -= w
            w *= 2.0
        w = 1e-6
        while gap(hi) > 0.0:
            hi += w
            w *= 2.0
        for _ in range(52):
            mid = 0.5 * (lo + hi)
            if gap(mid) > 0.0:
                lo = mid
            else:
                hi = mid
            if hi - lo < 1e-13:
                break
        x = 0.5 * (lo + hi)
        out[i] = base(ui - x)
        sc[:] = st
        element.commit(x)
        xc = x
    return out


# --- the forms -------------------------------------------------------------------------------------
def _deg_exp(s: Signal, d: float) -> np.ndarray:
    return s.fb * (1.0 - d * (1.0 - np.exp(-_work(s.u, s.fb) / (0.5 * s.w1))))


def _deg_sqrt(s: Signal, d: float) -> np.ndarray:
    return s.fb * np.maximum(1.0 - d * np.sqrt(_work(s.u, s.fb) / s.w1), 0.2)


def _deg_cycles(s: Signal, d: float) -> np.ndarray:
    return s.fb * (1.0 - d * (1.0 - np.exp(-_cycle_count(s.u, 0.05 * s.dd) / 6.0)))


def _ratio(s: Signal) -> np.ndarray:
    um = _prev_max(s.u)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(um > 0, np.abs(s.u) / um, 1.0)
    return np.clip(r, 0.0, 1.0)


def _mul_sine(s: Signal, m: float) -> np.ndarray:
    r = _ratio(s)
    return s.fb * (1.0 - np.where(r < 1.0, m * np.sin(0.5 * math.pi * (1.0 - r)), 0.0))


def _mul_quad(s: Signal, m: float) -> np.ndarray:
    r = _ratio(s)
    return s.fb * (1.0 - np.where(r < 1.0, m * (1.0 - r) ** 2, 0.0))


def _mul_erf(s: Signal, m: float) -> np.ndarray:
    r = _ratio(s)
    return s.fb * (1.0 - np.where(r < 1.0, m * erf((1.0 - r**2) / 0.5), 0.0))


def _hinge_shape(s: Signal) -> np.ndarray:
    h = _softplus_hinge(np.abs(s.u), 0.012, 0.003)
    return np.sign(s.u) * h / _softplus_hinge(np.array(s.dm), 0.012, 0.003)


def _quad_shape(s: Signal) -> np.ndarray:
    on = 0.5 * s.dd
    return np.sign(s.u) * (np.maximum(np.abs(s.u) - on, 0.0) / (s.dm - on)) ** 2


def _cubic_shape(s: Signal) -> np.ndarray:
    return (s.u / s.dm) ** 3


def _exp_shape(s: Signal) -> np.ndarray:
    lam = 0.25 * s.dm

    def e(x):
        return np.expm1(x / lam) - x / lam

    return np.sign(s.u) * e(np.abs(s.u)) / e(s.dm)


def _roll(shape):
    return lambda s, size: s.fb - size * s.f_pk * shape(s)


def _stiff(shape):
    return lambda s, size: s.fb + size * s.f_pk * shape(s)


def _rate_maxwell(s: Signal, size: float) -> np.ndarray:
    tau = 0.3
    c = size * s.f_pk / s.v_ref  # dashpot [kN s/m]; spring k_m = c / tau
    q = np.zeros(s.u.size)
    for i in range(1, s.u.size):
        dt = s.t[i] - s.t[i - 1]
        a = math.exp(-dt / tau)
        q[i] = q[i - 1] * a + c * (1.0 - a) * (s.u[i] - s.u[i - 1]) / dt
    return s.fb + q


def _rate_tanh(s: Signal, size: float) -> np.ndarray:
    return s.fb + size * s.f_pk * np.tanh(_velocity(s.t, s.u) / (0.3 * s.v_ref))


def _rate_friction(s: Signal, size: float) -> np.ndarray:
    v = _velocity(s.t, s.u)
    return s.k2 * s.u + s.qh * (1.0 + size * (1.0 - np.exp(-np.abs(v) / (0.3 * s.v_ref))))


def _asym_tanh(s: Signal, a: float) -> np.ndarray:
    return s.fb * (1.0 + a * np.tanh(s.u / 2e-3))


def _asym_stiff(s: Signal, a: float) -> np.ndarray:
    return s.fb + a * s.f_pk / s.dm * np.maximum(s.u, 0.0)


def _asym_strength(s: Signal, a: float) -> np.ndarray:
    qh = s.qh
    return s.k2 * s.u + qh * (1.0 + a * (qh > 0.0))


def _slip_ep(s: Signal, c: float) -> np.ndarray:
    return series_solve(s, EPSlider(20.0 * s.k_init, c * s.f_pk))


def _slip_smooth(s: Signal, c: float) -> np.ndarray:
    fs = c * s.f_pk
    return series_solve(s, _SmoothSlider(fs, fs / (5.0 * s.k_init)))


def _slip_stick(s: Signal, c: float) -> np.ndarray:
    return series_solve(s, EPSlider(50.0 * s.k_init, c * s.f_pk, static=1.2, decay=1e-3))


def _pin_gauss(s: Signal, p: float) -> np.ndarray:
    um = _prev_max(s.u)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(um > 0, s.u / (0.2 * um), np.inf)
    return s.fb * (1.0 - p * np.exp(-0.5 * x**2))


def _pin_lock(s: Signal, g: float) -> np.ndarray:
    return series_solve(s, _Gap(g * s.dd, 0.05 * s.k_init, 50.0 * s.k_init))


def _pin_bwbn(s: Signal, p: float) -> np.ndarray:
    z = s.qh / s.qd
    return s.k2 * s.u + s.qd * z * (1.0 - p * np.exp(-((z / 0.6) ** 2)))


def _scrag(g):
    def force(s: Signal, size: float) -> np.ndarray:
        um = np.maximum.accumulate(np.abs(s.u))
        return s.fb * (1.0 - size * g(s, um))

    return force


FORMS: dict[str, tuple[Form, ...]] = {
    "degradation": (
        Form("degradation", "energy_exp", "F_b (1 - D (1 - exp(-W / 0.5 W_1)))", (0.10, 0.40), _deg_exp),
        Form("degradation", "energy_sqrt", "F_b max(1 - D sqrt(W / W_1), 0.2)", (0.08, 0.30), _deg_sqrt),
        Form("degradation", "cycle_count", "F_b (1 - D (1 - exp(-N / 6)))", (0.10, 0.40), _deg_cycles),
    ),
    "mullins": (
        Form("mullins", "sine", "F_b (1 - m sin(pi/2 (1 - r)))", (0.15, 0.45), _mul_sine),
        Form("mullins", "quadratic", "F_b (1 - m (1 - r)^2)", (0.30, 0.70), _mul_quad),
        Form("mullins", "erf_energy", "F_b (1 - m erf((1 - r^2) / 0.5))", (0.10, 0.35), _mul_erf),
    ),
    "rollover": (
        Form("rollover", "smooth_hinge", "F_b - s F_pk sgn(u) softplus hinge at 12 mm, width 3 mm",
             (0.05, 0.25), _roll(_hinge_shape)),
        Form("rollover", "quadratic", "F_b - s F_pk sgn(u) ((|u| - DD/2)_+ / (DM - DD/2))^2",
             (0.05, 0.25), _roll(_quad_shape)),
        Form("rollover", "cubic", "F_b - s F_pk (u / DM)^3", (0.05, 0.25), _roll(_cubic_shape)),
    ),
    "rate": (
        Form("rate", "maxwell", "F_b + q, dq/dt = k_m (v - q / c), c / k_m = 0.3 s", (0.08, 0.30),
             _rate_maxwell),
        Form("rate", "tanh_friction", "F_b + s F_pk tanh(v / 0.3 v_ref)", (0.04, 0.16), _rate_tanh),
        Form("rate", "friction_velocity", "k2 u + q_h (1 + s (1 - exp(-|v| / 0.3 v_ref)))", (0.10, 0.40),
             _rate_friction),
    ),
    "asymmetry": (
        Form("asymmetry", "tanh_disp", "F_b (1 + a tanh(u / 2 mm))", (0.05, 0.20), _asym_tanh),
        Form("asymmetry", "sided_stiffness", "F_b + a (F_pk / DM) max(u, 0)", (0.05, 0.30), _asym_stiff),
        Form("asymmetry", "sided_strength", "k2 u + q_h (1 + a [q_h > 0])", (0.10, 0.40), _asym_strength),
    ),
    "slip": (
        Form("slip", "elastic_plastic", "series elastic-plastic slider, k 20 k_init, capacity c F_pk",
             (0.70, 0.92), _slip_ep),
        Form("slip", "smooth_slider", "series Bouc-Wen (n = 1) slider, capacity c F_pk", (0.70, 0.92),
             _slip_smooth),
        Form("slip", "stick_slip", "series slider, static 1.2 c F_pk decaying to c F_pk over 1 mm",
             (0.60, 0.78), _slip_stick),
    ),
    "stiffening": (
        Form("stiffening", "cubic", "F_b + s F_pk (u / DM)^3", (0.05, 0.25), _stiff(_cubic_shape)),
        Form("stiffening", "exponential", "F_b + s F_pk sgn(u) (e^x - 1 - x) / norm, x = |u| / 0.25 DM",
             (0.05, 0.25), _stiff(_exp_shape)),
        Form("stiffening", "smooth_knee", "F_b + s F_pk sgn(u) softplus hinge at 12 mm, width 3 mm",
             (0.05, 0.25), _stiff(_hinge_shape)),
    ),
    "pinching": (
        Form("pinching", "gaussian_slack", "F_b (1 - p exp(-(u / 0.2 u_max)^2 / 2))", (0.30, 0.70),
             _pin_gauss),
        Form("pinching", "slip_lock", "series elastic gap g DD: 0.05 k_init inside, 50 k_init beyond",
             (0.05, 0.20), _pin_lock),
        Form("pinching", "bwbn_like", "k2 u + qd z (1 - p exp(-(z / 0.6)^2)), z = q_h / qd", (0.60, 0.95),
             _pin_bwbn),
    ),
    "scragging": (
        Form("scragging", "power", "F_b (1 - s (min(u_max, 1.5 DM) / DM)^2)", (0.08, 0.25),
             _scrag(lambda s, um: (np.minimum(um, 1.5 * s.dm) / s.dm) ** 2)),
        Form("scragging", "linear_saturating", "F_b (1 - s min(u_max / DD, 1))", (0.08, 0.25),
             _scrag(lambda s, um: np.minimum(um / s.dd, 1.0))),
        Form("scragging", "first_large_cycle", "F_b (1 - s / (1 + exp(-(u_max - 0.8 DD) / 0.05 DD)))",
             (0.08, 0.25), _scrag(lambda s, um: 1.0 / (1.0 + np.exp(-(um - 0.8 * s.dd) / (0.05 * s.dd))))),
    ),
}
"""Effect -> its generator forms (the module table), for every effect of issue 12's catalogue."""


def forms_of(effect: str) -> tuple[Form, ...]:
    """The generator forms of ``effect`` (ValueError naming the known effects otherwise)."""
    try:
        return FORMS[effect]
    except KeyError:
        raise ValueError(f"effect must be one of {', '.join(FORMS)}, got {effect!r}") from None
