"""The resolved scene: frozen dataclasses every other module reads.

`ipsph.scene` turns a TOML file, a dict or a SPlisHSPlasH JSON scene into a `Scene`;
nothing downstream parses files. Units are SI, y is up. Solver tolerances are in
percent, as in SPlisHSPlasH (`density_error_pct = 0.05` means 0.05 %). Every default, unit,
range and description is declared once, in `ipsph.params.PARAMS` (`D(path)` below reads it):
this module only says where each value lands.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

from .params import BOUNDARY_ROLES, METHOD_NAMES
from .params import default as D

Vec3 = tuple[float, float, float]

Method = StrEnum("Method", {name.upper(): name for name in METHOD_NAMES})  # simulation.method
Role = StrEnum("Role", {name.upper(): name for name in BOUNDARY_ROLES})    # boundary.role


@dataclass(frozen=True)
class Transform:
    """x' = R (S x) + t: scale first, then rotate about `rotate_axis`, then translate."""
    translate: Vec3 = D("fluid.translate")
    scale: Vec3 = D("fluid.scale")
    rotate_axis: Vec3 = D("fluid.rotate_axis")
    rotate_deg: float = D("fluid.rotate_deg")


@dataclass(frozen=True)
class FluidSpec:
    """A fluid body: an axis-aligned box (`box_min`, `box_max`) or a closed mesh file."""
    name: str
    shape: str                      # "box" | "mesh"
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()
    velocity: Vec3 = D("fluid.velocity")
    allow_open_mesh: bool = D("fluid.allow_open_mesh")


@dataclass(frozen=True)
class BoundarySpec:
    """A static wall: a box or a closed mesh, as a container (fluid inside) or an obstacle."""
    name: str
    shape: str                      # "box" | "mesh"
    role: Role = Role(D("boundary.role"))
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()


@dataclass(frozen=True)
class TimeStepConfig:
    cfl_factor: float = D("time_step.cfl_factor")
    dt_min: float = D("time_step.dt_min")
    dt_max: float | None = D("time_step.dt_max")          # None: 5 ms * r / 0.025 m
    dt_initial: float | None = D("time_step.dt_initial")  # None: the CFL value of the initial velocities

    def resolved_dt_max(self, particle_radius: float) -> float:
        return self.dt_max if self.dt_max is not None else 0.005 * particle_radius / 0.025


@dataclass(frozen=True)
class DivergenceConfig:
    """[solver.divergence]: DFSPH's divergence solve, also IPSPH's (method.md sections 2, 4)."""
    enabled: bool = D("solver.divergence.enabled")
    error_pct: float = D("solver.divergence.error_pct")
    min_iterations: int = D("solver.divergence.min_iterations")
    max_iterations: int = D("solver.divergence.max_iterations")


@dataclass(frozen=True)
class DFSPHConfig:
    """[solver.dfsph]: DFSPH's density solve (method.md section 2)."""
    density_error_pct: float = D("solver.dfsph.density_error_pct")
    density_min_iterations: int = D("solver.dfsph.density_min_iterations")
    density_max_iterations: int = D("solver.dfsph.density_max_iterations")


@dataclass(frozen=True)
class PFConfig:
    """[solver.pf]: Projective Fluids (method.md section 3); the stiffness is IPSPH's too."""
    stiffness: float = D("solver.pf.stiffness")
    passes: int = D("solver.pf.passes")


@dataclass(frozen=True)
class IPSPHConfig:
    """[solver.ipsph]: IPSPH's average-density loop (method.md section 4)."""
    density_error_pct: float = D("solver.ipsph.density_error_pct")
    min_passes: int = D("solver.ipsph.min_passes")
    max_passes: int = D("solver.ipsph.max_passes")
    warm_start: float = D("solver.ipsph.warm_start")


@dataclass(frozen=True)
class SolverConfig:
    pair_cache_mb: float = D("solver.pair_cache_mb")
    divergence: DivergenceConfig = DivergenceConfig()
    dfsph: DFSPHConfig = DFSPHConfig()
    pf: PFConfig = PFConfig()
    ipsph: IPSPHConfig = IPSPHConfig()


@dataclass(frozen=True)
class OutputConfig:
    folder: Path = D("output.folder")
    fps: float = D("output.fps")
    every_step: bool = D("output.every_step")
    fields: tuple[str, ...] = D("output.fields")
    checkpoint_interval: float | None = D("output.checkpoint_interval")  # None: no checkpoints


@dataclass(frozen=True)
class RenderConfig:
    enabled: bool = D("render.enabled")
    width: int = D("render.width")
    height: int = D("render.height")
    view: str = D("render.view")
    camera_position: Vec3 | None = D("render.camera_position")
    focal_point: Vec3 | None = D("render.focal_point")
    view_up: Vec3 | None = D("render.view_up")
    speed_range: tuple[float, float] | None = D("render.speed_range")  # m/s; None: from the run


@dataclass(frozen=True)
class Scene:
    name: str
    method: Method = Method(D("simulation.method"))
    particle_radius: float = D("simulation.particle_radius")
    density0: float = D("simulation.density0")
    gravity: Vec3 = D("simulation.gravity")
    end_time: float = D("simulation.end_time")
    viscosity: float = D("simulation.viscosity")
    standard_viscosity: float = D("simulation.standard_viscosity")
    time_step: TimeStepConfig = TimeStepConfig()
    solver: SolverConfig = SolverConfig()
    fluids: tuple[FluidSpec, ...] = ()
    boundaries: tuple[BoundarySpec, ...] = ()
    output: OutputConfig = OutputConfig()
    render: RenderConfig = RenderConfig()
    source: Path | None = None          # the scene file, if any
    warnings: tuple[str, ...] = field(default=(), compare=False)
