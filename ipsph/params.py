"""Every declared fact the rest of ipsph is generated from.

* `PARAMS`: every scene parameter, once: key path, type, default, unit, allowed values, one line
  of doc. The model's dataclass defaults (`ipsph.model`), scene validation and `--set`
  (`ipsph.scene`), `--help`, the CLI's choices and docs/scene-reference.md are generated from it.
* `RENAMED`: keys that moved, old path -> new path; reading an old key is a one-line error that
  names the new one.
* `METHOD_NAMES`, `PHASES` (the timers a step reports, the stats.csv `ms_*` columns and the plot
  bars), `OUTPUT_FIELDS`, `RENDER_VIEWS`.

Adding a scene key: one `_P(...)` line here (and the field it lands in, in `ipsph.model`),
then `python -m ipsph.scene > docs/scene-reference.md`.

This module imports nothing from ipsph, so everything may import it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

# The lattice spacing d and the kernel support H, in particle radii r (method.md section 1)
SPACING_RADII = 2.0  # d = 2 r
SUPPORT_RADII = 4.0  # H = 4 r


def spacing(r: float) -> float:
    """The lattice spacing d = 2 r."""
    return SPACING_RADII * r


def support(r: float) -> float:
    """The kernel support H = 4 r."""
    return SUPPORT_RADII * r


METHOD_NAMES = ("ipsph", "pf", "dfsph")  # simulation.method; ipsph.methods.METHODS implements each
BACKEND_NAMES = ("cpu", "cuda")  # simulation.backend; ipsph.backends.BACKENDS implements each
PRECISIONS = ("float64", "float32")  # simulation.precision: the real arrays' type

# A step's timed phases, in report order: timer name -> (short label, what it times). Each method
# reports a subset (`Method.phases`); `Simulation.step` adds "step", the whole step.
PHASES = {
    "neighbourSearch": ("nbr", "cell sort, reordering and neighbour lists"),
    "densities": ("rho", "density pass at the end-of-step positions (DFSPH)"),
    "solvePDConstraints": ("PD", "Projective Fluids local/global passes (PF, IPSPH)"),
    "xsph": ("xsph", "viscosity pass (XSPH, Standard viscosity)"),
    "divergenceSolve": ("div", "divergence solve (DFSPH, IPSPH)"),
    "densitySolve": ("dens", "DFSPH density solve"),
}

SETTLE_MODES = ("auto", "on", "off")  # simulation.settle: the pre-pass before t = 0
BOUNDARY_ROLES = ("container", "obstacle")  # boundary.role: fluid inside the surface, or around it
MOTION_TYPES = ("static", "constant", "sinusoid", "keyframes")  # boundary.motion.type (ipsph/motion.py)
OUTPUT_FIELDS = ("velocity", "density", "pressure", "mass", "id")
# render.view: direction from the focal point to the camera, and the view-up vector (y is up)
RENDER_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "back": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "top": ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    "iso": ((0.75, 0.55, 1.0), (0.0, 1.0, 0.0)),
}
RENDER_MODES = ("particles", "surface")  # render.mode: lit particle spheres, or the surface mesh
AUTO = "auto"  # an optional value written as "auto" (or left out) means None: computed at run time


@dataclass(frozen=True)
class Param:
    """One scene parameter.

    path: dotted key path in the file (`fluid.velocity` is `velocity` in each [[fluid]] table).
    kind: float | int | bool | choice | path | vec3 | range2 | fields | keyframes.
    target: where the value lands in the model: `time_step.dt_max` (Scene.time_step.dt_max),
      `particle_radius` (Scene.particle_radius); for fluid/boundary keys, the FluidSpec /
      BoundarySpec attribute (`transform.translate`). Empty: no direct model field.
    lo/hi (+ lo_open/hi_open): allowed range, per component for vectors.
    optional: the value may be None (key left out, or written "auto").
    at_most: the path of a key whose value this one must not exceed (min <= max pairs).
    """

    path: str
    kind: str
    default: Any
    unit: str
    doc: str
    target: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] | None = None
    optional: bool = False
    required: bool = False
    at_most: str | None = None  # another key (same table) this value must not exceed

    @property
    def key(self) -> str:
        return self.path.rsplit(".", 1)[-1]


_Z3 = (0.0, 0.0, 0.0)


def _P(path, kind, default, unit, doc, target=None, **kw) -> Param:
    """One parameter; `target` (where the value lands in the model) defaults to the key path."""
    return Param(path, kind, default, unit, doc, path if target is None else target, **kw)


def _limits(
    table: str, what: str, lo: int, hi: int, solve: str, *, stem: str = "", least: int = 0
) -> tuple[Param, ...]:
    """A loop's minimum and maximum counts (`<stem>min_<what>` <= `<stem>max_<what>`)."""
    low, high = f"{table}.{stem}min_{what}", f"{table}.{stem}max_{what}"
    return (
        _P(low, "int", lo, "", f"{solve}: minimum {what}.", low, lo=least, hi=100_000, at_most=high),
        _P(high, "int", hi, "", f"{solve}: maximum {what}.", high, lo=1, hi=100_000),
    )


