"""Response-spectrum speed: the Numba Nigam-Jennings kernel against scipy ``lsim`` (the peer: the
same exact piecewise-linear solution, one period at a time) and a NumPy recurrence vectorised over
periods, on El Centro (5372 samples) and Chi-Chi CHY002 (37500 samples), 100 periods, 5 %.
Also the cold start (import + first call) with an empty and a warm Numba cache.

Run: ``python benchmarks/bench_spectra.py`` (writes its section of RESULTS.md).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# the repository first: a stale editable install may map ground_motions to an empty namespace
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import scipy.signal  # noqa: E402
from _results import write_section  # noqa: E402

import ground_motions as gm  # noqa: E402
from ground_motions.spectra import _coefficients  # noqa: E402

PERIODS = np.geomspace(0.02, 10.0, 100)
ZETA = 0.05


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def lsim_sd(rec):
    sd = np.empty(PERIODS.size)
    for j, t in enumerate(PERIODS):
        w = 2 * np.pi / t
        sys_ = scipy.signal.StateSpace([[0, 1], [-w * w, -2 * ZETA * w]], [[0], [1]], [[1, 0]], [[0]])
        _, y, _ = scipy.signal.lsim(sys_, -rec.accel, rec.time)
        sd[j] = np.max(np.abs(y))
    return sd


def numpy_sd(rec):
    c = np.array([_coefficients(2 * np.pi / t, ZETA, rec.dt) for t in PERIODS]).T
    u = np.zeros(PERIODS.size)
    v = np.zeros(PERIODS.size)
    peak = np.zeros(PERIODS.size)
    p = -rec.accel
    for i in range(p.size - 1):
        u, v = (
            c[0] * u + c[1] * v + c[2] * p[i] + c[3] * p[i + 1],
            c[4] * u + c[5] * v + c[6] * p[i] + c[7] * p[i + 1],
        )
        np.maximum(peak, np.abs(u), out=peak)
    return peak


def cold_start(cache_dir):
    code = (
        "import time; t0 = time.perf_counter(); import numpy as np, ground_motions as gm; "
        "r = gm.load('elcentro'); gm.response_spectrum(r, np.geomspace(0.02, 10, 100)); "
        "print(time.perf_counter() - t0)"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=root
    )
    return float(out.stdout.strip())


def main():
    rows = []
    for name in ("elcentro", "chichi"):
        rec = gm.load(name)
        gm.response_spectrum(rec, PERIODS, ZETA)  # compile / load cache
        t_nb, s = best_of(lambda rec=rec: gm.response_spectrum(rec, PERIODS, ZETA), 5)
        t_ls, sd_ls = best_of(lambda rec=rec: lsim_sd(rec), 1)
        t_np, sd_np = best_of(lambda rec=rec: numpy_sd(rec), 1)
        err = max(np.max(np.abs(s.sd - sd_ls) / sd_ls), np.max(np.abs(s.sd - sd_np) / sd_np))
        rows.append(
            f"| {name} | {rec.npts} | {1e3 * t_nb:.1f} | {1e3 * t_ls:.0f} | {1e3 * t_np:.0f} | "
            f"{t_ls / t_nb:.0f}x | {t_np / t_nb:.0f}x | {err:.1e} |"
        )
    with tempfile.TemporaryDirectory() as d:
        cold = cold_start(d)
        warm = cold_start(d)
    md = (
        "## Response spectra (`ground_motions.response_spectrum`)\n\n"
        f"100 periods (0.02-10 s), 5 % damping; best of 5 for Numba, one run for the peers; "
        f"{os.cpu_count()} cores shared with other jobs, so timings are noisy.\n\n"
        "| record | npts | Numba [ms] | scipy lsim loop [ms] | NumPy recurrence [ms] | speed-up vs lsim | "
        "vs NumPy | max rel. diff of Sd |\n|---|---|---|---|---|---|---|---|\n"
        + "\n".join(rows)
        + f"\n\nCold start (new process: import + load + first spectrum): {cold:.2f} s with an empty Numba "
        f"cache (compilation), {warm:.2f} s with the cache warm."
    )
    print(md)
    write_section("spectra", md)


if __name__ == "__main__":
    main()
