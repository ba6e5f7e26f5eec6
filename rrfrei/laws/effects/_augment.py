"""Template of an augmented law's step kernel (see :mod:`rrfrei.laws.effects`).

Slots, bound per augmented law by :func:`rrfrei.laws.effects.compose`:

* ``base_step``: the base law's step; ``NB``, ``NS``: its number of parameters and state size
  (the base law sees ``p[:NB]``, ``sc[:NS]``, ``st[:NS]``);
* ``effect_k``, ``P_k``, ``S_k`` (k = 1..4): the ``apply`` kernel of the k-th inner effect in the
  order named, with the offsets of its parameters and state (unused positions bound to
  :func:`rrfrei.laws.effects._neutral.no_effect`);
* ``HAS_SERIES``, ``series_capacity``, ``series_stick``, ``P_SERIES``, ``S_SERIES``,
  ``SERIES_TRAVEL``: the series slider, if any (its capacity, which may read its committed state,
  and its stick displacement: 0 for a rigid-plastic slider), and whether it keeps its slip
  travel since it last stuck (its second state variable);
* ``HAS_SLACK``, ``slack_compliance``, ``P_SLACK``, ``S_SLACK``: an inner effect's series
  elastic slack element, if any (:func:`_slack`): its compliance kernel, the offset of its
  travel parameter (0: rigid, the element is absent) and of its state (three slots: the
  element's deformation, the total displacement it was committed at, and its rate
  ``dx_s/du`` there: the first-order predictor that starts the next step's solve).

The offsets are constants of the instance, so the compiled step is as direct as a hand-written
one: no effect ids, no loop over a code array.
"""

import numpy as np
from numba import njit

from rrfrei.laws.specialise import unbound

SLOTS = (
    "base_step", "NB", "NS",
    "effect_1", "P_1", "S_1",
    "effect_2", "P_2", "S_2",
    "effect_3", "P_3", "S_3",
    "effect_4", "P_4", "S_4",
    "HAS_SERIES", "series_capacity", "series_stick", "P_SERIES", "S_SERIES", "SERIES_TRAVEL",
    "HAS_SLACK", "slack_compliance", "P_SLACK", "S_SLACK",
)
base_step = unbound("base_step")
effect_1 = unbound("effect_1")
effect_2 = unbound("effect_2")
effect_3 = unbound("effect_3")
effect_4 = unbound("effect_4")
series_capacity = unbound("series_capacity")
series_stick = unbound("series_stick")
slack_compliance = unbound("slack_compliance")
NB = NS = P_1 = S_1 = P_2 = S_2 = P_3 = S_3 = P_4 = S_4 = P_SERIES = S_SERIES = P_SLACK = S_SLACK = 0
HAS_SERIES = False
SERIES_TRAVEL = False
HAS_SLACK = False


@njit(cache=True)
def inner(p, sc, u, v, dt, st):
    """Base law with every inner effect (the series slider excluded): F = g f_b + f_a."""
    fb, kb, status = base_step(p[:NB], sc[:NS], u, v, dt, st[:NS])
    if status < 0:
        return fb, kb, status
    g = 1.0
    dg = 0.0
    fa = 0.0
    ka = 0.0
    g, dg, fa, ka = effect_1(p, P_1, sc, st, S_1, u, v, dt, fb, kb, g, dg, fa, ka)
    g, dg, fa, ka = effect_2(p, P_2, sc, st, S_2, u, v, dt, fb, kb, g, dg, fa, ka)
    g, dg, fa, ka = effect_3(p, P_3, sc, st, S_3, u, v, dt, fb, kb, g, dg, fa, ka)
    g, dg, fa, ka = effect_4(p, P_4, sc, st, S_4, u, v, dt, fb, kb, g, dg, fa, ka)
    return g * fb + fa, g * kb + fb * dg + ka, status


@njit(cache=True)
def _inner_fresh(p, sc, x, v, dt, st):
    """:func:`inner` from the committed state: the slider search evaluates the inner law at
    several trial points, and a base law that keeps a "sticky" trial variable (OpenSees
    plasticity keeps the trial u_p in the elastic branch) must not carry one trial into the
    next."""
    us = st[S_SERIES]
    st[:] = sc
    st[S_SERIES] = us
    return inner(p, sc, x, v, dt, st)


@njit(cache=True, inline="always")
def _secant(it, x, r, x_prev, r_prev, slope):
    """The slope of a series solve's residual ``r(x)``: the secant through the last two iterates
    from the second evaluation on (superlinear), else ``slope`` (the Newton slope from the law's
    tangent).  The law's tangent holds the velocity terms of rate effects (``dF/dv / dt``, the
    Newmark iteration's), which do not act in a series solve at a fixed velocity, so Newton with
    it converges only linearly there (a ratio of 0.014 per evaluation on the BNCS building with
    ``rate`` and the slack element: 5.6 law evaluations per call, 2.8 with the secant)."""
    if it > 0 and x != x_prev:
        s = (r - r_prev) / (x - x_prev)
        if s > 0.0 and s == s:
            return s
    return slope


