"""Speed of the law kernels against openseespy on the same 10,000-step displacement history.

For each OpenSees law: openseespy's fastest path (model built, then ONE ``analyze(10000)`` call
with an element recorder writing to a file; building the model is excluded) against
``rrfrei.simulate_force`` (public API, validation included) and the bare Numba driver
(the law's history driver, ``rrfrei.laws.specialise.history``), measured in the same run, best
of ``REPEAT``.  Also the cold start in a fresh subprocess (import + first ``simulate_force``
call) with an empty and with a warm Numba cache.  Writes section ``bench_laws`` of ``benchmarks/RESULTS.md``.

Run: ``python benchmarks/bench_laws.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

from _results import write_section  # noqa: E402

import rrfrei  # noqa: E402
from rrfrei.laws import get  # noqa: E402
from rrfrei.laws.specialise import history as law_driver  # noqa: E402

N = 10_000
REPEAT = 5

PARAMS = {
    "plasticity": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0),
    "bouc_wen (eta=1)": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.0,
                             beta=0.5, gamma=0.5),
    "bouc_wen (eta=1.37)": dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.02, mu=2.0, eta=1.37,
                                beta=0.6, gamma=0.4),
    "elastomeric_x": dict(fy=1.0, alpha=0.2, gr=500.0, d2=0.08, tr=0.002, n=15.0),
    "hdr": dict(a1=60.0, a2=-2e4, a3=3e7, b1=0.8, b2=300.0, b3=150.0, c1=1e3, c2=2e3, c3=0.4,
                c4=5e3),
}


def history() -> np.ndarray:
    """10,000 samples: 50 sine cycles of 200 steps, amplitude growing 2 -> 40 mm."""
    k = np.arange(1, N + 1)
    return (0.002 + 0.038 * k / N) * np.sin(2 * np.pi * k / 200)


def best(fn, repeat=REPEAT) -> float:
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return min(out)


def time_opensees(ops, law: str, p: dict, u: np.ndarray) -> tuple[float, np.ndarray]:
    import opensees_harness as h

    times = []
    force = None
    for _ in range(REPEAT):
        fd, path = tempfile.mkstemp(suffix=".out")
        os.close(fd)
        try:
            idx, sign = h._build(ops, law, p, u)
            ops.recorder("Element", "-file", path, "-precision", 17, "-ele", 1, "force")
            t0 = time.perf_counter()
            status = ops.analyze(u.size)
            ops.wipe()
            times.append(time.perf_counter() - t0)
            assert status == 0
            force = sign * np.loadtxt(path, ndmin=2)[-u.size:, idx]
        finally:
            os.unlink(path)
    return min(times), force


COLD = """
import time
t0 = time.perf_counter()
import numpy as np
import rrfrei
rrfrei.simulate_force({law!r}, {params!r}, np.linspace(0.0, 0.02, 100))
print(time.perf_counter() - t0)
"""


def cold_start(law: str, params: dict, cache_dir: str) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", COLD.format(law=law, params=params)], env=env,
                         capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    import openseespy.opensees as ops

    u = history()
    rows = []
    for label, p in PARAMS.items():
        law = label.split(" ")[0]
        spec = get(law)
        packed = spec.pack(p)
        force = np.empty(N)
        tang = np.empty(N)
        t = np.zeros(N)
        state0 = np.array(spec.initial_state)
        rrfrei.simulate_force(law, p, u)  # compile / load
        t_api = best(lambda law=law, p=p: rrfrei.simulate_force(law, p, u))
        drive = law_driver(spec)
        t_raw = best(lambda drive=drive, packed=packed, state0=state0, t=t, force=force, tang=tang:
                     drive(packed, state0.copy(), state0.copy(), u, t, False, 1, force, tang))
        t_os, f_os = time_opensees(ops, law, p, u)
        f = rrfrei.simulate_force(law, p, u)
        err = float(np.max(np.abs(f - f_os)) / np.max(np.abs(f_os)))
        rows.append((label, t_os, t_api, t_raw, err))
        print(f"{label:22s} openseespy {t_os * 1e3:8.2f} ms  simulate_force {t_api * 1e3:7.3f} ms "
              f"(x{t_os / t_api:6.0f})  kernel {t_raw * 1e3:7.3f} ms (x{t_os / t_raw:6.0f})  "
              f"max rel diff {err:.1e}")

    with tempfile.TemporaryDirectory() as cold_dir:
        t_cold = cold_start("bouc_wen", PARAMS["bouc_wen (eta=1)"], cold_dir)
        t_warm = cold_start("bouc_wen", PARAMS["bouc_wen (eta=1)"], cold_dir)
    print(f"cold start (import + first call): empty cache {t_cold:.2f} s, warm cache {t_warm:.2f} s")

    lines = [
        "Each law over the same 10,000-step history (50 sine cycles of 200 steps, amplitude "
        "2 -> 40 mm), best of 5. openseespy: one `analyze(10000)` with an element recorder "
        "(model building excluded); rrfrei: `simulate_force` (validation included) and the bare "
        "Numba driver `run_history`. Ratio = openseespy time / rrfrei time.",
        "",
        "| law | parameters | openseespy [ms] | simulate_force [ms] | ratio | kernel [ms] | ratio "
        "| max rel. diff |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for (label, t_os, t_api, t_raw, err), p in zip(rows, PARAMS.values()):
        ps = ", ".join(f"{k}={v:g}" for k, v in p.items())
        lines.append(f"| {label} | {ps} | {t_os * 1e3:.2f} | {t_api * 1e3:.3f} | {t_os / t_api:.0f} "
                     f"| {t_raw * 1e3:.3f} | {t_os / t_raw:.0f} | {err:.1e} |")
    lines += [
        "",
        f"Cold start in a fresh subprocess (`import rrfrei` + first `simulate_force`, bouc_wen): "
        f"empty Numba cache {t_cold:.2f} s, warm cache {t_warm:.2f} s.",
    ]
    write_section("bench_laws", "\n".join(lines))


if __name__ == "__main__":
    main()