def _transform(kind: str) -> tuple[Param, ...]:
    """The placement keys every [[fluid]] and [[boundary]] table has (model.Transform)."""
    return (
        _P(
            f"{kind}.translate",
            "vec3",
            _Z3,
            "m",
            "Translation t in x' = R(S x) + t. For boxes, applied to min and max.",
            "transform.translate",
        ),
        _P(
            f"{kind}.scale",
            "vec3",
            (1.0, 1.0, 1.0),
            "",
            "Scale S (per axis, > 0), applied first. For boxes, applied to min and max.",
            "transform.scale",
            lo=0.0,
            lo_open=True,
        ),
        _P(f"{kind}.rotate_axis", "vec3", (0.0, 1.0, 0.0), "", "Rotation axis (mesh only).", "transform.rotate_axis"),
        _P(
            f"{kind}.rotate_deg",
            "float",
            0.0,
            "deg",
            "Rotation angle about rotate_axis (mesh only; boxes are axis-aligned).",
            "transform.rotate_deg",
            lo=-360.0,
            hi=360.0,
        ),
    )


PARAMS: tuple[Param, ...] = (
    # -- top level ------------------------------------------------------------------------------
    _P(
        "name",
        "str",
        None,
        "",
        "Scene name used in outputs and logs. Default: the scene file's name without extension.",
    ),
    _P(
        "source",
        "str",
        None,
        "",
        "The scene file this scene was resolved from; written by "
        "ipsph into saved scenes (run.json), not normally set by hand.",
        optional=True,
    ),
    # -- [simulation] ---------------------------------------------------------------------------
    _P(
        "simulation.method",
        "choice",
        "ipsph",
        "",
        "Pressure solver: ipsph (the paper's method), pf (Projective Fluids) or dfsph (Divergence-Free SPH).",
        "method",
        choices=METHOD_NAMES,
    ),
    _P(
        "simulation.backend",
        "choice",
        "cpu",
        "",
        "Where the solver runs: cpu (Numba threads) or "
        "cuda (an NVIDIA GPU through numba-cuda: pip install 'ipsph[cuda]'; docs/method.md, "
        '"Backends and precision"). The same methods and outputs on both.',
        "backend",
        choices=BACKEND_NAMES,
    ),
    _P(
        "simulation.precision",
        "choice",
        "float64",
        "",
        "Storage type of the per-particle real "
        "arrays: float64, or float32 (half the memory and bandwidth; the passes still compute and sum "
        'in float64; docs/method.md, "Backends and precision").',
        "precision",
        choices=PRECISIONS,
    ),
    _P(
        "simulation.device",
        "int",
        0,
        "",
        "With backend cuda: the number of the GPU to run on.",
        "device",
        lo=0,
        hi=1023,
    ),
    _P(
        "simulation.particle_radius",
        "float",
        0.025,
        "m",
        "Particle radius r; lattice spacing d = 2r, kernel support H = 4r.",
        "particle_radius",
        lo=0.0,
        hi=1.0,
        lo_open=True,
    ),
    _P(
        "simulation.density0", "float", 1000.0, "kg/m^3", "Rest density rho0.", "density0", lo=0.0, hi=1e5, lo_open=True
    ),
    _P(
        "simulation.gravity",
        "vec3",
        (0.0, -9.81, 0.0),
        "m/s^2",
        "Gravitational acceleration (y is up).",
        "gravity",
        lo=-1e3,
        hi=1e3,
    ),
    _P(
        "simulation.end_time",
        "float",
        2.0,
        "s",
        "Simulated time at which the run stops.",
        "end_time",
        lo=0.0,
        hi=1e6,
        lo_open=True,
    ),
    _P(
        "simulation.viscosity",
        "float",
        0.01,
        "",
        "XSPH viscosity coefficient zeta (0.01-0.03 typical; 0 disables it).",
        "viscosity",
        lo=0.0,
        hi=1.0,
    ),
    _P(
        "simulation.standard_viscosity",
        "float",
        0.0,
        "m^2/s",
        "Kinematic viscosity nu of "
        'SPlisHSPlasH\'s "Standard" viscosity (an explicit SPH viscous acceleration, '
        "docs/method.md); 0 disables it. It also limits the step to H^2 / (60 nu). "
        "SPlisHSPlasH scenes with viscosityMethod 1 set it.",
        "standard_viscosity",
        lo=0.0,
        hi=10.0,
    ),
    _P(
        "simulation.fit_wall_volumes",
        "bool",
        False,
        "",
        "Fit the Akinci wall volumes (by least "
        "squares, within 1.05 x Akinci's) so that fluid at rest on the lattice reads rho0 to 1e-5 "
        "next to walls, edges and corners (docs/method.md section 1). Box walls already read it "
        "within 0.15 % without the fit; it costs a few seconds of setup on large walls. Only static "
        "walls are fitted: moving walls and rigid bodies keep Akinci's volumes.",
        "fit_wall_volumes",
    ),
    _P(
        "simulation.settle",
        "choice",
        "auto",
        "",
        "Settle the fluid under gravity before t = 0 "
        '(docs/method.md section 1, "A start at rest"): the solver\'s own steps with the '
        "velocities damped, until a step from rest moves nothing, so a pool starts in its discrete "
        "equilibrium with its hydrostatic pressure. auto: only fluid at rest that spans its "
        "container's floor (a tank, a pool), never a column that is meant to fall or flow.",
        "settle",
        choices=SETTLE_MODES,
    ),
    # -- [time_step] ----------------------------------------------------------------------------
    _P(
        "time_step.cfl_factor",
        "float",
        1.0,
        "",
        "CFL factor lambda in dt = lambda * 0.4 * d / max|v|.",
        lo=0.0,
        hi=2.5,
        lo_open=True,
    ),
    _P(
        "time_step.dt_min",
        "float",
        1e-4,
        "s",
        "Smallest time step; steps the CFL rule would make shorter are counted and reported.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
    ),
    _P(
        "time_step.dt_max",
        "float",
        None,
        "s",
        "Largest time step. auto: 5 ms * r / 0.025 m.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
        optional=True,
    ),
    _P(
        "time_step.dt_initial",
        "float",
        None,
        "s",
        "First time step. auto: the CFL value of the initial velocities.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
        optional=True,
    ),
    # -- [solver] -------------------------------------------------------------------------------
    _P(
        "solver.pair_cache_mb",
        "float",
        64.0,
        "MiB",
        "Memory the pressure solves (DFSPH's, IPSPH's "
        "divergence solve) may use to keep each fluid pair's kernel gradient instead of evaluating "
        "it in every iteration: 24 bytes per neighbour-list slot, about 1.5 KB per particle. Over it "
        "(about 40k fluid particles), or at 0, they evaluate the kernel again: the same results up "
        "to the order of floating-point additions.",
        lo=0.0,
        hi=1e6,
    ),
    # -- [solver.divergence] ---------------------------------------------------------------------
    _P(
        "solver.divergence.enabled",
        "bool",
        True,
        "",
        "Run the divergence solve (DFSPH's, and IPSPH's Algorithm 1; false turns both off, for experiments).",
    ),
    _P(
        "solver.divergence.error_pct",
        "float",
        0.1,
        "%",
        "Divergence solve (DFSPH and IPSPH): stop when mean Drho/Dt <= this * rho0 / dt.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.divergence", "iterations", 1, 100, "Divergence solve"),
    # -- [solver.dfsph] -------------------------------------------------------------------------
    _P(
        "solver.dfsph.density_error_pct",
        "float",
        0.01,
        "%",
        "DFSPH density solve: stop when the mean density error is below this.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.dfsph", "iterations", 2, 100, "DFSPH density solve", stem="density_"),
    # -- [solver.pf] ----------------------------------------------------------------------------
    _P(
        "solver.pf.stiffness",
        "float",
        50_000.0,
        "",
        "Projective Fluids constraint stiffness k_s (PF and IPSPH).",
        lo=0.0,
        hi=1e12,
        lo_open=True,
    ),
    _P(
        "solver.pf.passes",
        "int",
        3,
        "",
        "Local/global passes per step of plain PF (SPlisHSPlasH runs 3).",
        lo=1,
        hi=10_000,
    ),
    # -- [solver.ipsph] -------------------------------------------------------------------------
    _P(
        "solver.ipsph.density_error_pct",
        "float",
        0.05,
        "%",
        "IPSPH average-density loop: stop when mean max(rho/rho0 - 1, 0) is below this.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.ipsph", "passes", 2, 100, "IPSPH: PF passes per step", least=1),
    _P(
        "solver.ipsph.warm_start",
        "float",
        0.8,
        "",
        "IPSPH: fraction of the last step's PF multipliers to start from (0 = off).",
        lo=0.0,
        hi=1.0,
    ),
    # -- [output] -------------------------------------------------------------------------------
    _P(
        "output.folder",
        "path",
        Path("out"),
        "",
        "Output folder; a relative path resolves against the current working directory when the run starts.",
    ),
    _P("output.fps", "float", 25.0, "1/s", "Frames written per simulated second.", lo=0.0, hi=1e4, lo_open=True),
    _P("output.every_step", "bool", False, "", "Write a frame after every time step instead of at fps."),
    _P(
        "output.fields",
        "fields",
        ("velocity", "density", "pressure", "mass", "id"),
        "",
        "Per-particle arrays written to each frame (positions always are).",
        choices=OUTPUT_FIELDS,
    ),
    _P(
        "output.checkpoint_interval",
        "float",
        None,
        "s",
        "Simulated seconds between checkpoints. auto: no checkpoints.",
        lo=0.0,
        hi=1e6,
        lo_open=True,
        optional=True,
    ),
    _P(
        "output.surface",
        "bool",
        False,
        "",
        "Also write the fluid's surface mesh of every frame, "
        "surfaces/surface_NNNNNN.vtp (triangles, normals, velocity and speed on the vertices), "
        "listed in run.pvd beside the particles; reconstructed beside the solver with the "
        "[surface] settings. `ipsph run --surface` sets it; `ipsph surface OUT` makes them later.",
    ),
    # -- [render] -------------------------------------------------------------------------------
    _P(
        "render.enabled",
        "bool",
        True,
        "",
        "Render a PNG of every frame during the run (`--no-render` turns it off; "
        "`ipsph render OUT --video` makes a video afterwards).",
    ),
    _P("render.width", "int", 1280, "px", "Image width.", lo=16, hi=16384),
    _P("render.height", "int", 720, "px", "Image height.", lo=16, hi=16384),
    _P(
        "render.view",
        "choice",
        "front",
        "",
        "Named view, used when camera_position is auto.",
        choices=tuple(RENDER_VIEWS),
    ),
    _P("render.camera_position", "vec3", None, "m", "Camera position. auto: from view.", optional=True),
    _P("render.focal_point", "vec3", None, "m", "Point the camera looks at. auto: the scene centre.", optional=True),
    _P("render.view_up", "vec3", None, "", "Camera up direction. auto: +y.", optional=True),
    _P(
        "render.speed_range",
        "range2",
        None,
        "m/s",
        "Colour-map range of the speed, fixed for the "
        "series. auto: (0, sqrt(v0^2 + 2 g drop)), the speed of a fall from the fluid's top to the "
        "floor, an estimate made before the run (splashes can exceed it: faster particles are drawn "
        "white, and the run says how to re-render with its measured maximum).",
        lo=0.0,
        optional=True,
    ),
    _P(
        "render.mode",
        "choice",
        "particles",
        "",
        "What the renders show: particles (lit spheres) "
        "or surface (the reconstructed surface mesh coloured by speed, same camera and colour bar; "
        "turns output.surface on).",
        choices=RENDER_MODES,
    ),
    # -- [surface] ------------------------------------------------------------------------------
    _P(
        "surface.smoothing_length",
        "float",
        2.0,
        "r",
        "Smoothing length h of the colour field, in "
        "particle radii (support 2h). Larger: rounder, blobbier surfaces that bridge gaps and swallow "
        "small droplets, more volume (+1 % at 2.5 on a block at rest), cost grows about as h^3; "
        "smaller: bumpy surfaces, thin sheets tear, volume lost (-5 % at 1.5).",
        lo=1.0,
        hi=10.0,
    ),
    _P(
        "surface.cube_size",
        "float",
        1.0,
        "r",
        "Edge of the marching-cubes cells, in particle "
        "radii: the resolution and the cost knob. 0.5 gives about 4x the triangles of 1.0 and takes "
        "3-4x as long (a 1M-particle frame: about 12 s at 1.0, 54 s at 0.5 on 2 busy cores); above "
        "1.5 small features and droplets fall through the grid.",
        lo=0.05,
        hi=10.0,
    ),
    _P(
        "surface.iso_threshold",
        "float",
        0.6,
        "",
        "Level of the colour field (the SPH-interpolated "
        "fraction of rest density) at which the surface lies. Lower: a fatter surface that merges "
        "nearby droplets (+3.6 % volume at 0.5); higher: a thinner one, sheets and jets break up. "
        "No effect on cost.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
        hi_open=True,
    ),
    _P(
        "surface.mesh_smoothing_iterations",
        "int",
        10,
        "",
        "Weighted Laplacian smoothing passes "
        "over the vertices (near the free surface only, so flat sheets keep their volume): removes the "
        "marching-cubes stairs and the particles' bumps; each pass rounds edges a little more (a "
        "block at rest: -1.0 % volume at 0, -2.0 % at 10, -3.5 % at 25). Cheap.",
        lo=0,
        hi=1000,
    ),
    _P(
        "surface.normal_smoothing_iterations",
        "int",
        10,
        "",
        "Laplacian smoothing passes over the vertex normals: smoother shading, the geometry is unchanged. Cheap.",
        lo=0,
        hi=1000,
    ),
    _P(
        "surface.decimate",
        "bool",
        False,
        "",
        "Barnacle decimation and marching-cubes cleanup: "
        "about 20 % fewer, better shaped triangles (no slivers) for DCC tools, at a little more "
        "time and a little more shrinkage.",
    ),
    # -- [[fluid]] ------------------------------------------------------------------------------
    _P("fluid.name", "str", None, "", "Name of the body. Default: fluid<i> (i counts from 0).", "name"),
    _P(
        "fluid.box.min",
        "vec3",
        None,
        "m",
        "Box fluid: minimum corner. Lattice as "
        "SPlisHSPlasH's FluidBlocks: round(extent / 2r) - 1 particles per axis, the first at "
        "min + 2r.",
        "box_min",
        required=True,
    ),
    _P("fluid.box.max", "vec3", None, "m", "Box fluid: maximum corner.", "box_max", required=True),
    _P(
        "fluid.mesh",
        "path",
        None,
        "",
        "Mesh fluid: closed surface mesh file, relative to the scene file. Give box or mesh, not both.",
        "mesh",
    ),
    *_transform("fluid"),
    _P(
        "fluid.velocity",
        "vec3",
        _Z3,
        "m/s",
        "Initial velocity of every particle of the body.",
        "velocity",
        lo=-1e3,
        hi=1e3,
    ),
    _P(
        "fluid.allow_open_mesh",
        "bool",
        False,
        "",
        "Mesh only: sample a mesh that is not watertight (at your own risk) instead of refusing it.",
        "allow_open_mesh",
    ),
    # -- [[boundary]] ---------------------------------------------------------------------------
    _P("boundary.name", "str", None, "", "Name of the wall. Default: boundary<i>.", "name"),
    _P(
        "boundary.role",
        "choice",
        "container",
        "",
        "container: the fluid lives inside the closed surface; obstacle: the fluid flows around it.",
        "role",
        choices=BOUNDARY_ROLES,
    ),
    _P("boundary.box.min", "vec3", None, "m", "Box wall: minimum corner.", "box_min", required=True),
    _P("boundary.box.max", "vec3", None, "m", "Box wall: maximum corner.", "box_max", required=True),
    _P(
        "boundary.mesh",
        "path",
        None,
        "",
        "Mesh wall: closed surface mesh file, relative to the scene file. Give box or mesh, not both.",
        "mesh",
    ),
    *_transform("boundary"),
    # -- [[boundary]] motion and rigid bodies (ipsph/motion.py, ipsph/rigid.py; method.md section 9) ----
    _P(
        "boundary.motion.type",
        "choice",
        "static",
        "",
        "Prescribed motion of the wall (a kinematic "
        "wall: it pushes the fluid, the fluid does not push it): static, constant (velocity and "
        "angular_velocity), sinusoid (a paddle or piston: amplitude along axis and/or angle_amplitude "
        "about axis, with period and phase_deg) or keyframes. The scene places the wall at t = 0; "
        "every motion is an offset from there.",
        "motion.type",
        choices=MOTION_TYPES,
    ),
    _P(
        "boundary.motion.velocity", "vec3", _Z3, "m/s", "constant: linear velocity.", "motion.velocity", lo=-1e3, hi=1e3
    ),
    _P(
        "boundary.motion.angular_velocity",
        "vec3",
        _Z3,
        "deg/s",
        "constant: angular velocity about pivot (the vector's direction is the axis, right-handed).",
        "motion.angular_velocity",
        lo=-1e5,
        hi=1e5,
    ),
    _P(
        "boundary.motion.pivot",
        "vec3",
        None,
        "m",
        "Centre of rotation at t = 0 (it moves with the wall). auto: the centre of the wall's bounding box.",
        "motion.pivot",
        optional=True,
    ),
    _P(
        "boundary.motion.axis",
        "vec3",
        (1.0, 0.0, 0.0),
        "",
        "sinusoid: direction of the displacement and axis of the rotation (normalised).",
        "motion.axis",
    ),
    _P(
        "boundary.motion.amplitude",
        "float",
        0.0,
        "m",
        "sinusoid: displacement amplitude A: the "
        "wall moves by A (sin(2 pi t / period + phase) - sin(phase)) along axis.",
        "motion.amplitude",
        lo=0.0,
        hi=1e3,
    ),
    _P(
        "boundary.motion.angle_amplitude",
        "float",
        0.0,
        "deg",
        "sinusoid: rotation amplitude about axis through pivot (a flap paddle), with the same time dependence.",
        "motion.angle_amplitude",
        lo=0.0,
        hi=180.0,
    ),
    _P(
        "boundary.motion.period",
        "float",
        None,
        "s",
        "sinusoid: period (required, > 0).",
        "motion.period",
        lo=0.0,
        hi=1e6,
        lo_open=True,
        optional=True,
    ),
    _P(
        "boundary.motion.phase_deg",
        "float",
        0.0,
        "deg",
        "sinusoid: phase; -90 starts at rest at one end of the stroke (no jerk at t = 0), 0 starts at full speed.",
        "motion.phase_deg",
        lo=-360.0,
        hi=360.0,
    ),
    _P(
        "boundary.motion.keyframes",
        "keyframes",
        (),
        "",
        "keyframes: an array of tables "
        "{time, translate = [x, y, z], rotate_axis = [x, y, z], rotate_deg} with strictly "
        "increasing times: the wall's offset from its placement, interpolated by Catmull-Rom "
        "cubic Hermite splines (translation) and slerp (rotation about pivot); held before the "
        "first and after the last keyframe.",
        "motion.keyframes",
    ),
    _P(
        "boundary.density",
        "float",
        None,
        "kg/m^3",
        "Makes the wall a dynamic rigid body "
        "(role obstacle, a closed surface) of this density: the fluid pushes it and it pushes "
        "back, under gravity, with contacts (method.md section 9). auto: not a body.",
        "density",
        lo=0.0,
        hi=1e6,
        lo_open=True,
        optional=True,
    ),
    _P(
        "boundary.mass",
        "float",
        None,
        "kg",
        "A dynamic body's mass instead of density (give one of them). auto: from density.",
        "mass",
        lo=0.0,
        hi=1e9,
        lo_open=True,
        optional=True,
    ),
    _P("boundary.velocity", "vec3", _Z3, "m/s", "A dynamic body's initial velocity.", "velocity", lo=-1e3, hi=1e3),
    _P(
        "boundary.angular_velocity",
        "vec3",
        _Z3,
        "deg/s",
        "A dynamic body's initial angular velocity.",
        "angular_velocity",
        lo=-1e5,
        hi=1e5,
    ),
)

