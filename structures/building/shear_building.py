"""Shear buildings on an isolation layer: the models (frozen, validated) and modal analysis.

Units: kN, m, s, tonnes (kN s^2/m).  Degrees of freedom (all horizontal, relative to the ground)
are ``[base, floor 1, ..., floor n]``: one isolator layer between the ground and the base slab,
and one shear spring plus dashpot per story (a chain, so every matrix is tridiagonal).

Similitude of the isolator (equal stress, ``length_scale`` s): a law calibrated on a specimen
scaled 1:s is carried to the prototype with displacements x s and forces x s^2, so the layer of
``count`` bearings gives

    F(u, v) = count s^2 F_law(u / s, v / s),     dF/du = count s k_law(u / s).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg

from rrfrei.laws import LawSpec
from rrfrei.laws import get as get_law
from rrfrei.simulate import simulate_force
from structures.building.checks import positive, positive_vector

DAMPING_KINDS = ("stiffness", "rayleigh")


@dataclass(frozen=True)
class Isolator:
    """The isolation layer: ``count`` identical bearings following ``law``.

    Parameters
    ----------
    law
        Registered law name (``rrfrei.laws.names()``), possibly augmented (``"bouc_wen+rate"``).
    params
        Law parameters by name (kN, m, s) at the scale the law was calibrated on, or None when a
        posterior will supply them (see :meth:`ShearBuilding.with_isolator_params`).  Stored
        complete (optional parameters take their defaults) after validation by
        ``LawSpec.pack``.
    count
        Number of bearings in the layer (>= 1).
    length_scale
        Similitude scale s >= 1 from the calibrated specimen to the prototype bearing:
        displacements x s, forces x s^2 (equal stress).
    """

    law: str
    params: Mapping[str, float] | None = None
    count: int = 1
    length_scale: float = 1.0

    def __post_init__(self) -> None:
        spec = get_law(self.law)  # ValueError naming the unknown law
        object.__setattr__(self, "law", spec.name)
        if isinstance(self.count, bool) or not isinstance(self.count, (int, np.integer)) or self.count < 1:
            raise ValueError(f"isolator.count = {self.count!r} is invalid: expected an integer >= 1")
        object.__setattr__(self, "count", int(self.count))
        object.__setattr__(self, "length_scale", positive("isolator.length_scale", self.length_scale))
        if self.params is not None:
            object.__setattr__(self, "params", spec.as_dict(spec.pack(self.params)))

    @property
    def spec(self) -> LawSpec:
        return get_law(self.law)

    def packed(self) -> np.ndarray:
        """Parameters as a float64 array in the law's kernel order (ValueError if not set)."""
        if self.params is None:
            raise ValueError(
                f"the isolator ({self.law!r}) has no parameters; give isolator.params or use "
                "ShearBuilding.with_isolator_params(...)"
            )
        return self.spec.pack(self.params)

    def with_params(self, params: Mapping[str, float] | np.ndarray) -> Isolator:
        """A copy with other law parameters (validated)."""
        spec = self.spec
        return replace(self, params=spec.as_dict(spec.pack(params)))

    def force(self, disp, *, substeps: int = 1) -> np.ndarray:
        """Layer force [kN] along a quasi-static displacement history ``disp`` [m] (prototype)."""
        s = self.length_scale
        f = simulate_force(self.law, self.packed(), np.asarray(disp, dtype=float) / s, substeps=substeps)
        return self.count * s * s * f

    def initial_stiffness(self) -> float:
        """Tangent stiffness [kN/m] of the virgin layer at zero displacement."""
        s = self.length_scale
        _, k = simulate_force(self.law, self.packed(), [0.0], return_tangent=True)
        return float(self.count * s * k[0])

    def effective_stiffness(self, disp: float, *, cycles: int = 3, steps_per_cycle: int = 400) -> float:
        """Secant stiffness [kN/m] of the layer in its last cycle at amplitude ``disp`` [m].

        k_eff = (F_max - F_min) / (u_max - u_min) over the last of ``cycles`` quasi-static sine
        cycles (ASCE 7-22 eq. 17.8-1 form).
        """
        d = positive("disp", disp)
        n = int(cycles) * int(steps_per_cycle)
        t = np.arange(1, n + 1) / steps_per_cycle
        u = d * np.sin(2.0 * np.pi * t)
        f = self.force(u)
        last = slice(n - steps_per_cycle, n)
        return float((f[last].max() - f[last].min()) / (u[last].max() - u[last].min()))


