"""Response-spectrum speed: ``ground_motions.response_spectrum`` (Numba, exact piecewise-linear
recurrence of Nigam & Jennings) against the fair peer, the same exact recurrence vectorised over
the periods in NumPy, on El Centro (5372 samples) and Chi-Chi CHY002 (37500 samples), 100
periods, 5 % damping.

* per core (headline): both single-threaded, warm-up excluded, the same interleaved repeats,
  medians, the spectra asserted equal (max relative difference of Sd <= 1e-9) in the same run;
* the strongest peer measured: the same recurrence as a second-order IIR filter, scipy's C
  ``lfilter`` one period at a time (per core, same rules);
* secondary: a general-purpose peer, scipy ``lsim`` one period at a time (El Centro only; it
  solves the same piecewise-linear problem by the matrix exponential);
* multi-core throughput: spectra per second with every Numba thread (``prange`` over periods);
* cold start: a fresh interpreter importing ``ground_motions`` and computing the first spectrum,
  with an empty and with a warm (populated by the first run) temporary Numba cache;
* RotD50/RotD100 of a pair (``ground_motions.rotd_spectrum``, 180 angles, Boore 2010) against
  the same computation in NumPy (the recurrence vectorised over periods, storing both
  components' histories, then one vectorised projection per angle), per core, on the bundled
  Santa Monica pair (3000 samples) and Ferndale pair (10100 samples; full run only).

Run: ``python benchmarks/bench_spectra.py [--quick]`` (writes its section of RESULTS.md unless
``--quick``).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))

import _timing as tm  # noqa: E402  (first: pins BLAS threads before numpy)
import numpy as np  # noqa: E402
import scipy.signal  # noqa: E402
from _results import report  # noqa: E402

import ground_motions as gm  # noqa: E402

PERIODS = np.geomspace(0.02, 10.0, 100)
ZETA = 0.05
TOLERANCE = 1e-9  # max relative difference of Sd between ours and each peer


def coefficients(w: np.ndarray, zeta: float, dt: float) -> np.ndarray:
    """Nigam-Jennings coefficients (8, periods) for unit mass (Chopra, Table 5.2.1): those of
    :func:`ground_motions.spectra.coefficients` (checked against the matrix exponential in
    ``tests/test_spectra.py``), one column per circular frequency; outside every timer's hot
    loop (one evaluation per period), so the peers time the recurrence alone."""
    return np.array([gm.spectra.coefficients(float(x), zeta, dt) for x in np.atleast_1d(w)]).T


def numpy_sd(rec: gm.Record) -> np.ndarray:
    """The fair peer: the same recurrence, one NumPy vector operation per step over all periods."""
    a, b, cc, d, ap, bp, cp, dp = coefficients(2 * np.pi / PERIODS, ZETA, rec.dt)
    u = np.zeros(PERIODS.size)
    v = np.zeros(PERIODS.size)
    peak = np.zeros(PERIODS.size)
    p = -rec.accel
    for i in range(p.size - 1):
        u, v = a * u + b * v + cc * p[i] + d * p[i + 1], ap * u + bp * v + cp * p[i] + dp * p[i + 1]
        np.maximum(peak, np.abs(u), out=peak)
    return peak


def lfilter_sd(rec: gm.Record) -> np.ndarray:
    """A C-level peer: the same recurrence as a second-order IIR filter (``scipy.signal.lfilter``),
    one period at a time.

    With ``x = (u, v)``, ``x_n = A x_{n-1} + c p_{n-1} + d p_n`` from ``x_0 = 0`` gives
    ``U(z) = H(z) P(z) - p_0 G(z)``, ``H = e1' (I - A/z)^-1 (d + c/z)``, ``G = e1' (I - A/z)^-1 d``;
    the ``p_0 G`` term is a zero-input response, i.e. the filter's initial conditions ``zi``.
    """
    co = coefficients(2 * np.pi / PERIODS, ZETA, rec.dt)
    p = -rec.accel
    sd = np.empty(PERIODS.size)
    for j in range(PERIODS.size):
        a, b, cc, d, ap, bp, cp, dp = co[:, j]
        num = (d, cc - bp * d + b * dp, b * cp - bp * cc)
        den = (1.0, -(a + bp), a * bp - b * ap)
        zi = (-p[0] * d, -p[0] * (b * dp - bp * d))
        u, _ = scipy.signal.lfilter(num, den, p, zi=zi)
        sd[j] = np.max(np.abs(u))
    return sd


def lsim_sd(rec: gm.Record) -> np.ndarray:
    """A general-purpose peer: scipy ``lsim`` (linear interpolation of the input), period by period."""
    sd = np.empty(PERIODS.size)
    for j, t in enumerate(PERIODS):
        w = 2 * np.pi / t
        sys_ = scipy.signal.StateSpace([[0, 1], [-w * w, -2 * ZETA * w]], [[0], [1]], [[1, 0]], [[0]])
        _, y, _ = scipy.signal.lsim(sys_, -rec.accel, rec.time)
        sd[j] = np.max(np.abs(y))
    return sd


ROTD_PERIODS = np.geomspace(0.05, 5.0, 50)


def numpy_rotd(pair: gm.RecordPair) -> np.ndarray:
    """The fair peer for RotD: both components' histories by the NumPy recurrence (vectorised over
    periods), then for each of 180 angles the peak of u1 cos + u2 sin, then the percentiles."""
    a, b, cc, d, ap, bp, cp, dp = coefficients(2 * np.pi / ROTD_PERIODS, ZETA, pair.dt)
    hist = []
    for k in range(2):
        p = -pair.accel[:, k]
        u = np.zeros((p.size, ROTD_PERIODS.size))
        v = np.zeros(ROTD_PERIODS.size)
        for i in range(p.size - 1):
            un = a * u[i] + b * v + cc * p[i] + d * p[i + 1]
            v = ap * u[i] + bp * v + cp * p[i] + dp * p[i + 1]
            u[i + 1] = un
        hist.append(u)
    th = np.radians(np.arange(180.0))
    peaks = np.array([np.max(np.abs(hist[0] * np.cos(t) + hist[1] * np.sin(t)), axis=0) for t in th])
    return np.percentile(peaks, (50, 100), axis=0)


def max_rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / np.abs(b)))


COLD = tm.COLD_PRELUDE + """
import numpy as np, ground_motions as gm
t1 = time.perf_counter()
r = gm.load("elcentro")
gm.response_spectrum(r, np.geomspace(0.02, 10, 100))
print(json.dumps({"import": t1 - _t0, "first": time.perf_counter() - t1}))
"""


def main() -> None:
    args = tm.parser(__doc__).parse_args()
    repeat = 2 if args.quick else 7
    names = ("elcentro",) if args.quick else ("elcentro", "chichi")
    rows, multi, head = [], [], {}
    for name in names:
        rec = gm.load(name)
        ours = tm.Side("rrfrei", lambda _s, rec=rec: gm.response_spectrum(rec, PERIODS, ZETA).sd)
        peer = tm.Side("NumPy recurrence", lambda _s, rec=rec: numpy_sd(rec))
        c = tm.compare(ours, peer, repeat=repeat, agree=max_rel, tolerance=TOLERANCE, what=name)
        lf = tm.compare(ours, tm.Side("scipy lfilter", lambda _s, rec=rec: lfilter_sd(rec)), repeat=repeat,
                        agree=max_rel, tolerance=TOLERANCE, what=f"{name} (lfilter)")
        rows.append(f"| {name} | {rec.npts} | {tm.fmt(c.ours.median)} | {tm.fmt(c.peer.median)} "
                    f"| **{c.ratio:.0f}x** | {tm.fmt(lf.peer.median)} | **{lf.ratio:.1f}x** "
                    f"| {max(c.discrepancy, lf.discrepancy):.1e} |")
        rate, t_multi, _ = tm.throughput(ours, repeat=repeat)
        head[name] = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio,
                          lfilter_s=lf.peer.per_unit, lfilter_ratio=lf.ratio,
                          multi_s=t_multi.per_unit, threads=t_multi.threads)
        multi.append(f"| {name} | {t_multi.threads} | {tm.fmt(t_multi.median)} | {rate:.0f} |")
        print(rows[-1], multi[-1], flush=True)
    lsim = ""
    if not args.quick:
        rec = gm.load("elcentro")
        c = tm.compare(tm.Side("rrfrei", lambda _s: gm.response_spectrum(rec, PERIODS, ZETA).sd),
                       tm.Side("scipy lsim", lambda _s: lsim_sd(rec)), repeat=1, agree=max_rel,
                       tolerance=TOLERANCE, what="elcentro (lsim)")
        head["lsim"] = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio)
        lsim = (f"\n\nSecondary, a general-purpose peer: scipy `lsim` one period at a time on elcentro, "
                f"{tm.fmt(c.peer.median)} against {tm.fmt(c.ours.median)} ({c.ratio:.0f}x per core, one "
                f"timed run each after one warm-up; Sd agrees to {c.discrepancy:.1e}). It is not the "
                f"headline: `lsim` re-discretises and runs a general state-space loop per period.")
    rotd_rows = []
    for name in ("santamonica",) if args.quick else ("santamonica", "ferndale"):
        pair = gm.load_pair(name)
        c = tm.compare(
            tm.Side("rrfrei", lambda _s, pair=pair: gm.rotd_spectrum(pair, ROTD_PERIODS, ZETA).sd),
            tm.Side("NumPy RotD", lambda _s, pair=pair: numpy_rotd(pair)),
            repeat=2 if args.quick else 3, agree=max_rel, tolerance=TOLERANCE, what=f"{name} (RotD)")
        head[f"rotd_{name}"] = dict(ours_s=c.ours.per_unit, peer_s=c.peer.per_unit, ratio=c.ratio)
        rotd_rows.append(f"| {name} | {pair.npts} | {tm.fmt(c.ours.median)} | {tm.fmt(c.peer.median)} "
                         f"| **{c.ratio:.0f}x** | {c.discrepancy:.1e} |")
        print(rotd_rows[-1], flush=True)
    cold = tm.cold_start(COLD)
    md = (
        "## Response spectra (`ground_motions.response_spectrum`)\n\n"
        f"100 periods (0.02-10 s), 5 % damping. **Per core**: both on one thread, median of {repeat} "
        "interleaved runs after one warm-up each; the peer is the same exact piecewise-linear "
        "recurrence (Nigam-Jennings) vectorised over the periods in NumPy, one vector operation per "
        "time step; and the same recurrence written as a second-order IIR filter run by scipy's C "
        "`lfilter`, one period at a time (the strongest peer measured). Sd is asserted equal in the "
        "same run.\n\n"
        "| record | npts | rrfrei, 1 thread | NumPy recurrence, 1 thread | ratio per core | scipy lfilter, "
        "1 thread | ratio per core | max rel. diff of Sd |\n|---|---:|---:|---:|---:|---:|---:|---:|\n"
        + "\n".join(rows)
        + "\n\n**Multi-core throughput** (rrfrei alone, `prange` over periods):\n\n"
        "| record | threads | time per spectrum | spectra / s |\n|---|---:|---:|---:|\n" + "\n".join(multi)
        + lsim
        + "\n\n**RotD50 / RotD100 of a pair** (`ground_motions.rotd_spectrum`, 50 periods 0.05-5 s, 180 "
        "angles; per core, median of interleaved runs after a warm-up): the peer is the same "
        "computation in NumPy (the recurrence vectorised over periods for both components, then one "
        "vectorised projection per angle); RotD50 and RotD100 Sd asserted equal in the same run.\n\n"
        "| pair | npts | rrfrei, 1 thread | NumPy, 1 thread | ratio per core | max rel. diff |\n"
        "|---|---:|---:|---:|---:|---:|\n" + "\n".join(rotd_rows)
        + f"\n\nCold start (fresh interpreter, import + load El Centro + first spectrum; temporary "
        f"`NUMBA_CACHE_DIR`): empty cache {cold.cold['import']:.2f} s import + {cold.cold['first']:.2f} s "
        f"first call (compilation); warm cache (filled by that run) {cold.warm['import']:.2f} s + "
        f"{cold.warm['first']:.2f} s." + "".join(f" Note: {n}." for n in cold.notes)
    )
    report("spectra", md, quick=args.quick, headline=head)


if __name__ == "__main__":
    main()
