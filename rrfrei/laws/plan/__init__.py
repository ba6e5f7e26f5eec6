"""Coupled bidirectional ("plan") isolator laws: both horizontal shear directions at once.

An isolator pushed diagonally yields earlier than two independent springs would say: the shear
laws of OpenSees' 3-D bearing elements couple the two directions (a circular yield surface, a
vector Bouc-Wen variable).  Each law of this package ports the 3-D shear behaviour of one
OpenSees element and is registered under the name of its unidirectional law, whose parameters
(names, units, bounds, priors) it shares: ``rrfrei.laws.plan.get("plasticity").law`` is
``rrfrei.laws.get("plasticity")``.  A path along one axis gives the unidirectional law.

Public entry point: :func:`rrfrei.simulate_force` with an (n, 2) displacement array [m] returns
the (n, 2) shear forces [kN].  Kernel contract: :mod:`rrfrei.laws.plan.registry`.
"""

from rrfrei.laws.plan.registry import PlanLawSpec, driver, get, names, register

__all__ = ["PlanLawSpec", "driver", "get", "names", "register"]
