"""Hypothesis strategies shared by the law tests: parameter sets spread across physically
meaningful ranges (scaled to displacement amplitudes of a few cm) and displacement histories
with reversals, repeated values, tiny and large increments."""

from __future__ import annotations

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st


def logu(lo: float, hi: float):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda x: float(10.0**x))


@st.composite
def plasticity_params(draw):
    return dict(k_init=draw(logu(10.0, 1e5)), qd=draw(logu(1e-2, 1e2)),
                alpha1=draw(st.floats(0.0, 0.95)), alpha2=draw(st.floats(-0.05, 0.3)),
                mu=draw(st.sampled_from([1.0, 2.0, 3.0]) | st.floats(1.0, 5.0)))


@st.composite
def bouc_wen_params(draw, *, dissipative: bool = False):
    p = draw(plasticity_params())
    eta = draw(st.sampled_from([1.0, 2.0]) | st.floats(1.0 if dissipative else 0.2, 6.0))
    beta = draw(st.floats(0.05, 3.0))
    gamma = draw(st.floats(-beta, beta) if dissipative else st.floats(-3.0, 3.0))
    assume(beta + gamma > 1e-3)
    return {**p, "eta": eta, "beta": beta, "gamma": gamma}


@st.composite
def elastomeric_x_params(draw):
    d2 = draw(logu(0.05, 1.0))
    return dict(fy=draw(logu(1e-2, 1e2)), alpha=draw(st.floats(0.01, 0.95)),
                gr=draw(logu(100.0, 1e4)), d1=draw(st.floats(0.0, 0.3)) * d2, d2=d2,
                tr=draw(logu(1e-3, 2e-2)), n=float(draw(st.integers(1, 50))),
                tc=draw(st.floats(0.0, 0.02)), cd=draw(st.floats(0.0, 100.0)))


@st.composite
def hdr_params(draw, *, physical: bool = False):
    a1 = draw(logu(10.0, 1e4))
    b1 = draw(logu(1e-2, 1e2))
    lo = 0.0 if physical else -1.0
    b2 = draw(st.floats(-100.0, 100.0) if physical else st.floats(-200.0, 1000.0))
    return dict(a1=a1, a2=a1 * draw(st.floats(lo * 100.0, 300.0)),
                a3=a1 * draw(st.floats(lo * 1e4, 1e5)), b1=b1,
                b2=b1 * b2, b3=draw(logu(100.0 if physical else 1.0, 1e4)),
                c1=draw(st.floats(0.0, 1e6)), c2=draw(st.floats(0.0, 1e6)),
                c3=draw(st.floats(0.0, 1.0)), c4=draw(st.floats(0.0, 1e6)))


LAW_PARAMS = {
    "plasticity": plasticity_params,
    "bouc_wen": bouc_wen_params,
    "elastomeric_x": elastomeric_x_params,
    "hdr": hdr_params,
}

_INCREMENT = st.one_of(
    st.just(0.0),                      # repeated value
    st.floats(1e-10, 1e-7),            # tiny
    st.floats(1e-4, 5e-3),             # ordinary
    st.floats(5e-3, 0.04),             # large
)


@st.composite
def histories(draw, *, min_size: int = 2, max_size: int = 60, limit: float = 0.06):
    """Displacement histories [m] from rest: random-sign increments of all sizes, clipped."""
    steps = draw(st.lists(st.tuples(_INCREMENT, st.booleans()), min_size=min_size,
                          max_size=max_size))
    u = np.cumsum([d if up else -d for d, up in steps])
    return np.clip(u, -limit, limit)
