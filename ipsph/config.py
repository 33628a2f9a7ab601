"""The resolved scene: frozen dataclasses every other module reads.

`ipsph.scene` turns a TOML file, a dict or a SPlisHSPlasH JSON scene into a `Scene`;
nothing downstream parses files. Units are SI, y is up. Solver tolerances are in
percent, as in SPlisHSPlasH (`density_error_pct = 0.05` means 0.05 %). Every default, unit,
range and description is declared once, in `ipsph.params.PARAMS`: the config tables below are
generated from it (`_section`), and so are the Scene and the [[fluid]], [[boundary]], motion,
[[emitter]], [[sink]] and [[gauge]] specs (`_declared`: a field per key that lands on them, in PARAMS'
order, with its type and default). Only what no key declares is written here: the shared `Body`
(a shape, its box or mesh, its `Transform`), keyframes, the Scene's tables and where it came from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass
from enum import StrEnum
from pathlib import Path

from .params import BOUNDARY_ROLES, COURANT, METHOD_NAMES, PARAMS, VISCOUS_STEP, auto_dt_max, spacing, support
from .params import default as D

Vec3 = tuple[float, float, float]

Method = StrEnum("Method", {name.upper(): name for name in METHOD_NAMES})  # simulation.method
Role = StrEnum("Role", {name.upper(): name for name in BOUNDARY_ROLES})  # boundary.role


_TYPES = {
    "float": float,
    "int": int,
    "bool": bool,
    "choice": str,
    "str": str,
    "path": Path,
    "vec3": tuple[float, float, float],
    "range2": tuple[float, float],
    "fields": tuple[str, ...],
}

ENUMS = {"simulation.method": Method, "boundary.role": Role}  # choices held as StrEnum members


def _declared(table: str, skip=(), nested: dict | None = None) -> list:
    """A dataclass field per parameter of `table` that lands directly on it (its target has no
    dot, or is `<nested>.<key>`: then the nested dataclass, once, where its first key stands), in
    the order params.PARAMS declares them; names, types and defaults as declared there. Fields
    without a default (required keys, except those in `skip`) come first, as dataclasses need."""
    nested = nested or {}
    required, rest, seen = [], [], set()
    for p in PARAMS:
        head, _, key = p.path.partition(".")
        if head != table or p.target in skip:
            continue
        owner, dot, attr = p.target.partition(".")
        if dot:
            if owner in nested and owner not in seen:
                seen.add(owner)
                rest.append((owner, nested[owner], field(default=nested[owner]())))
            continue
        kind = ENUMS.get(p.path) or _TYPES[p.kind]
        if p.required or p.default is None and not p.optional:
            required.append((p.target, kind))
        else:
            default = ENUMS[p.path](p.default) if p.path in ENUMS else p.default
            rest.append((p.target, kind | None if p.optional else kind, field(default=default)))
    return required + rest


def _spec(name: str, doc: str, fields: list, bases: tuple = (), **namespace) -> type:
    return make_dataclass(
        name, fields, bases=bases, frozen=True, namespace={"__doc__": doc, "__module__": __name__, **namespace}
    )


@dataclass(frozen=True)
class Transform:
    """x' = R (S x) + t: scale first, then rotate about `rotate_axis`, then translate."""

    translate: Vec3 = D("fluid.translate")
    scale: Vec3 = D("fluid.scale")
    rotate_axis: Vec3 = D("fluid.rotate_axis")
    rotate_deg: float = D("fluid.rotate_deg")


_BODY_TARGETS = ("name", "box_min", "box_max", "mesh")  # Body's own fields (and `transform.*`)


@dataclass(frozen=True)
class Body:
    """What a fluid body and a wall share: a name, and an axis-aligned box or a mesh file, placed."""

    name: str
    shape: str  # "box" | "mesh"
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()


FluidSpec = _spec(
    "FluidSpec",
    "A fluid body ([[fluid]]): the box is filled with a lattice, a closed mesh's inside too.",
    _declared("fluid", skip=_BODY_TARGETS),
    (Body,),
)


