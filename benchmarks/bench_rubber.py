"""bench_rubber: one protocol-1 evaluation of the PRF model (case A) against scipy Radau (rtol 1e-6)
in the same run, at the accuracy max|P - P_ref| / max|P_ref| <= 1e-4 (P_ref: Radau rtol 1e-10);
cold start; and a full 11-parameter CMA-ES fit with restarts (2 processes, one per core).

``python benchmarks/bench_rubber.py --multirate`` instead times the CLI fit of the seeded synthetic
12-test acrylic set (3 stretch rates x 4 maximum stretches, load-unload, 1 % noise, kPa CSVs) with
``--bounds auto`` (issue 16.3: at most 10 minutes on 2 cores) and compares the recovered identifiable
combinations with the truth (section ``bench_rubber_multirate``)."""

from __future__ import annotations

import math
import sys
import time
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))
from _results import write_section  # noqa: E402

t_import = time.perf_counter()
import rubber  # noqa: E402, F401  (timed: cold import)
from rubber import PRESETS, fit, protocol1, simulate  # noqa: E402
from rubber.study import synthetic_test  # noqa: E402


def radau(p, t, lam, rtol, atol=1e-12):
    """Both chains as one 2-state system, restarted at kinks (Frobenius tau, literal form)."""
    d = p.as_dict()
    ch = [tuple(d[k + "_" + c] for k in ("nkt", "N", "C1", "C2", "C3")) for c in "BC"]
    xi = d["xi"]

    def w1(i1, nkt, n):
        x = i1 / n
        return nkt * (0.5 + x / 10 + 33 / 1050 * x**2 + 76 / 7000 * x**3 + 2595 / 673750 * x**4)

    def rhs(tt, y, a, b):
        lt = lam[a] + (lam[b] - lam[a]) * (tt - t[a]) / (t[b] - t[a])
        out = []
        for (nkt, n, c1, c2, c3), yk in zip(ch, y):
            lv = math.exp(min(yk, 50.0))
            le = lt / lv
            dl = 2 * w1(le * le + 2 / le, nkt, n) * (le * le - 1 / le)
            lch = math.sqrt(max((lv * lv + 2 / lv) / 3, 1.0))
            r = math.sqrt(2 / 3) * c1 * (lch - 1 + xi) ** c2 * (math.sqrt(2 / 3) * abs(dl)) ** c3
            out.append(math.copysign(r, dl))
        return out

    s = np.diff(lam) / np.diff(t)
    kinks = [0] + [i for i in range(1, s.size) if abs(s[i] - s[i - 1]) > 1e-12] + [t.size - 1]
    u = np.zeros((2, t.size))
    y0 = [0.0, 0.0]
    for a, b in zip(kinks[:-1], kinks[1:]):
        sol = solve_ivp(rhs, (t[a], t[b]), y0, method="Radau", rtol=rtol, atol=atol, t_eval=t[a:b + 1],
                        args=(a, b))
        u[:, a:b + 1] = sol.y
        y0 = list(sol.y[:, -1])
    x = lam**2 + 2 / lam - 3
    p_out = 2 * (d["C10"] + 2 * d["C20"] * x + 3 * d["C30"] * x**2) * (lam - lam**-2)
    for (nkt, n, *_), uk in zip(ch, u):
        le = lam / np.exp(uk)
        p_out = p_out + 2 * w1(le * le + 2 / le, nkt, n) * (le * le - 1 / le) / lam
    return p_out