# -- [[emitter]], [[sink]], [domain]: fluid entering and leaving (ipsph.emitters) ---------------
EMITTER_SHAPES = ("box", "circle")  # emitter.shape: a rectangular or a circular nozzle

PARAMS += (
    _P(
        "domain.min",
        "vec3",
        None,
        "m",
        "Domain box, minimum corner: fluid that leaves the box "
        "is removed (an outflow on every side). auto: no domain box; fluid leaving the containers' "
        "bounds is then a numerical failure. SPlisHSPlasH's emitterBoxMin with emitterReuseParticles.",
        optional=True,
    ),
    _P("domain.max", "vec3", None, "m", "Domain box, maximum corner.", optional=True),
    _P("emitter.name", "str", None, "", "Name of the emitter. Default: emitter<i>.", "name"),
    _P(
        "emitter.shape",
        "choice",
        "box",
        "",
        "Nozzle shape: box (width x height) or circle (radius), as SPlisHSPlasH's Emitters type 0 / 1.",
        "shape",
        choices=EMITTER_SHAPES,
    ),
    _P(
        "emitter.position",
        "vec3",
        None,
        "m",
        "Centre of the nozzle's outlet; the first layer of each emission is placed here and moves off along direction.",
        "position",
        required=True,
    ),
    _P(
        "emitter.direction",
        "vec3",
        (1.0, 0.0, 0.0),
        "",
        "Direction the fluid leaves in (normalised; SPlisHSPlasH: the first column of the emitter's rotation).",
        "direction",
    ),
    _P(
        "emitter.height_axis",
        "vec3",
        None,
        "",
        "Box nozzle: the direction of its height (made "
        "perpendicular to direction). auto: +y, or +z when the direction is vertical.",
        "height_axis",
        optional=True,
    ),
    _P(
        "emitter.width",
        "float",
        None,
        "m",
        "Box nozzle: width; round(width / 2r) particles across (at least 1).",
        "width",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.height",
        "float",
        None,
        "m",
        "Box nozzle: height; round(height / 2r) particles.",
        "height",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.radius",
        "float",
        None,
        "m",
        "Circle nozzle: radius; the lattice points of spacing 2r within it.",
        "radius",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.velocity",
        "float",
        1.0,
        "m/s",
        "Speed of the emitted fluid along direction. A "
        "layer leaves every 2r / velocity seconds, so the mass rate is rho0 * A * velocity "
        "(A: the particles of a layer times (2r)^2).",
        "velocity",
        lo=0.0,
        lo_open=True,
        hi=1e3,
    ),
    _P("emitter.start_time", "float", 0.0, "s", "First emission.", "start_time", lo=0.0, hi=1e6),
    _P(
        "emitter.end_time",
        "float",
        None,
        "s",
        "Last emission (no layer after it). auto: simulation.end_time.",
        "end_time",
        lo=0.0,
        lo_open=True,
        hi=1e6,
        optional=True,
    ),
    _P("sink.name", "str", None, "", "Name of the sink. Default: sink<i>.", "name"),
    _P(
        "sink.min",
        "vec3",
        None,
        "m",
        "Outflow box, minimum corner: fluid inside is removed after every step.",
        "box_min",
        required=True,
    ),
    _P("sink.max", "vec3", None, "m", "Outflow box, maximum corner.", "box_max", required=True),
)