@dataclass(frozen=True)
class Keyframe:
    """One keyframe of a wall's motion: its offset from the placement at `time`."""

    time: float
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate_axis: Vec3 = (0.0, 1.0, 0.0)
    rotate_deg: float = 0.0


MotionSpec = _spec(
    "MotionSpec",
    "[boundary.motion]: a prescribed (kinematic) motion, evaluated by ipsph.boundary.motion.",
    [
        (
            p.target.partition(".")[2],
            _TYPES.get(p.kind, tuple[Keyframe, ...]) | None if p.optional else _TYPES.get(p.kind, tuple[Keyframe, ...]),
            field(default=p.default),
        )
        for p in PARAMS
        if p.path.startswith("boundary.motion.")
    ],
)


class _Wall:
    """What a wall's fields say about it."""

    @property
    def dynamic(self) -> bool:
        """A rigid body the fluid pushes (a density or a mass was given)."""
        return self.density is not None or self.mass is not None

    @property
    def moving(self) -> bool:
        """Not a static wall: a prescribed motion or a dynamic body."""
        return self.dynamic or self.motion.type != "static"


BoundarySpec = _spec(
    "BoundarySpec",
    """A wall ([[boundary]]): a container (fluid inside) or an obstacle (fluid around); static,
    moving as prescribed (`motion`), or a dynamic rigid body (`density` or `mass` set).""",
    _declared("boundary", skip=_BODY_TARGETS, nested={"motion": MotionSpec}),
    (Body, _Wall),
)


EmitterSpec = _spec(
    "EmitterSpec",
    """A nozzle ([[emitter]]): fluid layers leave `position` along `direction` at `velocity`
    from start_time to end_time (ipsph.flow). Sizes in metres (width/height or radius).""",
    _declared("emitter"),
)


SinkSpec = _spec(
    "SinkSpec", "An outflow box ([[sink]]): fluid inside it is removed after every step.", _declared("sink")
)


GaugeSpec = _spec(
    "GaugeSpec",
    """A gauge ([[gauge]]): a time series at a point, along a vertical line, on a wall or through a
    rectangle (ipsph.gauges); `quantities` resolved to the kind's list, `interval` None: every step.""",
    _declared("gauge"),
)


def _section(name: str, table: str, doc: str, nested: dict | None = None, **methods) -> type:
    """The frozen dataclass of one scene table: a field per parameter of `table` (its name, type
    and default as params.PARAMS declares them), then the sub-tables in `nested`."""
    own = [p for p in PARAMS if p.target.rpartition(".")[0] == table]
    fields = [
        (p.target.rpartition(".")[2], _TYPES[p.kind] | None if p.optional else _TYPES[p.kind], field(default=p.default))
        for p in own
    ]
    fields += [(key, cls, field(default=cls())) for key, cls in (nested or {}).items()]
    return make_dataclass(name, fields, frozen=True, namespace={"__doc__": doc, "__module__": __name__, **methods})


def _resolved_dt_max(self, particle_radius: float) -> float:
    """time_step.dt_max, or its auto value (params.auto_dt_max)."""
    return self.dt_max if self.dt_max is not None else auto_dt_max(particle_radius)