@dataclass(frozen=True)
class ShearBuilding:
    """A shear building (lumped story masses) on an isolation layer.

    Parameters
    ----------
    story_masses
        Floor masses [t], floor 1 first, roof last.
    story_stiffness
        Story shear stiffness [kN/m], story 1 (between the base slab and floor 1) first.
    story_heights
        Story heights [m] (drift ratio = drift / height).
    damping_ratio
        Superstructure damping ratio zeta in [0, 1).
    base_mass
        Mass of the base slab above the isolators [t].
    isolator
        The :class:`Isolator` layer between the ground and the base slab.
    damping
        ``"stiffness"``: story dashpots c_i = (2 zeta / omega_1) k_i, omega_1 the first mode of the
        superstructure with the base held fixed (OpenSees-compatible: ``uniaxialMaterial Elastic k
        eta=c`` story springs).  ``"rayleigh"``: classical Rayleigh damping on the superstructure,
        C = a0 M_s + a1 K_s with zeta in the first and the last (n-th) fixed-base modes,
        a0 = 2 zeta w_1 w_n / (w_1 + w_n), a1 = 2 zeta / (w_1 + w_n) (Chopra 2012, eq. 11.4.9);
        the mass term acts on the floors' velocity relative to the ground.  The base slab and the
        isolators get no viscous damping in either case (unless the law has some, like
        elastomeric_x's cd).
    name
        Label (the TOML file stem for loaded buildings).
    """

    story_masses: Sequence[float]
    story_stiffness: Sequence[float]
    story_heights: Sequence[float]
    damping_ratio: float
    base_mass: float
    isolator: Isolator
    damping: str = "stiffness"
    name: str = ""

    def __post_init__(self) -> None:
        m = tuple(float(x) for x in positive_vector("story_masses", self.story_masses, "t"))
        k = tuple(float(x) for x in positive_vector("story_stiffness", self.story_stiffness, "kN/m"))
        h = tuple(float(x) for x in positive_vector("story_heights", self.story_heights, "m"))
        if not (len(m) == len(k) == len(h)):
            raise ValueError(
                f"story_masses, story_stiffness and story_heights must have the same length "
                f"(one per story); got {len(m)}, {len(k)} and {len(h)}"
            )
        z = positive("damping_ratio", self.damping_ratio, allow_zero=True)
        if z >= 1.0:
            raise ValueError(f"damping_ratio = {z:g} is invalid: expected 0 <= zeta < 1")
        mb = positive("base_mass", self.base_mass)
        if not isinstance(self.isolator, Isolator):
            raise ValueError(f"isolator must be an Isolator, got {type(self.isolator).__name__}")
        if self.damping not in DAMPING_KINDS:
            raise ValueError(f"damping = {self.damping!r} is unknown; expected one of {DAMPING_KINDS}")
        for name, val in (("story_masses", m), ("story_stiffness", k), ("story_heights", h),
                          ("damping_ratio", z), ("base_mass", mb), ("name", str(self.name))):
            object.__setattr__(self, name, val)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_toml(cls, path: str | Path, isolator_params: Mapping[str, float] | None = None) -> ShearBuilding:
        """Read a building from a TOML file.

        Keys: ``story_masses`` [t], ``story_stiffness`` [kN/m], ``story_heights`` [m],
        ``damping_ratio``, ``base_mass`` [t], optional ``damping`` and ``name``, and an
        ``[isolator]`` table with ``law``, ``count``, ``length_scale`` and optionally a
        ``[isolator.params]`` table.  ``isolator_params`` replaces the file's parameters.
        """
        p = Path(path)
        where = f"building file {str(p)!r}"
        if p.is_dir():
            raise ValueError(f"{where} is a directory; expected a building TOML file")
        try:
            data = tomllib.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ValueError(f"{where} does not exist") from None
        except UnicodeDecodeError as exc:
            raise ValueError(f"{where} is not UTF-8 TOML text (byte {exc.start} is not UTF-8: a binary file, "
                             "or another encoding)") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{where} is not valid TOML: {exc}") from None
        try:
            return cls.from_mapping(data, isolator_params=isolator_params, name=p.stem, source=where)
        except ValueError as exc:
            if str(p) in str(exc):
                raise
            raise ValueError(f"{where}: {exc}") from None

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, isolator_params: Mapping[str, float] | None = None,
                     name: str = "", source: str = "building") -> ShearBuilding:
        """Build from a mapping with the keys of :meth:`from_toml`."""
        keys = ("story_masses", "story_stiffness", "story_heights", "damping_ratio", "base_mass", "isolator")
        missing = [k for k in keys if k not in data]
        if missing:
            raise ValueError(f"{source}: missing key(s) {', '.join(missing)}; required: {', '.join(keys)}")
        known = set(keys) | {"damping", "name", "description"}
        extra = sorted(set(data) - known)
        if extra:
            raise ValueError(
                f"{source}: unknown key(s) {', '.join(extra)}; accepted: {', '.join(sorted(known))}"
            )
        if not isinstance(data["isolator"], Mapping):
            raise ValueError(f"{source}: isolator must be a table ([isolator] with law, count, "
                             f"length_scale, params), got {data['isolator']!r}")
        iso = dict(data["isolator"])
        if "law" not in iso:
            raise ValueError(f"{source}: the [isolator] table needs a 'law'")
        iso_extra = sorted(set(iso) - {"law", "count", "length_scale", "params"})
        if iso_extra:
            raise ValueError(f"{source}: unknown [isolator] key(s) {', '.join(iso_extra)}; "
                             "accepted: law, count, length_scale, params")
        params = isolator_params if isolator_params is not None else iso.get("params")
        if isolator_params is None and params is not None:
            if not isinstance(params, Mapping):
                raise ValueError(f"{source}: [isolator.params] must be a table of numbers, got {params!r}")
            for key, value in params.items():
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ValueError(f"{source}: isolator.params.{key} = {value!r} is not a number")
        isolator = Isolator(iso["law"], params, count=iso.get("count", 1),
                            length_scale=iso.get("length_scale", 1.0))
        return cls(data["story_masses"], data["story_stiffness"], data["story_heights"],
                   data["damping_ratio"], data["base_mass"], isolator,
                   damping=data.get("damping", "stiffness"), name=str(data.get("name", name)))

    def with_isolator_params(self, params: Mapping[str, float] | np.ndarray) -> ShearBuilding:
        """A copy whose isolator has the parameters ``params`` (validated by the law)."""
        return replace(self, isolator=self.isolator.with_params(params))

    # ------------------------------------------------------------------ matrices
    @property
    def n_stories(self) -> int:
        return len(self.story_masses)

    @property
    def total_mass(self) -> float:
        """Base slab plus floors [t]."""
        return float(self.base_mass + sum(self.story_masses))

    def _fixed_base_eig(self) -> tuple[np.ndarray, np.ndarray]:
        m = np.asarray(self.story_masses)
        k = np.asarray(self.story_stiffness)
        n = m.size
        K = np.zeros((n, n))
        for i in range(n):  # story i joins floor i-1 (the fixed base when i = 0) and floor i
            K[i, i] += k[i]
            if i > 0:
                K[i - 1, i - 1] += k[i]
                K[i - 1, i] -= k[i]
                K[i, i - 1] -= k[i]
        w2, phi = scipy.linalg.eigh(K, np.diag(m))
        return np.sqrt(w2), phi

    def fixed_base_modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Periods [s] (longest first) and mass-normalised mode shapes (columns, floor 1 first)
        of the superstructure with the base slab held fixed."""
        w, phi = self._fixed_base_eig()
        return 2.0 * np.pi / w, phi.copy()

    def damping_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """(story dashpots c_i [kN s/m], dashpots to the ground per DOF [kN s/m]) for the
        chosen ``damping`` model; the second array covers ``[base, floors...]``."""
        w, _ = self._fixed_base_eig()
        k = np.asarray(self.story_stiffness)
        z = self.damping_ratio
        c_ground = np.zeros(self.n_stories + 1)
        if self.damping == "stiffness":
            return 2.0 * z / w[0] * k, c_ground
        w1, wn = w[0], w[-1]
        a0 = 2.0 * z * w1 * wn / (w1 + wn)
        a1 = 2.0 * z / (w1 + wn)
        c_ground[1:] = a0 * np.asarray(self.story_masses)
        return a1 * k, c_ground

    def isolated_period(self, disp: float | None = None) -> float:
        """First period [s] of the whole building with the isolator layer linearised.

        ``disp=None`` uses the layer's initial stiffness; a displacement [m] uses its secant
        (effective) stiffness in cyclic loading at that amplitude
        (:meth:`Isolator.effective_stiffness`).  The superstructure stays flexible (eigenvalue
        problem of the full chain), so this is a little longer than 2 pi sqrt(M_total / k).
        """
        iso = self.isolator
        k_iso = iso.initial_stiffness() if disp is None else iso.effective_stiffness(disp)
        if not k_iso > 0.0:
            raise ValueError(f"the isolator stiffness at disp={disp} is {k_iso:g} kN/m: no isolated period")
        m = np.concatenate(([self.base_mass], self.story_masses))
        k = np.asarray(self.story_stiffness)
        n = m.size
        K = np.zeros((n, n))
        K[0, 0] = k_iso
        for i in range(1, n):
            K[i - 1, i - 1] += k[i - 1]
            K[i, i] += k[i - 1]
            K[i - 1, i] -= k[i - 1]
            K[i, i - 1] -= k[i - 1]
        w2 = scipy.linalg.eigh(K, np.diag(m), eigvals_only=True)
        return float(2.0 * np.pi / math.sqrt(w2[0]))


# ---------------------------------------------------------------------- bundled buildings
_BUILDINGS = Path(__file__).with_name("buildings")


def available_buildings() -> tuple[str, ...]:
    """Names of the bundled example buildings."""
    return tuple(sorted(p.stem for p in _BUILDINGS.glob("*.toml")))


def load_building(name: str | Path, isolator_params: Mapping[str, float] | None = None) -> ShearBuilding:
    """A bundled example building by name (see :func:`available_buildings`), or a TOML file.

    ``name`` is read as a file when it is a ``Path``, names an existing file, or ends in
    ``.toml``; otherwise it must be a bundled name (the error lists them).
    """
    names = available_buildings()
    text = str(name)
    if isinstance(name, Path) or text.endswith(".toml") or Path(text).is_file():
        path = Path(text)
        if not path.exists():
            raise FileNotFoundError(2, "building file not found", str(path))
        return ShearBuilding.from_toml(path, isolator_params=isolator_params)
    if text not in names:
        raise ValueError(f"unknown building {text!r}; bundled buildings: {', '.join(names)} "
                         "(or give the path of a building TOML file)")
    return ShearBuilding.from_toml(_BUILDINGS / f"{text}.toml", isolator_params=isolator_params)
