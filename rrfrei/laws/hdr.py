"""HDR shear law (OpenSees v3.7.1, ``HDR.cpp``, Grant-Fenves-Whittaker 2004), force form.

STUB: the kernel is being written (issue 2).  The spec below is final.
"""

from numba import njit

from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register

KERNEL_ID = 4


@njit(cache=True)
def step(p, sc, u, v, dt, st):
    return 0.0, 0.0, -9


SPEC = register(
    LawSpec(
        name="hdr",
        kernel_id=KERNEL_ID,
        params=(
            ParamSpec("a1", "kN/m", 1e-6, 1e9, "initial elastic stiffness",
                      Prior("loguniform", 10.0, 1e6)),
            ParamSpec("a2", "kN/m^3", -1e12, 1e12, "quadratic elastic stiffening",
                      Prior("normal", 0.0, 1e6)),
            ParamSpec("a3", "kN/m^5", -1e16, 1e16, "quartic elastic stiffening",
                      Prior("normal", 0.0, 1e9)),
            ParamSpec("b1", "kN", 0.0, 1e6, "bounding-surface radius at zero displacement",
                      Prior("loguniform", 1e-2, 1e3)),
            ParamSpec("b2", "kN/m^2", -1e9, 1e9, "growth of the bounding surface with |u|^2",
                      Prior("normal", 0.0, 1e4)),
            ParamSpec("b3", "1/m", 0.0, 1e6, "rate of approach to the bounding surface",
                      Prior("loguniform", 1.0, 1e4)),
            ParamSpec("c1", "1/m^3", 0.0, 1e12, "scragging damage of the elastic part",
                      Prior("halfnormal", 1e3)),
            ParamSpec("c2", "1/m^3", 0.0, 1e12, "scragging damage of the bounding surface",
                      Prior("halfnormal", 1e3)),
            ParamSpec("c3", "-", 0.0, 1.0, "residual fraction after Mullins damage",
                      Prior("uniform", 0.0, 1.0)),
            ParamSpec("c4", "1/m^3", 0.0, 1e12, "Mullins damage rate",
                      Prior("halfnormal", 1e3)),
        ),
        state_size=8,
        description="OpenSees HDR (Grant et al. 2004): elastic + bounding-surface hysteresis "
        "with scragging and Mullins damage.",
        opensees_element="HDR",
    )
)
