"""The resolved scene: frozen dataclasses every other module reads.

`ipsph.scene` turns a TOML file, a dict or a SPlisHSPlasH JSON scene into a `Scene`;
nothing downstream parses files. Units are SI, y is up. Solver tolerances are in
percent, as in SPlisHSPlasH (`density_error_pct = 0.05` means 0.05 %).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

Vec3 = tuple[float, float, float]


class Method(StrEnum):
    IPSPH = "ipsph"
    PF = "pf"
    DFSPH = "dfsph"


class Role(StrEnum):
    CONTAINER = "container"  # fluid lives inside the closed surface
    OBSTACLE = "obstacle"    # fluid flows around the closed surface


@dataclass(frozen=True)
class Transform:
    """x' = R (S x) + t: scale first, then rotate about `rotate_axis`, then translate."""
    translate: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (1.0, 1.0, 1.0)
    rotate_axis: Vec3 = (0.0, 1.0, 0.0)
    rotate_deg: float = 0.0


@dataclass(frozen=True)
class FluidSpec:
    """A fluid body: an axis-aligned box (`box_min`, `box_max`) or a closed mesh file."""
    name: str
    shape: str                      # "box" | "mesh"
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()
    velocity: Vec3 = (0.0, 0.0, 0.0)
    allow_open_mesh: bool = False


@dataclass(frozen=True)
class BoundarySpec:
    """A static wall: a box or a closed mesh, as a container (fluid inside) or an obstacle."""
    name: str
    shape: str                      # "box" | "mesh"
    role: Role = Role.CONTAINER
    box_min: Vec3 | None = None
    box_max: Vec3 | None = None
    mesh: Path | None = None
    transform: Transform = Transform()


@dataclass(frozen=True)
class TimeStepConfig:
    cfl_factor: float = 1.0          # lambda in dt = lambda * 0.4 * d / max|v|
    dt_min: float = 1e-4             # s
    dt_max: float | None = None      # s; None: 5 ms * r / 0.025 m (method.md section 1)
    dt_initial: float | None = None  # s; None: the CFL value of the initial velocities

    def resolved_dt_max(self, particle_radius: float) -> float:
        return self.dt_max if self.dt_max is not None else 0.005 * particle_radius / 0.025


@dataclass(frozen=True)
class SolverConfig:
    # DFSPH (method.md section 2), also the divergence solve of IPSPH
    density_error_pct: float = 0.01
    density_min_iterations: int = 2
    density_max_iterations: int = 100
    divergence_error_pct: float = 0.1
    divergence_min_iterations: int = 1
    divergence_max_iterations: int = 100
    divergence_solve: bool = True
    # Projective Fluids (section 3)
    pf_stiffness: float = 50_000.0
    pf_passes: int = 3
    # IPSPH average-density loop (section 4)
    ipsph_density_error_pct: float = 0.05
    ipsph_min_passes: int = 2
    ipsph_max_passes: int = 100
    ipsph_warm_start: float = 0.8      # fraction of last step's multipliers to start from; 0 = off
    # the pressure solves' per-pair kernel gradients, kept while they fit (0 = never)
    pair_cache_mb: float = 64.0


@dataclass(frozen=True)
class OutputConfig:
    folder: Path = Path("out")
    fps: float = 25.0
    every_step: bool = False
    fields: tuple[str, ...] = ("velocity", "density", "pressure", "mass", "id")
    checkpoint_interval: float | None = None  # simulated seconds between checkpoints
    surface: bool = False                     # surfaces/surface_%06d.vtp per frame (ipsph.surface)


@dataclass(frozen=True)
class RenderConfig:
    enabled: bool = True
    width: int = 1280
    height: int = 720
    view: str = "front"                 # named view, used when no camera position is given
    camera_position: Vec3 | None = None
    focal_point: Vec3 | None = None
    view_up: Vec3 | None = None
    speed_range: tuple[float, float] | None = None  # m/s; None: from the run
    mode: str = "particles"             # "particles" | "surface" (the reconstructed surface mesh)


@dataclass(frozen=True)
class SurfaceConfig:
    """Surface reconstruction (splashsurf through ipsph.surface); lengths in multiples of r."""
    smoothing_length: float = 2.0       # kernel smoothing length h / r (support 2h)
    cube_size: float = 1.0              # marching-cubes cell edge / r: the cost knob
    iso_threshold: float = 0.6          # colour-field level of the surface (fraction of rest density)
    mesh_smoothing_iterations: int = 10  # weighted Laplacian smoothing of the vertices
    normal_smoothing_iterations: int = 10
    decimate: bool = False              # barnacle decimation + marching-cubes cleanup


@dataclass(frozen=True)
class Scene:
    name: str
    method: Method = Method.IPSPH
    particle_radius: float = 0.025
    density0: float = 1000.0
    gravity: Vec3 = (0.0, -9.81, 0.0)
    end_time: float = 2.0
    viscosity: float = 0.01             # XSPH zeta
    standard_viscosity: float = 0.0     # nu (m^2/s) of SPlisHSPlasH's "Standard" viscosity; 0 = off
    fit_wall_volumes: bool = False      # Akinci volumes fitted to the rest lattice (boundary.fit_volumes)
    time_step: TimeStepConfig = TimeStepConfig()
    solver: SolverConfig = SolverConfig()
    fluids: tuple[FluidSpec, ...] = ()
    boundaries: tuple[BoundarySpec, ...] = ()
    output: OutputConfig = OutputConfig()
    render: RenderConfig = RenderConfig()
    surface: SurfaceConfig = SurfaceConfig()
    source: Path | None = None          # the scene file, if any
    warnings: tuple[str, ...] = field(default=(), compare=False)
