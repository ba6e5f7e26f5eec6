"""ElastomericX shear law (OpenSees v3.7.1, ``ElastomericX.cpp``), one shear direction.

STUB: the kernel is being written (issue 2).  The spec below is final.
"""

from numba import njit

from rrfrei.laws.registry import LawSpec, ParamSpec, Prior, register

KERNEL_ID = 3


@njit(cache=True)
def step(p, sc, u, v, dt, st):
    return 0.0, 0.0, -9


SPEC = register(
    LawSpec(
        name="elastomeric_x",
        kernel_id=KERNEL_ID,
        params=(
            ParamSpec("fy", "kN", 1e-9, 1e6,
                      "characteristic strength Qd (OpenSees' name Fy)", Prior("loguniform", 1e-2, 1e3)),
            ParamSpec("alpha", "-", 1e-4, 0.9999,
                      "ratio of post-yield to initial shear stiffness", Prior("uniform", 0.01, 0.99)),
            ParamSpec("gr", "kN/m^2", 1e-3, 1e8, "rubber shear modulus",
                      Prior("loguniform", 10.0, 1e5)),
            ParamSpec("d1", "m", 0.0, 100.0, "inner (lead/hole) diameter", geometry=True,
                      default=0.0),
            ParamSpec("d2", "m", 1e-4, 100.0, "outer diameter", geometry=True),
            ParamSpec("tr", "m", 1e-5, 10.0, "thickness of one rubber layer", geometry=True),
            ParamSpec("n", "-", 1.0, 1000.0, "number of rubber layers", geometry=True),
            ParamSpec("tc", "m", 0.0, 10.0, "rubber cover thickness", geometry=True, default=0.0),
            ParamSpec("cd", "kN*s/m", 0.0, 1e9, "viscous damping coefficient", default=0.0),
        ),
        state_size=5,
        description="OpenSees ElastomericX (Kumar): Park-Wen hysteresis plus elastic rubber.",
        opensees_element="ElastomericX",
        uses_velocity=True,
    )
)
