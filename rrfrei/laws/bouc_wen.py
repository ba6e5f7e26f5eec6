"""ElastomericBearingBoucWen (OpenSees v3.7.1, ``ElastomericBearingBoucWen2d.cpp``).

STUB: the kernel is being written (issue 2).  The spec below is final.
"""

import numpy as np
from numba import njit

from rrfrei.laws.plasticity import PARAMS as _PLASTICITY_PARAMS
from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register

KERNEL_ID = 2


@njit(cache=True)
def step(p, sc, u, v, dt, st):
    return 0.0, 0.0, -9


def _check(p: np.ndarray) -> None:
    if p[2] >= 1.0:
        raise ValueError(f"law 'bouc_wen': alpha1 = {p[2]:g} must be < 1")
    if p[6] + p[7] <= 0.0:
        raise ValueError(
            f"law 'bouc_wen': beta + gamma = {p[6] + p[7]:g} must be > 0 (bounded hysteretic "
            "variable z)"
        )


SPEC = register(
    LawSpec(
        name="bouc_wen",
        kernel_id=KERNEL_ID,
        params=_PLASTICITY_PARAMS
        + (
            ParamSpec("eta", "-", 0.1, 10.0, "Bouc-Wen exponent", Prior("uniform", 0.5, 5.0)),
            ParamSpec("beta", "-", 0.0, 5.0, "coefficient of the sign-dependent term",
                      Prior("uniform", 0.0, 2.0)),
            ParamSpec("gamma", "-", -5.0, 5.0, "coefficient of the constant term",
                      Prior("uniform", -1.0, 1.0)),
        ),
        state_size=4,
        description="OpenSees ElastomericBearingBoucWen: smooth Bouc-Wen hysteresis (A = 1).",
        opensees_element="elastomericBearingBoucWen",
        check=_check,
    )
)