TimeStepConfig = _section(
    "TimeStepConfig", "time_step", "[time_step]: the CFL step (method.md section 1).", resolved_dt_max=_resolved_dt_max
)
DivergenceConfig = _section(
    "DivergenceConfig",
    "solver.divergence",
    "[solver.divergence]: DFSPH's divergence solve, also IPSPH's (method.md 2, 4).",
)
DFSPHConfig = _section("DFSPHConfig", "solver.dfsph", "[solver.dfsph]: DFSPH's density solve (method.md 2).")
PFConfig = _section(
    "PFConfig", "solver.pf", "[solver.pf]: Projective Fluids (method.md 3); the stiffness is IPSPH's too."
)
IPSPHConfig = _section("IPSPHConfig", "solver.ipsph", "[solver.ipsph]: IPSPH's average-density loop (method.md 4).")
ViscosityConfig = _section(
    "ViscosityConfig", "solver.viscosity", "[solver.viscosity]: the implicit viscosity solve (method.md 10)."
)
SolverConfig = _section(
    "SolverConfig",
    "solver",
    "[solver] and its per-method sub-tables.",
    {
        "divergence": DivergenceConfig,
        "dfsph": DFSPHConfig,
        "pf": PFConfig,
        "ipsph": IPSPHConfig,
        "viscosity": ViscosityConfig,
    },
)
OutputConfig = _section("OutputConfig", "output", "[output]: what is written, where, how often.")
RenderConfig = _section("RenderConfig", "render", "[render]: the offscreen renders.")
DomainConfig = _section(
    "DomainConfig", "domain", "[domain]: the box outside which fluid is removed (both corners or none)."
)
SurfaceConfig = _section(
    "SurfaceConfig",
    "surface",
    "[surface]: surface reconstruction (splashsurf through ipsph.post.surface); lengths in multiples of r.",
)


class _Derived:
    """What follows from a scene's particle radius r, derived here and nowhere else (method.md section 1)."""

    @property
    def spacing(self) -> float:
        """The lattice spacing d = 2 r."""
        return spacing(self.particle_radius)

    @property
    def support(self) -> float:
        """The kernel support H = 4 r."""
        return support(self.particle_radius)

    @property
    def fluid_mass(self) -> float:
        """Every fluid particle carries the water of its lattice cell, rho0 d^3."""
        return self.density0 * self.spacing**3

    @property
    def dt_max(self) -> float:
        """time_step.dt_max, or its auto value (params.auto_dt_max)."""
        return self.time_step.resolved_dt_max(self.particle_radius)

    @property
    def viscous_dt(self) -> float:
        """H^2 / (VISCOUS_STEP nu): the explicit Standard viscosity's step limit (inf without it)."""
        nu = self.kinematic_viscosity_m2s if self.viscosity_model == "standard" else 0.0  # implicit: none
        h = self.support
        return h * h / (VISCOUS_STEP * nu) if nu > 0.0 else math.inf

    def cfl_step(self, vmax: float) -> tuple[float, bool]:
        """The CFL rule: dt = clamp(min(cfl_factor COURANT d / vmax, viscous_dt), dt_min, dt_max), and
        whether the raw value fell below dt_min."""
        ts = self.time_step
        raw = ts.cfl_factor * COURANT * self.spacing / vmax if vmax > 0 else math.inf
        raw = min(raw, self.viscous_dt)
        return min(max(raw, ts.dt_min), self.dt_max), raw < ts.dt_min

    def rest_dt(self) -> float:
        """The CFL rule's step at rest: dt_max, at most the viscous limit (never below dt_min)."""
        return min(self.dt_max, max(self.viscous_dt, self.time_step.dt_min))


Scene = _spec(
    "Scene",
    "A resolved scene: [simulation]'s keys, the tables, the bodies, emitters and sinks, where it was read from.",
    [("name", str)]
    + _declared("simulation")
    + [
        ("time_step", TimeStepConfig, field(default=TimeStepConfig())),
        ("solver", SolverConfig, field(default=SolverConfig())),
        ("fluids", tuple[FluidSpec, ...], field(default=())),
        ("boundaries", tuple[BoundarySpec, ...], field(default=())),
        ("emitters", tuple[EmitterSpec, ...], field(default=())),
        ("sinks", tuple[SinkSpec, ...], field(default=())),
        ("gauges", tuple[GaugeSpec, ...], field(default=())),
        ("domain", DomainConfig, field(default=DomainConfig())),
        ("output", OutputConfig, field(default=OutputConfig())),
        ("render", RenderConfig, field(default=RenderConfig())),
        ("surface", SurfaceConfig, field(default=SurfaceConfig())),
        ("source", Path | None, field(default=None)),  # the scene file, if any
        ("warnings", tuple[str, ...], field(default=(), compare=False)),
    ],
    (_Derived,),
)
