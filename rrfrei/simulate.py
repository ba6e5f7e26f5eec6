"""Public entry point for driving a law along a displacement history."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rrfrei._inputs import as_history
from rrfrei.errors import NumericalFailure
from rrfrei.laws import STATUS_MESSAGES, LawSpec, get
from rrfrei.laws.dispatch import base_drive
from rrfrei.laws.kernel import drive


def simulate_force(
    law: str | LawSpec,
    params: Mapping[str, float] | np.ndarray,
    disp,
    *,
    time=None,
    substeps: int = 1,
    return_tangent: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Shear force [kN] of ``law`` along the displacement history ``disp`` [m].

    Parameters
    ----------
    law : name of a registered law (``rrfrei.laws.names()``), possibly augmented
        (``"bouc_wen+rate"``), or its :class:`LawSpec`.
    params : parameter values by name (kN, m, s), or an array in ``spec.param_names`` order.
    disp : displacement history [m]; the law starts virgin at zero displacement.
    time : sample times [s], strictly increasing; needed only by velocity-dependent terms.
        Without it the history is quasi-static (velocity 0, dt = 1 as in OpenSees statics).
    substeps : 1 reproduces OpenSees (one implicit update per increment, so the result depends on
        the sampling); n > 1 splits every increment into n equal parts for a step-size-converged
        answer.
    return_tangent : also return the tangent stiffness history [kN/m].

    Raises
    ------
    ValueError
        unknown law, bad parameters, non-finite or non-1-D displacement, or bad time.
    NumericalFailure
        (a ``ValueError`` subclass) the law's local solve failed; the message names the sample
        index, the state and the parameters.
    """
    spec = get(law)
    p = spec.pack(params)
    u = as_history(disp, "disp")
    if not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    if time is None:
        t = np.zeros_like(u)
        use_time = False
    else:
        t = as_history(time, "time")
        if t.size != u.size:
            raise ValueError(f"time has {t.size} values but disp has {u.size}")
        dt = np.diff(t)
        if np.any(dt <= 0):
            i = int(np.flatnonzero(dt <= 0)[0])
            raise ValueError(
                f"time must be strictly increasing; time[{i + 1}] = {t[i + 1]} <= time[{i}] = {t[i]}"
            )
        use_time = True
    force = np.empty_like(u)
    tangent = np.empty_like(u)
    sc = np.array(spec.initial_state, dtype=float)
    st = sc.copy()
    if spec.effects:
        status, idx = drive(spec.code, p, sc, st, u, t, use_time, int(substeps), force, tangent)
    else:  # base law: its own loop, without compiling the effect catalogue (cold start)
        status, idx = base_drive(
            int(spec.kernel_id), p, sc, st, u, t, use_time, int(substeps), force, tangent
        )
    if status != 0:
        raise NumericalFailure(
            f"law {spec.name!r} failed at sample {idx} (disp = {u[idx]:.6g} m): "
            f"{STATUS_MESSAGES.get(int(status), f'status {status}')}; committed state "
            f"{np.array2string(sc, precision=6)}, failed trial state "
            f"{np.array2string(st, precision=6)}; parameters {spec.as_dict(p)}"
        )
    return (force, tangent) if return_tangent else force