@njit(cache=True)
def _stick(p, sc, u, us, ys, fs, v, dt, st):
    """The inner law in series with the slider's stick spring ``k_s = F_s / y_s`` while it
    sticks: the inner displacement ``x`` solves ``phi(x) = x + F(x) / k_s - (u - u_s) = 0``,
    increasing in ``x`` (slope ``1 + k / k_s >= 1`` for a tangent ``k >= 0``) and bracketed by
    ``x0 = u - u_s`` and ``x0 - F(x0) / k_s``; Newton (the secant from the second evaluation on,
    :func:`_secant`), a bisection step whenever it leaves the bracket.  Returns ``(x, F, k, status)``,
    ``k`` the inner tangent at ``x``."""
    cs = ys / fs  # the stick spring's compliance 1 / k_s [m/kN]
    x0 = u - us
    f, k, status = inner(p, sc, x0, v, dt, st)
    if status < 0 or f == 0.0:
        return x0, f, k, status
    dev = status
    x1 = x0 - f * cs
    lo = min(x0, x1)
    hi = max(x0, x1)
    x = x0
    tol = 1e-12 * max(abs(ys), 1e-12)
    x_prev = x
    ph_prev = 0.0
    for it in range(100):
        ph = x + f * cs - x0
        if ph > 0.0:
            hi = x
        else:
            lo = x
        if abs(ph) <= tol or hi - lo <= tol:
            return x, f, k, dev
        d = _secant(it, x, ph, x_prev, ph_prev, 1.0 + k * cs)
        xn = x - ph / d if d > 0.0 else 0.5 * (lo + hi)
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        x_prev = x
        ph_prev = ph
        x = xn
        f, k, status = _inner_fresh(p, sc, x, v, dt, st)
        if status < 0:
            return x, f, k, status
        dev = max(dev, status)
    return x, f, k, -2


@njit(cache=True)
def _slide(p, sc, u, v, dt, st):
    """The inner law in series with a slider of capacity ``series_capacity``: while |F| < F_s it
    sticks, else u_s moves so that |F| = F_s (safeguarded Newton on the inner law, the secant
    from the second evaluation on (:func:`_secant`), then bisection).  With a stick displacement
    ``y_s = series_stick > 0`` the slider is elastic-plastic: while it sticks it deforms as a
    spring of stiffness ``F_s / y_s`` in series with the inner law (:func:`_stick`), and ``u_s``
    is its plastic slip; ``y_s = 0``: the rigid-plastic slider."""
    so = S_SERIES
    fs = series_capacity(p, P_SERIES, sc, so)
    ys = series_stick(p, P_SERIES)
    us = sc[so]
    st[so] = us
    if ys == 0.0:
        x = u - us
        f, kt, status = inner(p, sc, x, v, dt, st)
    else:
        x, f, kt, status = _stick(p, sc, u, us, ys, fs, v, dt, st)
        st[so] = us
        if status >= 0 and abs(f) <= fs:
            if SERIES_TRAVEL:
                st[so + 1] = 0.0  # stuck: the travel since the last stick restarts
            return f, kt / (1.0 + kt * ys / fs), status
    if status < 0 or abs(f) <= fs:
        if SERIES_TRAVEL:
            st[so + 1] = 0.0
        return f, kt, status
    # sliding: find the inner displacement x with |F(x)| = fs between x (|F| > fs) and a point
    # back towards the committed inner displacement where |F| <= fs
    dev = status  # > 0: a robust base solve acted (a deviation from OpenSees)
    s = 1.0 if f > 0.0 else -1.0
    target = s * fs
    tol = 1e-12 * max(fs, 1.0) + 1e-9 * fs
    hi = x  # s * (F - target) > 0 here
    lo = x
    step = max(abs(u - us), 1e-9)
    found = False
    # safeguarded Newton first (one inner call per iteration)
    xn = x
    fn = f
    kn = kt
    x_prev = xn
    r_prev = 0.0
    for it in range(30):
        if abs(fn - target) <= tol:
            found = True
            break
        if s * (fn - target) > 0.0:
            hi = xn
        slope = _secant(it, xn, fn - target, x_prev, r_prev, kn)
        if slope > 0.0:
            xt = xn - (fn - target) / slope
        else:
            break
        if not np.isfinite(xt):
            break
        x_prev = xn
        r_prev = fn - target
        xn = xt
        fn, kn, status = _inner_fresh(p, sc, xn, v, dt, st)
        if status < 0:
            return fn, kn, status
        dev = max(dev, status)
    if not found:
        # bracket then bisect
        lo = hi - s * step
        for _ in range(80):
            fl, kl, status = _inner_fresh(p, sc, lo, v, dt, st)
            if status < 0:
                return fl, kl, status
            dev = max(dev, status)
            if s * (fl - target) <= 0.0:
                break
            step *= 2.0
            lo = hi - s * step
        else:
            return fl, kl, -2
        for _ in range(200):
            xn = 0.5 * (lo + hi)
            fn, kn, status = _inner_fresh(p, sc, xn, v, dt, st)
            if status < 0:
                return fn, kn, status
            dev = max(dev, status)
            if s * (fn - target) > 0.0:
                hi = xn
            else:
                lo = xn
            if abs(fn - target) <= tol or abs(hi - lo) <= 1e-15 * max(abs(hi), 1e-3):
                break
    st[so] = u - xn if ys == 0.0 else u - xn - s * ys
    if SERIES_TRAVEL:
        st[so + 1] = sc[so + 1] + abs(st[so] - us)
    return target, 0.0, dev


