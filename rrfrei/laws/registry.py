"""Registry of isolator shear laws: the one place a law is declared.

Everything downstream (simulation, calibration, propagation, gap diagnosis, CLI) reads a law's
parameter names, units, bounds, priors *and kernels* from its :class:`LawSpec`; nothing switches
on law names or ids by hand.  A law is one module of the :mod:`rrfrei.laws` package (or any
module that calls :func:`register`) with one registry entry; the package's modules are
discovered on the first lookup (:func:`get`, :func:`names`), so no import list names them.

Kernel contract
---------------
Every law provides a Numba step kernel (``LawSpec.step``)::

    step(p, sc, u, v, dt, st) -> (force, tangent, status)

* ``p``      float64 array of the law's parameters, in ``LawSpec.param_names`` order;
* ``sc``     committed state (read only), float64 array of length ``LawSpec.state_size``;
* ``u``      trial shear displacement [m];
* ``v``      trial shear velocity [m/s] (0 under static displacement control);
* ``dt``     time step since the last commit [s] (1.0 under static control, as in OpenSees);
* ``st``     trial state: on entry the previous trial (OpenSees keeps trial variables between
  ``update()`` calls), on exit the new trial state;
* returns the shear force [kN], the tangent dF/du [kN/m] and a status (0 = converged, < 0 =
  failure; see :data:`STATUS_MESSAGES`; > 0 only from a robust local solve, a converged step
  that deviates from OpenSees).

A driver commits by copying ``st`` into ``sc`` once a step has converged.  Kernels that call a
law (history drivers, the batched likelihood, Newmark) are templates instantiated per law from
these fields (:mod:`rrfrei.laws.specialise`), so only the laws a command uses are compiled.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

STATUS_MESSAGES = {
    0: "converged",
    -1: "singular Newton derivative in the law's local solve",
    -2: "the law's local Newton iteration did not converge",
    -3: "non-finite force or state",
    -4: "global Newton iteration did not converge even after step subdivision",
}


@dataclass(frozen=True)
class Prior:
    """A univariate prior.

    ``kind`` is one of ``uniform`` (on [a, b]), ``loguniform`` (on [a, b], a > 0),
    ``normal`` (mean a, sd b), ``lognormal`` (median a, log-sd b), ``halfnormal`` (scale a).
    """

    kind: str
    a: float
    b: float = 0.0

    _KINDS = ("uniform", "loguniform", "normal", "lognormal", "halfnormal")

    def __post_init__(self) -> None:
        if self.kind not in self._KINDS:
            raise ValueError(f"prior kind {self.kind!r} unknown; expected one of {self._KINDS}")
        if self.kind in ("uniform", "loguniform") and not self.b > self.a:
            raise ValueError(f"{self.kind} prior needs a < b, got a={self.a}, b={self.b}")
        if self.kind == "loguniform" and self.a <= 0:
            raise ValueError(f"loguniform prior needs a > 0, got a={self.a}")
        if self.kind in ("normal", "lognormal") and self.b <= 0:
            raise ValueError(f"{self.kind} prior needs a positive spread b, got {self.b}")
        if self.kind == "lognormal" and self.a <= 0:
            raise ValueError(f"lognormal prior needs a positive median a, got {self.a}")
        if self.kind == "halfnormal" and self.a <= 0:
            raise ValueError(f"halfnormal prior needs a positive scale a, got {self.a}")

    def logpdf(self, x: np.ndarray | float) -> np.ndarray:
        """Log density (up to no constant: normalised) at ``x``; -inf outside the support."""
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            if self.kind == "uniform":
                out = np.where((x >= self.a) & (x <= self.b), -math.log(self.b - self.a), -np.inf)
            elif self.kind == "loguniform":
                out = np.where(
                    (x >= self.a) & (x <= self.b),
                    -np.log(x) - math.log(math.log(self.b / self.a)),
                    -np.inf,
                )
            elif self.kind == "normal":
                z = (x - self.a) / self.b
                out = -0.5 * z * z - math.log(self.b * math.sqrt(2 * math.pi))
            elif self.kind == "lognormal":
                lx = np.log(np.where(x > 0, x, 1.0))
                z = (lx - math.log(self.a)) / self.b
                out = np.where(
                    x > 0, -0.5 * z * z - lx - math.log(self.b * math.sqrt(2 * math.pi)), -np.inf
                )
            else:  # halfnormal
                z = x / self.a
                out = np.where(
                    x >= 0, -0.5 * z * z + math.log(math.sqrt(2 / math.pi) / self.a), -np.inf
                )
        return out

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> np.ndarray:
        """Draw ``size`` samples with the generator ``rng``."""
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b, size)
        if self.kind == "loguniform":
            return np.exp(rng.uniform(math.log(self.a), math.log(self.b), size))
        if self.kind == "normal":
            return rng.normal(self.a, self.b, size)
        if self.kind == "lognormal":
            return self.a * np.exp(rng.normal(0.0, self.b, size))
        return np.abs(rng.normal(0.0, self.a, size))

    @classmethod
    def from_mapping(cls, data: Mapping) -> Prior:
        """Build from ``{"kind": ..., "a": ..., "b": ...}`` (as in a priors TOML table)."""
        try:
            return cls(str(data["kind"]), float(data["a"]), float(data.get("b", 0.0)))
        except KeyError as exc:
            raise ValueError(f"prior {dict(data)!r} lacks the field {exc.args[0]!r}") from None


@dataclass(frozen=True)
class ParamSpec:
    """One law parameter.

    ``lower``/``upper`` are physical bounds (inclusive); ``prior`` the default calibration prior;
    ``geometry`` marks parameters fixed from the bearing drawing (never sampled);
    ``default`` is the value of an optional parameter when it is not given;
    ``hold`` is a value at which calibration holds the parameter unless a prior for it is given,
    used where the force is exactly invariant along a direction of parameter space (the reason is
    stated in the law's docstring), so the posterior would otherwise be an unbounded ridge.
    """

    name: str
    unit: str
    lower: float
    upper: float
    description: str
    prior: Prior | None = None
    geometry: bool = False
    default: float | None = None
    hold: float | None = None

    @property
    def optional(self) -> bool:
        return self.default is not None


@dataclass(frozen=True)
class OpenSeesElement:
    """The OpenSees element a law ports, and its argument list (openseespy 3.7.1).

    ``ops.element(name, tag, i_node, j_node, *args(p, ndm, orient, materials))`` builds the
    element at the law's parameters, where

    * ``p``         the law's full parameters (a mapping in ``LawSpec.param_names`` order; kN, m, s);
    * ``ndm``       the model dimension, 2 (``-ndm 2 -ndf 3``) or 3 (``-ndm 3 -ndf 6``), one of
      ``dims``;
    * ``orient``    the six numbers of the element's orientation: local x (axial) then a vector
      in the local x-y plane (local y is the shear direction of a unidirectional law), as given
      (ints stay ints);
    * ``materials`` the uniaxial material tags of the directions the shear law does not model
      (``-P -Mz`` in 2-D, ``-P -T -My -Mz`` in 3-D), for the elements that take them.

    Arguments that enter only the vertical, torsional or rotational response (bulk modulus,
    shims, cavitation and buckling constants: :data:`OPENSEES_VERTICAL`) are written at fixed
    values; they leave the shear force unchanged.
    """

    name: str
    args: Callable[..., list] = field(compare=False, repr=False)
    dims: tuple[int, ...] = (2, 3)


#: Vertical properties the shear laws do not use, written into the 3-D element commands
#: (ElastomericX, HDR): rubber bulk modulus [kN/m^2], steel shim thickness [m], and the
#: cavitation and buckling parameters kc, PhiM, ac, sDratio, m at OpenSees' documented defaults.
OPENSEES_VERTICAL = {"kbulk": 2.0e6, "ts": 0.001, "kc": 10.0, "phi_m": 0.5, "ac": 1.0,
                     "sd_ratio": 0.5, "m": 0.0}


def elastomeric_bearing(name: str) -> OpenSeesElement:
    """An ``elastomericBearing*`` element of OpenSees (Plasticity, BoucWen), whose law takes
    OpenSees' positional arguments as its parameters: all parameters in order, the material
    flags (2-D ``-P -Mz``, 3-D ``-P -T -My -Mz``; default tags 1, 2, ...) and ``-orient``."""

    def args(p: Mapping[str, float], ndm: int, orient: Sequence[float],
             materials: Sequence[int] | None = None) -> list:
        flags = ("-P", "-Mz") if ndm == 2 else ("-P", "-T", "-My", "-Mz")
        tags = tuple(range(1, len(flags) + 1)) if materials is None else tuple(materials)
        if len(tags) != len(flags):
            raise ValueError(f"{name} in a {ndm}-D model takes {len(flags)} material tags "
                             f"({' '.join(flags)}), got {len(tags)}")
        out: list = list(p.values())
        for flag, tag in zip(flags, tags):
            out += [flag, tag]
        return [*out, "-orient", *orient]

    return OpenSeesElement(name, args)


@dataclass(frozen=True)
class LawSpec:
    """A shear law: its parameters, state size and kernels.

    Parameters are in kN, m, s.

    Attributes
    ----------
    step : the jitted step kernel (contract in the module docstring).
    step_robust : optional jitted robust local solve with the same contract (a positive status
        where it deviated from OpenSees); it enables ``local_solver="robust"``.
    fast_run, fast_setup : optional jitted fast solver for whole histories, bound into the
        ``law_run`` / ``law_run_setup`` slots of the history loop (contract in
        :mod:`rrfrei.laws._history`): it takes the sub-steps where it certifies the step's own
        result, the step takes the others (Bouc-Wen's :mod:`rrfrei.laws._bouc_wen_fast`).
    local_iteration : False for a closed-form update (``local_solver="robust"`` is then a no-op).
    check : optional callable taking the packed parameter array and raising ValueError for
        cross-parameter constraints.
    effects : names of the effects of an augmented law (:mod:`rrfrei.laws.effects`).
    opensees : the OpenSees element the law ports and its argument list
        (:class:`OpenSeesElement`), or None; read by :meth:`opensees_args`.
    """

    name: str
    params: tuple[ParamSpec, ...]
    state_size: int
    description: str
    step: Callable = field(default=None, compare=False, repr=False)  # type: ignore[assignment]
    step_robust: Callable | None = field(default=None, compare=False, repr=False)
    fast_run: Callable | None = field(default=None, compare=False, repr=False)
    fast_setup: Callable | None = field(default=None, compare=False, repr=False)
    opensees: OpenSeesElement | None = None
    uses_velocity: bool = False
    local_iteration: bool = True
    check: Callable[[np.ndarray], None] | None = field(default=None, compare=False, repr=False)
    effects: tuple[str, ...] = ()
    initial_state: np.ndarray = field(default=None, compare=False, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if not callable(self.step):
            raise ValueError(
                f"law {self.name!r}: step = {self.step!r} is not a kernel; expected the law's "
                "jitted step(p, sc, u, v, dt, st) -> (force, tangent, status)"
            )
        if (self.fast_run is None) != (self.fast_setup is None):
            raise ValueError(f"law {self.name!r}: fast_run and fast_setup come together (or neither)")
        for name in ("step_robust", "fast_run", "fast_setup"):
            value = getattr(self, name)
            if value is not None and not callable(value):
                raise ValueError(f"law {self.name!r}: {name} = {value!r} is not a kernel (or None)")
        if self.initial_state is None:
            object.__setattr__(self, "initial_state", np.zeros(self.state_size))
        if np.shape(self.initial_state) != (self.state_size,):
            raise ValueError(
                f"law {self.name!r}: initial_state has shape {np.shape(self.initial_state)}, "
                f"expected ({self.state_size},) (state_size)"
            )
        self.initial_state.setflags(write=False)

    def __reduce_ex__(self, protocol):
        """A registered law pickles by name (its kernels live in its module; an augmented law's
        step in a generated file), so another process rebuilds it from the registry."""
        if _REGISTRY.get(self.name) is self:
            return (get, (self.name,))
        return super().__reduce_ex__(protocol)

    # --- OpenSees ------------------------------------------------------------------------
    @property
    def opensees_element(self) -> str:
        """Name of the OpenSees element the law ports ("" for none)."""
        return self.opensees.name if self.opensees is not None else ""

    def opensees_args(self, params: Mapping[str, float] | np.ndarray | list | tuple, *,
                      ndm: int, orient: Sequence[float],
                      materials: Sequence[int] | None = None) -> list:
        """Arguments of ``ops.element(self.opensees_element, tag, i_node, j_node, *args)``
        that build the law at ``params`` (validated by :meth:`pack`; optional parameters take
        their defaults) in a ``ndm``-dimensional model with orientation ``orient``
        (:class:`OpenSeesElement`).  Raises ValueError for a law without an OpenSees element or
        a model dimension the element does not exist in."""
        if self.opensees is None:
            raise ValueError(f"law {self.name!r} has no OpenSees element")
        if ndm not in self.opensees.dims:
            raise ValueError(
                f"law {self.name!r}: OpenSees' {self.opensees.name} exists only in "
                f"{' or '.join(f'{d}-D' for d in self.opensees.dims)} models, got ndm = {ndm!r}"
            )
        if len(orient) != 6:
            raise ValueError(f"orient needs 6 numbers (local x, then local y), got {len(orient)}")
        return self.opensees.args(self.as_dict(self.pack(params)), ndm, orient, materials)

    # --- names -------------------------------------------------------------------------
    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Parameters calibrated by default: neither geometry, optional nor held."""
        return tuple(
            p.name for p in self.params if not p.geometry and not p.optional and p.hold is None
        )

    def resolve_fixed(
        self,
        geometry: Mapping[str, float] | None = None,
        fixed: Mapping[str, float] | None = None,
        sample: set[str] | frozenset[str] = frozenset(),
        *,
        source: str = "the test",
    ) -> tuple[tuple[str, ...], dict[str, float]]:
        """Split the parameters into sampled ones and fixed values, for calibration and fits.

        Order of precedence: ``fixed`` (user values), then ``geometry`` for geometry parameters,
        then, unless the parameter is named in ``sample``, the default of an optional parameter
        and the ``hold`` value of a held one.  Returns ``(free names, fixed values)``; a geometry
        parameter with neither a value nor a default raises ValueError naming it.
        """
        geometry = dict(geometry or {})
        fixed = dict(fixed or {})
        for k in fixed:
            self.param(k)  # unknown names raise, listing the law's parameters
        out: dict[str, float] = {}
        missing = []
        for p in self.params:
            if p.name in fixed:
                out[p.name] = float(fixed[p.name])
            elif p.geometry and p.name in geometry:
                out[p.name] = float(geometry[p.name])
            elif p.name in sample:
                continue
            elif p.optional:
                out[p.name] = float(p.default)
            elif p.geometry:
                missing.append(p.name)
            elif p.hold is not None:
                out[p.name] = float(p.hold)
        if missing:
            raise ValueError(
                f"law {self.name!r} needs the bearing geometry {', '.join(missing)} [m] for "
                f"{source}; give it in a sidecar TOML [geometry] table next to the test file "
                "(<file>.toml, <stem>.toml or geometry.toml, searched in that order), via "
                "read_test(geometry=...) or as fixed values"
            )
        for k, v in out.items():
            ps = self.param(k)
            if not (math.isfinite(v) and ps.lower <= v <= ps.upper):
                raise ValueError(
                    f"law {self.name!r}: fixed {k} = {v:g} {ps.unit} is outside its bounds "
                    f"[{ps.lower:g}, {ps.upper:g}] {ps.unit}"
                )
        free = tuple(p.name for p in self.params if p.name not in out)
        return free, out

    @property
    def geometry_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if p.geometry)

    def param(self, name: str) -> ParamSpec:
        for p in self.params:
            if p.name == name:
                return p
        raise ValueError(
            f"law {self.name!r} has no parameter {name!r}; its parameters are "
            f"{', '.join(self.param_names)}"
        )

    # --- validation ------------------------------------------------------------------------
    def pack(self, params: Mapping[str, float] | np.ndarray | list | tuple) -> np.ndarray:
        """Validate parameters and return them as a float64 array in kernel order.

        A mapping must name every required parameter (optional ones take their default);
        a sequence must give all parameters in :attr:`param_names` order.  Unknown, missing,
        non-finite and out-of-bounds values raise ValueError naming the parameter, its value and
        the accepted range.
        """
        names = self.param_names
        if isinstance(params, Mapping):
            extra = [k for k in params if k not in names]
            if extra:
                raise ValueError(
                    f"law {self.name!r} has no parameter(s) {', '.join(map(repr, extra))}; "
                    f"accepted: {', '.join(names)}"
                )
            values = []
            for p in self.params:
                if p.name in params:
                    values.append(params[p.name])
                elif p.optional:
                    values.append(p.default)
                else:
                    missing = [q.name for q in self.params if q.name not in params and not q.optional]
                    raise ValueError(
                        f"law {self.name!r} is missing parameter(s) {', '.join(missing)}; "
                        f"required: {', '.join(q.name for q in self.params if not q.optional)}"
                    )
            arr = np.asarray(values, dtype=float)
        else:
            arr = np.asarray(params, dtype=float).ravel()
            if arr.size != len(names):
                raise ValueError(
                    f"law {self.name!r} takes {len(names)} parameters ({', '.join(names)}), "
                    f"got {arr.size}"
                )
        for p, x in zip(self.params, arr):
            if not math.isfinite(x):
                raise ValueError(f"law {self.name!r}: parameter {p.name} = {x} is not finite")
            if not (p.lower <= x <= p.upper):
                raise ValueError(
                    f"law {self.name!r}: parameter {p.name} = {x:g} {p.unit} is outside its "
                    f"physical bounds [{p.lower:g}, {p.upper:g}] {p.unit}"
                )
        if self.check is not None:
            self.check(arr)
        return arr

    def as_dict(self, arr: np.ndarray) -> dict[str, float]:
        """Inverse of :meth:`pack`."""
        return {n: float(x) for n, x in zip(self.param_names, np.asarray(arr, dtype=float))}

    def bounds(self, names: tuple[str, ...] | None = None) -> np.ndarray:
        """(n, 2) array of physical bounds for ``names`` (default: all parameters)."""
        names = self.param_names if names is None else names
        return np.array([[self.param(n).lower, self.param(n).upper] for n in names], dtype=float)


_REGISTRY: dict[str, LawSpec] = {}


def add_entry(table: dict, spec, kind: str):
    """Put ``spec`` into ``table`` under ``spec.name`` and return it; a second, different entry
    of that name is refused (ValueError naming the ``kind`` of entry: "law", "plan law",
    "effect").  The ``register`` of every table (laws, plan laws, effects)."""
    if spec.name in table and table[spec.name] is not spec:
        article = "an" if kind[0] in "aeiou" else "a"
        raise ValueError(f"{article} {kind} named {spec.name!r} is already registered")
    table[spec.name] = spec
    return spec


def register(spec: LawSpec) -> LawSpec:
    """Add a law to the registry (names are unique)."""
    return add_entry(_REGISTRY, spec, "law")


def import_entries(package: str, path) -> None:
    """Import every module of ``package`` (its ``__path__`` is ``path``), so each registers its
    entry: the discovery of the law table and of the effect table (:mod:`rrfrei.laws.effects`).

    Modules whose name starts with ``_`` (helpers, templates) and subpackages are skipped.
    """
    import importlib
    import pkgutil

    for info in pkgutil.iter_modules(path):
        if not info.ispkg and not info.name.startswith("_"):
            importlib.import_module(f"{package}.{info.name}")


_DISCOVERED: set[str] = set()


def discover(package: str) -> None:
    """Import every module of ``package`` once (:func:`import_entries`), so each registers its
    entry; the first call does it, later calls (also those made while it imports) return."""
    if package in _DISCOVERED:
        return
    _DISCOVERED.add(package)
    import importlib

    import_entries(package, importlib.import_module(package).__path__)


def _discover() -> None:
    """Import every module of the :mod:`rrfrei.laws` package once, so each registers its law."""
    discover("rrfrei.laws")


def get(name: str | LawSpec) -> LawSpec:
    """Return the spec of law ``name``.

    Augmented laws are named ``base+effect[+effect...]`` (e.g. ``bouc_wen+rate``); they are
    composed on first use from the effect table (:mod:`rrfrei.laws.effects`).
    """
    if isinstance(name, LawSpec):
        return name
    if not isinstance(name, str):
        raise ValueError(f"a law name must be a string, got {name!r}")
    key = name.strip()
    if key in _REGISTRY:
        return _REGISTRY[key]
    _discover()
    if key in _REGISTRY:
        return _REGISTRY[key]
    if "+" in key:
        from rrfrei.laws import effects

        base, *effs = [s.strip() for s in key.split("+")]
        spec = effects.compose(get(base), effs)
        _REGISTRY[key] = spec
        return spec
    raise ValueError(f"unknown law {name!r}; available laws: {', '.join(names())}")


def _listing_order(spec: LawSpec) -> tuple:
    """OpenSees laws first, then the others; simplest (fewest parameters) first, then by name."""
    return (spec.opensees is None, len(spec.params), spec.name)


def names() -> tuple[str, ...]:
    """Names of the registered base laws, in a fixed order (independent of import order).

    The order: laws that port an OpenSees element first, then the others; within each group
    the simplest law (fewest parameters) first, then by name.  :func:`opensees_laws` gives the
    first group alone.
    """
    _discover()
    return tuple(s.name for s in sorted((s for s in _REGISTRY.values() if not s.effects),
                                        key=_listing_order))


def opensees_laws() -> tuple[str, ...]:
    """Names of the base laws that port an OpenSees element (``opensees`` set), in
    :func:`names` order: the laws compared against openseespy."""
    return tuple(n for n in names() if _REGISTRY[n].opensees is not None)


def __getattr__(attr: str):
    if attr == "OPENSEES_LAWS":  # read from the table on first use (module __getattr__)
        return opensees_laws()
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")
