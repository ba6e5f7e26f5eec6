"""Isolator shear laws: registry (names, units, bounds, priors) and Numba step kernels.

>>> from rrfrei import laws
>>> laws.get("bouc_wen").param_names
('k_init', 'qd', 'alpha1', 'alpha2', 'mu', 'eta', 'beta', 'gamma')
"""

from rrfrei.laws import bouc_wen, elastomeric_x, hdr, linear, plasticity  # noqa: F401  (register)
from rrfrei.laws.registry import (
    OPENSEES_LAWS,
    STATUS_MESSAGES,
    LawSpec,
    ParamSpec,
    Prior,
    get,
    names,
    register,
)

__all__ = [
    "OPENSEES_LAWS",
    "STATUS_MESSAGES",
    "LawSpec",
    "ParamSpec",
    "Prior",
    "get",
    "names",
    "register",
]