PARAM_BY_PATH: dict[str, Param] = {p.path: p for p in PARAMS}
_ENTITIES = ("fluid", "boundary")
_ENTITY_TABLE = {"fluid": "[[fluid]]", "boundary": "[[boundary]]"}

SECTION_DOCS = {
    "": "Top-level keys (outside any table).",
    "simulation": "The physics: method, resolution, material, duration.",
    "time_step": "Adaptive time step (CFL). method.md section 1.",
    "solver": "Shared by the pressure solvers.",
    "solver.divergence": "The divergence solve of DFSPH and of IPSPH (method.md sections 2, 4).",
    "solver.dfsph": "DFSPH's density solve (method.md section 2).",
    "solver.pf": "Projective Fluids (method.md section 3); the stiffness also applies to IPSPH.",
    "solver.ipsph": "IPSPH's average-density loop around the PF passes (method.md section 4).",
    "output": "What is written, where and how often.",
    "render": "Offscreen renders of the written frames.",
    "surface": "Surface meshes of the fluid (output.surface, `ipsph surface`), reconstructed by "
    "splashsurf (docs/output-format.md). Lengths are in particle radii r.",
    "fluid": "One [[fluid]] table per fluid body: `box = {min = [..], max = [..]}` or "
    '`mesh = "file.obj"`. `fluid[0]` in messages is the first [[fluid]] table.',
    "boundary": "One [[boundary]] table per wall (Akinci boundary particles on its "
    "surface): a box or a closed mesh, as a container or an obstacle. A wall is static, "
    'moves as prescribed (`motion = {type = "sinusoid", ...}`: a kinematic wall) or, '
    "with a density or mass, is a dynamic rigid body two-way coupled to the fluid.",
    "domain": "Optional box outside which fluid is removed (docs/output-format.md: particle counts vary).",
    "emitter": "One [[emitter]] table per nozzle emitting fluid layers at a velocity from start_time "
    "to end_time (SPlisHSPlasH's Emitters). Its position must lie inside a container's "
    "bounds or the [domain] box. New particles carry rho0 (2r)^3 and fresh ids.",
    "sink": "One [[sink]] table per axis-aligned outflow box: fluid entering it is removed (ids are never reused).",
}

# keys that moved: old path -> new path (a scene that uses the old one gets a one-line error)
RENAMED = {
    "solver.dfsph.divergence_error_pct": "solver.divergence.error_pct",
    "solver.dfsph.divergence_min_iterations": "solver.divergence.min_iterations",
    "solver.dfsph.divergence_max_iterations": "solver.divergence.max_iterations",
    "solver.dfsph.divergence_solve": "solver.divergence.enabled",
}


def default(path: str) -> Any:
    """The declared default of a parameter (the model's dataclasses take theirs from here)."""
    return PARAM_BY_PATH[path].default
