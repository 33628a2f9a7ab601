"""The resolved scene: frozen dataclasses every other module reads.

`ipsph.scene` turns a TOML file, a dict or a SPlisHSPlasH JSON scene into a `Scene`;
nothing downstream parses files. Units are SI, y is up. Solver tolerances are in
percent, as in SPlisHSPlasH (`density_error_pct = 0.05` means 0.05 %). Every default, unit,
range and description is declared once, in `ipsph.params.PARAMS`: the config tables below are
generated from it (`_section`), and the scene's and bodies' own fields read their defaults from
it (`D(path)`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass
from enum import StrEnum
from pathlib import Path

from .params import BOUNDARY_ROLES, COURANT, METHOD_NAMES, PARAMS, VISCOUS_STEP, spacing, support
from .params import default as D

Vec3 = tuple[float, float, float]

Method = StrEnum("Method", {name.upper(): name for name in METHOD_NAMES})  # simulation.method
Role = StrEnum("Role", {name.upper(): name for name in BOUNDARY_ROLES})  # boundary.role


@dataclass(frozen=True)
class Transform:
    """x' = R (S x) + t: scale first, then rotate about `rotate_axis`, then translate."""

    translate: Vec3 = D("fluid.translate")
    scale: Vec3 = D("fluid.scale")
    rotate_axis: Vec3 = D("fluid.rotate_axis")
    rotate_deg: float = D("fluid.rotate_deg")


@dataclass(frozen=True)
class Body:
    """What a fluid body and a wall share: a name, and an axis-aligned box or a mesh file, placed."""

    name: str
    shape: str  # "box" | "mesh"
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()


@dataclass(frozen=True)
class FluidSpec(Body):
    """A fluid body ([[fluid]]): the box is filled with a lattice, a closed mesh's inside too."""

    velocity: Vec3 = D("fluid.velocity")
    allow_open_mesh: bool = D("fluid.allow_open_mesh")


@dataclass(frozen=True)
class Keyframe:
    """One keyframe of a wall's motion: its offset from the placement at `time`."""

    time: float
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate_axis: Vec3 = (0.0, 1.0, 0.0)
    rotate_deg: float = 0.0


@dataclass(frozen=True)
class MotionSpec:
    """[boundary.motion]: a prescribed (kinematic) motion, evaluated by ipsph.motion."""

    type: str = D("boundary.motion.type")
    velocity: Vec3 = D("boundary.motion.velocity")
    angular_velocity: Vec3 = D("boundary.motion.angular_velocity")  # deg/s
    pivot: Vec3 | None = D("boundary.motion.pivot")
    axis: Vec3 = D("boundary.motion.axis")
    amplitude: float = D("boundary.motion.amplitude")
    angle_amplitude: float = D("boundary.motion.angle_amplitude")  # deg
    period: float | None = D("boundary.motion.period")
    phase_deg: float = D("boundary.motion.phase_deg")
    keyframes: tuple[Keyframe, ...] = ()


@dataclass(frozen=True)
class BoundarySpec(Body):
    """A wall ([[boundary]]): a container (fluid inside) or an obstacle (fluid around); static,
    moving as prescribed (`motion`), or a dynamic rigid body (`density` or `mass` set)."""

    role: Role = Role(D("boundary.role"))
    motion: MotionSpec = MotionSpec()
    density: float | None = D("boundary.density")
    mass: float | None = D("boundary.mass")
    velocity: Vec3 = D("boundary.velocity")
    angular_velocity: Vec3 = D("boundary.angular_velocity")  # deg/s

    @property
    def dynamic(self) -> bool:
        """A rigid body the fluid pushes (a density or a mass was given)."""
        return self.density is not None or self.mass is not None

    @property
    def moving(self) -> bool:
        """Not a static wall: a prescribed motion or a dynamic body."""
        return self.dynamic or self.motion.type != "static"


@dataclass(frozen=True)
class EmitterSpec:
    """A nozzle ([[emitter]]): fluid layers leave `position` along `direction` at `velocity`
    from start_time to end_time (ipsph.emitters). Sizes in metres (width/height or radius)."""

    name: str
    position: Vec3
    shape: str = D("emitter.shape")
    direction: Vec3 = D("emitter.direction")
    height_axis: Vec3 | None = None
    width: float | None = None
    height: float | None = None
    radius: float | None = None
    velocity: float = D("emitter.velocity")
    start_time: float = D("emitter.start_time")
    end_time: float | None = None


@dataclass(frozen=True)
class SinkSpec:
    """An outflow box ([[sink]]): fluid inside it is removed after every step."""

    name: str
    box_min: Vec3
    box_max: Vec3


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
    """time_step.dt_max, or its auto value 5 ms * r / 0.025 m."""
    return self.dt_max if self.dt_max is not None else 0.005 * particle_radius / 0.025


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
SolverConfig = _section(
    "SolverConfig",
    "solver",
    "[solver] and its per-method sub-tables.",
    {"divergence": DivergenceConfig, "dfsph": DFSPHConfig, "pf": PFConfig, "ipsph": IPSPHConfig},
)
OutputConfig = _section("OutputConfig", "output", "[output]: what is written, where, how often.")
RenderConfig = _section("RenderConfig", "render", "[render]: the offscreen renders.")
DomainConfig = _section(
    "DomainConfig", "domain", "[domain]: the box outside which fluid is removed (both corners or none)."
)
SurfaceConfig = _section(
    "SurfaceConfig",
    "surface",
    "[surface]: surface reconstruction (splashsurf through ipsph.surface); lengths in multiples of r.",
)


@dataclass(frozen=True)
class Scene:
    name: str
    method: Method = Method(D("simulation.method"))
    backend: str = D("simulation.backend")
    precision: str = D("simulation.precision")
    device: int = D("simulation.device")
    particle_radius: float = D("simulation.particle_radius")
    density0: float = D("simulation.density0")
    gravity: Vec3 = D("simulation.gravity")
    end_time: float = D("simulation.end_time")
    viscosity: float = D("simulation.viscosity")
    standard_viscosity: float = D("simulation.standard_viscosity")
    fit_wall_volumes: bool = D("simulation.fit_wall_volumes")
    settle: str = D("simulation.settle")
    time_step: TimeStepConfig = TimeStepConfig()
    solver: SolverConfig = SolverConfig()
    fluids: tuple[FluidSpec, ...] = ()
    boundaries: tuple[BoundarySpec, ...] = ()
    emitters: tuple[EmitterSpec, ...] = ()
    sinks: tuple[SinkSpec, ...] = ()
    domain: DomainConfig = DomainConfig()
    output: OutputConfig = OutputConfig()
    render: RenderConfig = RenderConfig()
    surface: SurfaceConfig = SurfaceConfig()
    source: Path | None = None  # the scene file, if any
    warnings: tuple[str, ...] = field(default=(), compare=False)

    # -- what follows from the particle radius r, derived here and nowhere else (method.md section 1)
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
        """time_step.dt_max, or its auto value (5 ms * r / 0.025 m)."""
        return self.time_step.resolved_dt_max(self.particle_radius)

    @property
    def viscous_dt(self) -> float:
        """H^2 / (VISCOUS_STEP nu): the explicit Standard viscosity's step limit (inf without it)."""
        nu = self.standard_viscosity
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
