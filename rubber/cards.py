"""SDRSI material inputs from a fitted PRF set: MSC Marc and Abaqus PRF cards, characteristic curves
(equilibrium, instantaneous, relaxation, creep) and equivalent linear properties, as JSON and CSV.

Units: MPa, s.  tau conventions: the fit's C1 is for tau = ||dev sigma||_F (Bergstrom's code, Marc as
used by the study).  Abaqus' Bergstrom-Boyce creep law uses the equivalent (Mises-type) deviatoric
Kirchhoff stress, so A = C1_mises = C1_frob (2/3)^((C3+1)/2) (exact,
``docs/reference/prf_model.md`` section 4).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from . import integrate as _k
from .prf import PRFModel, PRFParams, _as_model, equilibrium_stress, instantaneous_stress, simulate


def marc_card(params: PRFParams | PRFModel, tau: str = "frobenius") -> dict:
    """Marc inputs: Yeoh equilibrium (C10, C20, C30) and per network an Arruda-Boyce (Eight-Chain)
    spring (nkT, N) with the Bergstrom-Boyce flow gamma_dot = C1 (lam_ch - 1 + xi)^C2 tau^C3.
    ``tau`` states the convention of the given C1; the card is written for Frobenius tau."""
    m = _as_model(params)
    e = m.equilibrium
    nets = []
    for i, c in enumerate(m.chains, start=1):
        c1 = c.C1 if tau == "frobenius" else c.C1 * (2.0 / 3.0) ** (-(c.C3 + 1.0) / 2.0)
        nets.append({"network": i, "spring": "arruda_boyce", "nkT": c.nkt, "N": c.N,
                     "lambda_lock": math.sqrt(c.N), "mu0": c.mu0,
                     "flow": "bergstrom_boyce", "C1": c1, "C2": c.C2, "C3": c.C3, "xi": c.xi})
    return {"program": "MSC Marc", "units": "MPa, s", "tau": "frobenius",
            "equilibrium": {"model": "yeoh", "C10": e.C10, "C20": e.C20, "C30": e.C30},
            "networks": nets}


def abaqus_card(params: PRFParams | PRFModel, tau: str = "frobenius") -> tuple[str, dict]:
    """Abaqus PRF keyword block and its data.

    Abaqus PRF shares one hyperelastic law among all networks (network i carries the fraction
    SRATIO_i of it), so the Eight-Chain springs are represented by their small-strain moduli
    (exact for small strains; at lambda = 1.3 the error is below ~1 % for N >= 2).  The Yeoh
    coefficients are scaled to the total instantaneous modulus and each network gets
    SRATIO = mu0_i / mu0_total.  Creep law: BERGSTROM-BOYCE with A = C1_mises, m = C3, C = C2, E = xi.
    """
    m = _as_model(params)
    mu = np.array(m.mu0)
    tot = float(mu.sum())
    scale = tot / mu[0] if mu[0] > 0 else 1.0
    e = m.equilibrium
    lines = ["*MATERIAL, NAME=SDRSI_PU", "*HYPERELASTIC, YEOH",
             f"{e.C10 * scale:.8g}, {e.C20 * scale:.8g}, {e.C30 * scale:.8g}, 0., 0., 0."]
    nets = []
    for i, c in enumerate(m.chains, start=1):
        a = c.C1 * (2.0 / 3.0) ** ((c.C3 + 1.0) / 2.0) if tau == "frobenius" else c.C1
        sr = c.mu0 / tot
        lines += [f"*VISCOELASTIC, NONLINEAR, NETWORKID={i}, SRATIO={sr:.8g}, LAW=BERGSTROM-BOYCE",
                  f"{a:.8g}, {c.C3:.8g}, {c.C2:.8g}, {c.xi:.8g}"]
        nets.append({"network": i, "SRATIO": sr, "A": a, "m": c.C3, "C": c.C2, "E": c.xi})
    data = {"program": "Abaqus", "units": "MPa, s", "yeoh_instantaneous": [e.C10 * scale, e.C20 * scale,
            e.C30 * scale], "networks": nets, "note": abaqus_card.__doc__.split("\n\n")[1].strip()}
    return "\n".join(lines) + "\n", data


def relaxation_curve(params, stretch: float = 1.2, *, rate: float = 10.0, hold: float = 100.0,
                     n: int = 200, tau: str = "frobenius") -> tuple[np.ndarray, np.ndarray]:
    """Nominal stress (MPa) in a hold at ``stretch`` after a ramp at ``rate`` (1/s); time from hold start."""
    t_r = abs(stretch - 1.0) / rate
    th = np.concatenate([[0.0], np.geomspace(1e-4, hold, n)])
    t = np.concatenate([[0.0], t_r + th])
    lam = np.concatenate([[1.0], np.full(th.size, stretch)])
    r = simulate(params, t, lam, tau=tau)
    return th, r.nominal[1:]


def creep_curve(params, stress: float = 1.0, *, hold: float = 100.0, n: int = 200, tau: str = "frobenius"
                ) -> tuple[np.ndarray, np.ndarray]:
    """Stretch during a hold at constant nominal stress ``stress`` (MPa), applied instantaneously.

    Each chain's u advances by backward Euler on a geometric time grid with sub-steps limited by the
    chain's stiffness; lambda is solved from P(lambda, u) = stress at every sub-step (bisection).
    """
    m = _as_model(params)
    eq, ch = m.arrays(tau)

    def p_of(lam, u):
        s = _k.yeoh_delta(lam, eq[0], eq[1], eq[2])
        for k in range(ch.shape[0]):
            s += _k.ec_delta(lam / math.exp(u[k]), ch[k, 0], ch[k, 1])[0]
        return s / lam

    def solve_lam(u):
        lo, hi = 1e-3, 1.0
        while p_of(hi, u) < stress:
            hi *= 1.5
            if hi > 1e3:
                raise ValueError(f"creep_curve: stress {stress} MPa exceeds the model's range")
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if p_of(mid, u) < stress else (lo, mid)
        return 0.5 * (lo + hi)

    times = np.concatenate([[0.0], np.geomspace(1e-4, hold, n)])
    u = np.zeros(ch.shape[0])
    lam = solve_lam(u)
    out = [lam]
    for i in range(1, times.size):
        t, t_end = times[i - 1], times[i]
        while t < t_end:
            rates = [_k.flow_rate(u[k], lam, ch[k, 0], ch[k, 1], ch[k, 2], ch[k, 3], ch[k, 4], ch[k, 5])
                     for k in range(ch.shape[0])]
            stiff = max([abs(r[1]) for r in rates] + [1e-12])
            h = min(t_end - t, 0.2 / stiff)
            u = u + h * np.array([r[0] for r in rates])
            lam = solve_lam(u)
            t += h
        out.append(lam)
    return times, np.array(out)


def equivalent_linear(params, amplitude: float = 0.05, frequency: float = 1.0, *, prestretch: float = 1.0,
                      n_cycles: int = 4, tau: str = "frobenius") -> dict[str, float]:
    """Secant Young's modulus (MPa) and loss factor of the steady loop lambda = lam0 (1 + a sin 2 pi f t).

    E_sec = (P_max - P_min) / (2 a lam0); eta = W_d / (pi a lam0 P_amp), W_d the loop area (MJ/m^3) of
    the last cycle, P_amp = (P_max - P_min)/2 (the linear-viscoelastic definition eta = E''/E').
    """
    if not 0 < amplitude < 1:
        raise ValueError(f"amplitude = {amplitude!r}: expected a strain amplitude in (0, 1)")
    if not frequency > 0:
        raise ValueError(f"frequency = {frequency!r}: expected > 0 Hz")
    npc = 400
    t = np.linspace(0.0, n_cycles / frequency, n_cycles * npc + 1)
    lam = prestretch * (1.0 + amplitude * np.sin(2 * np.pi * frequency * t))
    r = simulate(params, t, lam, tau=tau)
    sl = slice((n_cycles - 1) * npc, None)
    p, lm = r.nominal[sl], r.stretch[sl]
    wd = float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(lm)))
    pa = 0.5 * (p.max() - p.min())
    ea = amplitude * prestretch
    return {"amplitude": amplitude, "frequency_Hz": frequency, "prestretch": prestretch,
            "E_secant_MPa": pa / ea, "G_secant_MPa": pa / ea / 3.0, "loss_factor": wd / (math.pi * ea * pa),
            "dissipated_per_cycle_MJ_m3": wd}


def write_cards(params, out_dir: str | Path, *, amplitudes=(0.01, 0.05, 0.1, 0.2), frequency: float = 1.0,
                tau: str = "frobenius") -> dict:
    """Write material.json (Marc, Abaqus, equivalent linear), abaqus.inp and curves.csv into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    inp, abq = abaqus_card(params, tau)
    eql = [equivalent_linear(params, a, frequency, tau=tau) for a in amplitudes]
    doc = {"params": params.as_dict() if isinstance(params, PRFParams) else str(params),
           "marc": marc_card(params, tau), "abaqus": abq, "equivalent_linear": eql}
    (out / "material.json").write_text(json.dumps(doc, indent=2))
    (out / "abaqus.inp").write_text(inp)
    lam = np.linspace(0.7, 1.5, 81)
    tr, pr = relaxation_curve(params, tau=tau)
    tc, lc = creep_curve(params, tau=tau)
    with (out / "curves.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["stretch", "P_equilibrium_MPa", "P_instantaneous_MPa"])
        for a, b, c in zip(lam, equilibrium_stress(params, lam), instantaneous_stress(params, lam)):
            w.writerow([f"{a:.6g}", f"{b:.8g}", f"{c:.8g}"])
    with (out / "relaxation_creep.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "P_relaxation_MPa_at_1.2", "stretch_creep_at_1MPa"])
        for a, b, c in zip(tr, pr, lc):
            w.writerow([f"{a:.6g}", f"{b:.8g}", f"{c:.8g}"])
    return doc