def best(fn, n):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def main() -> None:
    t, lam = protocol1()
    p = PRESETS["A"]
    t0 = time.perf_counter()
    simulate(p, t, lam)
    cold = time.perf_counter() - t_import
    first = time.perf_counter() - t0
    ref = radau(p, t, lam, 1e-10)
    rows = []
    for rtol in (1e-6, 1e-7):
        got = simulate(p, t, lam, rtol=rtol).nominal
        err = float(np.max(np.abs(got - ref)) / np.max(np.abs(ref)))
        rows.append((rtol, err, best(lambda r=rtol: simulate(p, t, lam, rtol=r), 30)))
    t_radau = best(lambda: radau(p, t, lam, 1e-6, 1e-9), 3)
    err_radau = float(np.max(np.abs(radau(p, t, lam, 1e-6, 1e-9) - ref)) / np.max(np.abs(ref)))

    test = synthetic_test(p, "p1")
    with get_context("fork").Pool(2) as pool:
        t0 = time.perf_counter()
        r = fit(test, seed=0, restarts=2, max_evals=4000, pool=pool)
        t_fit = time.perf_counter() - t0

    md = ["## bench_rubber", "",
          "One protocol-1 evaluation (case A preset, 253 samples, 23.7 s of history).", "",
          "| method | max rel. error vs Radau 1e-10 | time | speed-up vs Radau 1e-6 |", "|---|---|---|---|",
          f"| scipy Radau rtol 1e-6, atol 1e-9 (peer) | {err_radau:.1e} | {t_radau * 1e3:.1f} ms | 1 |"]
    for rtol, err, tm in rows:
        md.append(f"| rubber.simulate rtol {rtol:g} (TR-BDF2, Numba) | {err:.1e} | {tm * 1e3:.2f} ms | "
                  f"{t_radau / tm:.0f}x |")
    md += ["", f"Cold start (import rubber + first simulate, Numba cache warm): {cold:.2f} s "
           f"(first call {first:.2f} s).", "",
           f"Full fit (11 free parameters, CMA-ES popsize 16, 2 restarts x 4000 evaluations on 2 processes, "
           f"then least-squares polish and Fisher information): {t_fit:.1f} s, {r.evaluations} evaluations, "
           f"f = {r.f_total:.2e} (noise-free case-A protocol-1 data)."]
    text = "\n".join(md)
    print(text)
    write_section("bench_rubber", text)


def multirate() -> None:
    import json
    import os
    import subprocess
    import tempfile

    from rubber.fit import combinations
    from rubber.io import write_test
    from rubber.study import ACRYLIC, multirate_tests

    root = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for t in multirate_tests(seed=0):
            paths.append(str(Path(tmp) / f"{t.name}.csv"))
            write_test(paths[-1], t, unit="kPa")
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        c0 = os.times()
        subprocess.run([sys.executable, "-m", "rubber", "fit", *paths, "--bounds", "auto", "--out",
                        str(Path(tmp) / "out")], cwd=root, check=True, capture_output=True)
        wall = time.perf_counter() - t0
        cpu = os.times().children_user - c0.children_user
        load1 = os.getloadavg()[0]
        doc = json.loads((Path(tmp) / "out" / "params.json").read_text())
    truth = combinations(ACRYLIC, rate=doc["ref_rate"])
    md = ["## bench_rubber_multirate", "",
          "`python -m rubber fit <12 csvs> --bounds auto` (defaults: 2 CMA-ES runs x 6000 evaluations, "
          "serial, then least squares and the Fisher step) on the seeded synthetic acrylic set "
          "(`rubber.study.multirate_tests(seed=0)`: rates 0.01/0.03/0.1 /s x lambda_max 1.5/2/2.5/3, "
          "1 % noise, 1,512 samples).", "",
          f"Wall time {wall:.0f} s (CPU {cpu:.0f} s; 1-min load average {load0:.1f} before, {load1:.1f} "
          f"after, on 2 cores shared with other work); limit 600 s. f_total = {doc['f_total']:.3e} "
          f"({doc['evaluations']} evaluations), reference rate {doc['ref_rate']} /s.", "",
          "| combination | truth | fitted | rel. error |", "|---|---|---|---|"]
    for n, v in truth.items():
        g = doc["combinations"][n]
        md.append(f"| {n} | {v:.4g} | {g:.4g} | {abs(g / v - 1):.1%} |")
    text = "\n".join(md)
    print(text)
    write_section("bench_rubber_multirate", text)


if __name__ == "__main__":
    multirate() if "--multirate" in sys.argv[1:] else main()