@njit(cache=True)
def _core(p, sc, u, v, dt, st):
    """The law without the slack element: the inner law, in series with the slider if any."""
    if HAS_SERIES:
        return _slide(p, sc, u, v, dt, st)
    return inner(p, sc, u, v, dt, st)


@njit(cache=True)
def _core_fresh(p, sc, y, v, dt, st):
    """:func:`_core` at ``y`` from the committed state (no trial carried from the last one)."""
    st[:] = sc
    return _core(p, sc, y, v, dt, st)


@njit(cache=True)
def _slack(p, sc, u, v, dt, st):
    """:func:`_core` in series with an elastic slack element whose deformation is a function of
    the force it carries, ``x_s = X(F)`` (``slack_compliance(p, P_SLACK, F) -> (X, dX/dF)``,
    increasing, ``|X| < a`` the travel ``p[P_SLACK]``).  The element's deformation solves
    ``phi(x) = x - X(F_c(u - x)) = 0``, increasing in ``x`` with slope ``1 + X' k_c >= 1`` when
    the law's tangent ``k_c >= 0``, and bracketed by ``[-a, a]``: Newton from the first-order
    predictor ``x_c + (dx_s/du)_c (u - u_c)`` (the committed deformation, displacement and rate:
    the element's share ``X' k_c / (1 + X' k_c)`` of a displacement increment), a bisection step
    whenever Newton leaves the bracket.  The predictor only moves the start: the root and its
    tolerance are the same, reached in fewer law evaluations.  From the second evaluation on, the
    slope is the secant of ``phi`` (:func:`_secant`): the law's tangent ``k_c`` holds the
    velocity terms of rate effects (``dF/dv / dt``), which do not move while ``v`` is held, so
    Newton with it converged only linearly.  Tangent ``k_c / (1 + k_c X')``.
    The law sees the total velocity ``v``."""
    a = p[P_SLACK]
    if a == 0.0:
        return _core(p, sc, u, v, dt, st)
    lo = -a
    hi = a
    x = min(max(sc[S_SLACK] + sc[S_SLACK + 2] * (u - sc[S_SLACK + 1]), lo), hi)
    tol = 1e-10 * a
    f = 0.0
    k = 0.0
    dx = 0.0
    dev = 0
    x_prev = x
    ph_prev = 0.0
    for it in range(100):
        f, k, status = _core_fresh(p, sc, u - x, v, dt, st)
        if status < 0:
            return f, k, status
        dev = max(dev, status)
        xs, dx = slack_compliance(p, P_SLACK, f)
        ph = x - xs
        if ph > 0.0:
            hi = x
        else:
            lo = x
        if abs(ph) <= tol or hi - lo <= tol:
            break
        d = _secant(it, x, ph, x_prev, ph_prev, 1.0 + dx * k)
        xn = x - ph / d if d > 0.0 else 0.5 * (lo + hi)
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        x_prev = x
        ph_prev = ph
        x = xn
    else:
        return f, k, -2
    st[S_SLACK] = x
    st[S_SLACK + 1] = u
    d = 1.0 + k * dx
    st[S_SLACK + 2] = k * dx / d if d > 0.0 else 0.0
    return f, k / d, dev


@njit(cache=True)
def step(p, sc, u, v, dt, st):
    """Step of the augmented law: (force [kN], tangent [kN/m], status); contract of the
    registry."""
    if HAS_SLACK:
        return _slack(p, sc, u, v, dt, st)
    return _core(p, sc, u, v, dt, st)
