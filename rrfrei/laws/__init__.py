"""Isolator shear laws: registry (names, units, bounds, priors, kernels) and Numba step kernels.

Each law is one module of this package with one registry entry (:mod:`rrfrei.laws.registry`);
the modules are found on the first lookup, so adding a law edits no other file.

>>> from rrfrei import laws
>>> laws.get("bouc_wen").param_names
('k_init', 'qd', 'alpha1', 'alpha2', 'mu', 'eta', 'beta', 'gamma')
"""

from rrfrei.laws.registry import (
    STATUS_MESSAGES,
    LawSpec,
    OpenSeesElement,
    ParamSpec,
    Prior,
    get,
    names,
    opensees_laws,
    register,
)

__all__ = [
    "OPENSEES_LAWS",
    "STATUS_MESSAGES",
    "LawSpec",
    "OpenSeesElement",
    "ParamSpec",
    "Prior",
    "get",
    "names",
    "opensees_laws",
    "register",
]


def __getattr__(attr: str):
    if attr == "OPENSEES_LAWS":  # the laws that port an OpenSees element, read from the table
        return opensees_laws()
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")
