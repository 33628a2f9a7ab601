"""Scene files -> `ipsph.model.Scene`: the TOML format, strictly validated.

Every parameter is declared once, in `PARAMS` (key path, type, default, unit, allowed values,
one-line doc). That table drives validation, the `--set key.path=value` overrides, the generated
reference (`reference_markdown()`, committed as docs/scene-reference.md) and `--help` text
(`override_help()`). Defaults in the table equal the dataclass defaults of `ipsph.model` (a test
checks it); a key left out of a file takes that default.

Sources: `.toml` (this module) and `.json` (SPlisHSPlasH scenes, `ipsph.splishsplash`, which
converts them to the same dict form first, so overrides and validation are shared).

Rules (house-style 6 and 7): unknown keys are refused with a "did you mean"; a wrong type or an
out-of-range value is refused naming the full key path (`fluid[1].velocity`) and the allowed
range; nothing is clamped; every error is one line (`ConfigError`, exit code 2).
Paths: mesh files resolve relative to the scene file's folder; the output folder resolves
relative to the current working directory when the run starts (it is stored as written).
"""
from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any, Iterable

from .errors import ConfigError
from .model import (BoundarySpec, FluidSpec, Method, OutputConfig, RenderConfig, Role, Scene,
                    SolverConfig, SurfaceConfig, TimeStepConfig, Transform)

__all__ = ["Param", "PARAMS", "OUTPUT_FIELDS", "RENDER_VIEWS", "load_scene", "scene_from_dict",
           "apply_overrides", "scene_to_dict", "surface_config", "default_scene_path", "reference_markdown",
           "override_help", "lattice_counts"]

# Choices shared with the writers and the renderer (io-render owns their meaning).
OUTPUT_FIELDS = ("velocity", "density", "pressure", "mass", "id")
RENDER_VIEWS = ("front", "back", "side", "top", "iso")  # = ipsph.render.VIEWS
AUTO = "auto"  # an optional value written as "auto" (or left out) means None: computed at run time


@dataclass(frozen=True)
class Param:
    """One scene parameter.

    path: dotted key path in the file (`fluid.velocity` is `velocity` in each [[fluid]] table).
    kind: float | int | bool | choice | path | vec3 | range2 | fields.
    target: where the value lands in the model: `time_step.dt_max` (Scene.time_step.dt_max),
      `particle_radius` (Scene.particle_radius); for fluid/boundary keys, the FluidSpec /
      BoundarySpec attribute (`transform.translate`). Empty: no direct model field.
    lo/hi (+ lo_open/hi_open): allowed range, per component for vectors.
    optional: the value may be None (key left out, or written "auto").
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

    @property
    def key(self) -> str:
        return self.path.rsplit(".", 1)[-1]


_INF = math.inf
_Z3 = (0.0, 0.0, 0.0)


def _P(path, kind, default, unit, doc, target="", **kw) -> Param:
    return Param(path, kind, default, unit, doc, target, **kw)


PARAMS: tuple[Param, ...] = (
    # -- top level ------------------------------------------------------------------------------
    _P("name", "str", None, "", "Scene name used in outputs and logs. Default: the scene file's "
       "name without extension.", "name"),
    _P("source", "str", None, "", "The scene file this scene was resolved from; written by "
       "ipsph into saved scenes (run.json), not normally set by hand.", "source", optional=True),
    # -- [simulation] ---------------------------------------------------------------------------
    _P("simulation.method", "choice", "ipsph", "", "Pressure solver: ipsph (the paper's "
       "method), pf (Projective Fluids) or dfsph (Divergence-Free SPH).", "method",
       choices=("ipsph", "pf", "dfsph")),
    _P("simulation.particle_radius", "float", 0.025, "m", "Particle radius r; lattice spacing "
       "d = 2r, kernel support H = 4r.", "particle_radius", lo=0.0, hi=1.0, lo_open=True),
    _P("simulation.density0", "float", 1000.0, "kg/m^3", "Rest density rho0.", "density0",
       lo=0.0, hi=1e5, lo_open=True),
    _P("simulation.gravity", "vec3", (0.0, -9.81, 0.0), "m/s^2", "Gravitational acceleration "
       "(y is up).", "gravity", lo=-1e3, hi=1e3),
    _P("simulation.end_time", "float", 2.0, "s", "Simulated time at which the run stops.",
       "end_time", lo=0.0, hi=1e6, lo_open=True),
    _P("simulation.viscosity", "float", 0.01, "", "XSPH viscosity coefficient zeta "
       "(0.01-0.03 typical; 0 disables it).", "viscosity", lo=0.0, hi=1.0),
    _P("simulation.standard_viscosity", "float", 0.0, "m^2/s", "Kinematic viscosity nu of "
       "SPlisHSPlasH's \"Standard\" viscosity (an explicit SPH viscous acceleration, "
       "docs/method.md); 0 disables it. It also limits the step to H^2 / (60 nu). "
       "SPlisHSPlasH scenes with viscosityMethod 1 set it.",
       "standard_viscosity", lo=0.0, hi=10.0),
    _P("simulation.fit_wall_volumes", "bool", False, "", "Correct the Akinci wall volumes so that "
       "fluid at rest on the lattice reads rho0 next to walls, edges and corners (docs/method.md "
       "section 1): a block that starts against walls has no corner pop (the tank at rest: 1 m/s "
       "instead of 27 m/s). Walls get up to 34 % lighter, so fast impacts come closer: the default "
       "dam break with PF and a coarse IPSPH dam break went through a wall with it. For scenes "
       "that start at rest.", "fit_wall_volumes"),
    # -- [time_step] ----------------------------------------------------------------------------
    _P("time_step.cfl_factor", "float", 1.0, "", "CFL factor lambda in "
       "dt = lambda * 0.4 * d / max|v|.", "time_step.cfl_factor", lo=0.0, hi=2.5, lo_open=True),
    _P("time_step.dt_min", "float", 1e-4, "s", "Smallest time step; steps the CFL rule would "
       "make shorter are counted and reported.", "time_step.dt_min", lo=0.0, hi=1.0,
       lo_open=True),
    _P("time_step.dt_max", "float", None, "s", "Largest time step. auto: 5 ms * r / 0.025 m.",
       "time_step.dt_max", lo=0.0, hi=1.0, lo_open=True, optional=True),
    _P("time_step.dt_initial", "float", None, "s", "First time step. auto: the CFL value of the "
       "initial velocities.", "time_step.dt_initial", lo=0.0, hi=1.0, lo_open=True,
       optional=True),
    # -- [solver] -------------------------------------------------------------------------------
    _P("solver.pair_cache_mb", "float", 64.0, "MiB", "Memory the pressure solves (DFSPH's, IPSPH's "
       "divergence solve) may use to keep each fluid pair's kernel gradient instead of evaluating "
       "it in every iteration: 24 bytes per neighbour-list slot, about 1.5 KB per particle. Over it "
       "(about 40k fluid particles), or at 0, they evaluate the kernel again: the same results up "
       "to the order of floating-point additions.",
       "solver.pair_cache_mb", lo=0.0, hi=1e6),
    # -- [solver.dfsph] -------------------------------------------------------------------------
    _P("solver.dfsph.density_error_pct", "float", 0.01, "%", "DFSPH density solve: stop when "
       "the mean density error is below this.", "solver.density_error_pct", lo=0.0, hi=100.0,
       lo_open=True),
    _P("solver.dfsph.density_min_iterations", "int", 2, "", "DFSPH density solve: minimum "
       "iterations.", "solver.density_min_iterations", lo=0, hi=100_000),
    _P("solver.dfsph.density_max_iterations", "int", 100, "", "DFSPH density solve: maximum "
       "iterations.", "solver.density_max_iterations", lo=1, hi=100_000),
    _P("solver.dfsph.divergence_error_pct", "float", 0.1, "%", "Divergence solve (DFSPH and "
       "IPSPH): stop when mean Drho/Dt <= this * rho0 / dt.", "solver.divergence_error_pct",
       lo=0.0, hi=100.0, lo_open=True),
    _P("solver.dfsph.divergence_min_iterations", "int", 1, "", "Divergence solve (DFSPH and "
       "IPSPH): minimum iterations.", "solver.divergence_min_iterations", lo=0, hi=100_000),
    _P("solver.dfsph.divergence_max_iterations", "int", 100, "", "Divergence solve (DFSPH and "
       "IPSPH): maximum iterations.", "solver.divergence_max_iterations", lo=1, hi=100_000),
    _P("solver.dfsph.divergence_solve", "bool", True, "", "Run the divergence solve (DFSPH's, and "
       "IPSPH's Algorithm 1; false turns both off, for experiments).", "solver.divergence_solve"),
    # -- [solver.pf] ----------------------------------------------------------------------------
    _P("solver.pf.stiffness", "float", 50_000.0, "", "Projective Fluids constraint stiffness "
       "k_s (PF and IPSPH).", "solver.pf_stiffness", lo=0.0, hi=1e12, lo_open=True),
    _P("solver.pf.passes", "int", 3, "", "Local/global passes per step of plain PF "
       "(SPlisHSPlasH runs 3).", "solver.pf_passes", lo=1, hi=10_000),
    # -- [solver.ipsph] -------------------------------------------------------------------------
    _P("solver.ipsph.density_error_pct", "float", 0.05, "%", "IPSPH average-density loop: stop "
       "when mean max(rho/rho0 - 1, 0) is below this.", "solver.ipsph_density_error_pct",
       lo=0.0, hi=100.0, lo_open=True),
    _P("solver.ipsph.min_passes", "int", 2, "", "IPSPH: minimum PF passes per step.",
       "solver.ipsph_min_passes", lo=1, hi=100_000),
    _P("solver.ipsph.max_passes", "int", 100, "", "IPSPH: maximum PF passes per step.",
       "solver.ipsph_max_passes", lo=1, hi=100_000),
    _P("solver.ipsph.warm_start", "float", 0.8, "", "IPSPH: fraction of the last step's PF "
       "multipliers to start from (0 = off).", "solver.ipsph_warm_start", lo=0.0, hi=1.0),
    # -- [output] -------------------------------------------------------------------------------
    _P("output.folder", "path", Path("out"), "", "Output folder; a relative path resolves "
       "against the current working directory when the run starts.", "output.folder"),
    _P("output.fps", "float", 25.0, "1/s", "Frames written per simulated second.",
       "output.fps", lo=0.0, hi=1e4, lo_open=True),
    _P("output.every_step", "bool", False, "", "Write a frame after every time step instead "
       "of at fps.", "output.every_step"),
    _P("output.fields", "fields", ("velocity", "density", "pressure", "mass", "id"), "",
       "Per-particle arrays written to each frame (positions always are).", "output.fields",
       choices=OUTPUT_FIELDS),
    _P("output.checkpoint_interval", "float", None, "s", "Simulated seconds between "
       "checkpoints. auto: no checkpoints.", "output.checkpoint_interval", lo=0.0, hi=1e6,
       lo_open=True, optional=True),
    _P("output.surface", "bool", False, "", "Also write the fluid's surface mesh of every frame, "
       "surfaces/surface_NNNNNN.vtp (triangles, normals, velocity and speed on the vertices), "
       "listed in run.pvd beside the particles; reconstructed beside the solver with the "
       "[surface] settings. `ipsph run --surface` sets it; `ipsph surface OUT` makes them later.",
       "output.surface"),
    # -- [render] -------------------------------------------------------------------------------
    _P("render.enabled", "bool", True, "", "Render a PNG of every frame during the run (`--no-render` turns it off; "
       "`ipsph render OUT --video` makes a video afterwards).",
       "render.enabled"),
    _P("render.width", "int", 1280, "px", "Image width.", "render.width", lo=16, hi=16384),
    _P("render.height", "int", 720, "px", "Image height.", "render.height", lo=16, hi=16384),
    _P("render.view", "choice", "front", "", "Named view, used when camera_position is auto.",
       "render.view", choices=RENDER_VIEWS),
    _P("render.camera_position", "vec3", None, "m", "Camera position. auto: from view.",
       "render.camera_position", optional=True),
    _P("render.focal_point", "vec3", None, "m", "Point the camera looks at. auto: the scene "
       "centre.", "render.focal_point", optional=True),
    _P("render.view_up", "vec3", None, "", "Camera up direction. auto: +y.", "render.view_up",
       optional=True),
    _P("render.speed_range", "range2", None, "m/s", "Colour-map range of the speed, fixed for the "
       "series. auto: (0, sqrt(v0^2 + 2 g drop)), the speed of a fall from the fluid's top to the "
       "floor, an estimate made before the run (splashes can exceed it: faster particles are drawn "
       "white, and the run says how to re-render with its measured maximum).", "render.speed_range",
       lo=0.0, optional=True),
    _P("render.mode", "choice", "particles", "", "What the renders show: particles (lit spheres) "
       "or surface (the reconstructed surface mesh coloured by speed, same camera and colour bar; "
       "turns output.surface on).", "render.mode", choices=("particles", "surface")),
    # -- [surface] ------------------------------------------------------------------------------
    _P("surface.smoothing_length", "float", 2.0, "r", "Smoothing length h of the colour field, in "
       "particle radii (support 2h). Larger: rounder, blobbier surfaces that bridge gaps and swallow "
       "small droplets, more volume (+1 % at 2.5 on a block at rest), cost grows about as h^3; "
       "smaller: bumpy surfaces, thin sheets tear, volume lost (-5 % at 1.5).",
       "surface.smoothing_length", lo=1.0, hi=10.0),
    _P("surface.cube_size", "float", 1.0, "r", "Edge of the marching-cubes cells, in particle "
       "radii: the resolution and the cost knob. 0.5 gives about 4x the triangles of 1.0 and takes "
       "3-4x as long (a 1M-particle frame: about 12 s at 1.0, 54 s at 0.5 on 2 busy cores); above "
       "1.5 small features and droplets fall through the grid.", "surface.cube_size",
       lo=0.05, hi=10.0),
    _P("surface.iso_threshold", "float", 0.6, "", "Level of the colour field (the SPH-interpolated "
       "fraction of rest density) at which the surface lies. Lower: a fatter surface that merges "
       "nearby droplets (+3.6 % volume at 0.5); higher: a thinner one, sheets and jets break up. "
       "No effect on cost.", "surface.iso_threshold", lo=0.0, hi=1.0, lo_open=True, hi_open=True),
    _P("surface.mesh_smoothing_iterations", "int", 10, "", "Weighted Laplacian smoothing passes "
       "over the vertices (near the free surface only, so flat sheets keep their volume): removes the "
       "marching-cubes stairs and the particles' bumps; each pass rounds edges a little more (a "
       "block at rest: -1.0 % volume at 0, -2.0 % at 10, -3.5 % at 25). Cheap.",
       "surface.mesh_smoothing_iterations", lo=0, hi=1000),
    _P("surface.normal_smoothing_iterations", "int", 10, "", "Laplacian smoothing passes over the "
       "vertex normals: smoother shading, the geometry is unchanged. Cheap.",
       "surface.normal_smoothing_iterations", lo=0, hi=1000),
    _P("surface.decimate", "bool", False, "", "Barnacle decimation and marching-cubes cleanup: "
       "about 20 % fewer, better shaped triangles (no slivers) for DCC tools, at a little more "
       "time and a little more shrinkage.", "surface.decimate"),
    # -- [[fluid]] ------------------------------------------------------------------------------
    _P("fluid.name", "str", None, "", "Name of the body. Default: fluid<i> (i counts from 0).",
       "name"),
    _P("fluid.box.min", "vec3", None, "m", "Box fluid: minimum corner. Lattice as "
       "SPlisHSPlasH's FluidBlocks: round(extent / 2r) - 1 particles per axis, the first at "
       "min + 2r.", "box_min", required=True),
    _P("fluid.box.max", "vec3", None, "m", "Box fluid: maximum corner.", "box_max",
       required=True),
    _P("fluid.mesh", "path", None, "", "Mesh fluid: closed surface mesh file, relative to the "
       "scene file. Give box or mesh, not both.", "mesh"),
    _P("fluid.translate", "vec3", _Z3, "m", "Translation t in x' = R(S x) + t. For boxes, "
       "applied to min and max.", "transform.translate"),
    _P("fluid.scale", "vec3", (1.0, 1.0, 1.0), "", "Scale S (per axis, > 0), applied first. "
       "For boxes, applied to min and max.", "transform.scale", lo=0.0, lo_open=True),
    _P("fluid.rotate_axis", "vec3", (0.0, 1.0, 0.0), "", "Rotation axis (mesh only).",
       "transform.rotate_axis"),
    _P("fluid.rotate_deg", "float", 0.0, "deg", "Rotation angle about rotate_axis (mesh only; "
       "boxes are axis-aligned).", "transform.rotate_deg", lo=-360.0, hi=360.0),
    _P("fluid.velocity", "vec3", _Z3, "m/s", "Initial velocity of every particle of the body.",
       "velocity", lo=-1e3, hi=1e3),
    _P("fluid.allow_open_mesh", "bool", False, "", "Mesh only: sample a mesh that is not "
       "watertight (at your own risk) instead of refusing it.", "allow_open_mesh"),
    # -- [[boundary]] ---------------------------------------------------------------------------
    _P("boundary.name", "str", None, "", "Name of the wall. Default: boundary<i>.", "name"),
    _P("boundary.role", "choice", "container", "", "container: the fluid lives inside the "
       "closed surface; obstacle: the fluid flows around it.", "role",
       choices=("container", "obstacle")),
    _P("boundary.box.min", "vec3", None, "m", "Box wall: minimum corner.", "box_min",
       required=True),
    _P("boundary.box.max", "vec3", None, "m", "Box wall: maximum corner.", "box_max",
       required=True),
    _P("boundary.mesh", "path", None, "", "Mesh wall: closed surface mesh file, relative to "
       "the scene file. Give box or mesh, not both.", "mesh"),
    _P("boundary.translate", "vec3", _Z3, "m", "Translation t in x' = R(S x) + t. For boxes, "
       "applied to min and max.", "transform.translate"),
    _P("boundary.scale", "vec3", (1.0, 1.0, 1.0), "", "Scale S (per axis, > 0), applied "
       "first.", "transform.scale", lo=0.0, lo_open=True),
    _P("boundary.rotate_axis", "vec3", (0.0, 1.0, 0.0), "", "Rotation axis (mesh only).",
       "transform.rotate_axis"),
    _P("boundary.rotate_deg", "float", 0.0, "deg", "Rotation angle about rotate_axis (mesh "
       "only).", "transform.rotate_deg", lo=-360.0, hi=360.0),
)

PARAM_BY_PATH: dict[str, Param] = {p.path: p for p in PARAMS}
_ENTITIES = ("fluid", "boundary")
_ENTITY_TABLE = {"fluid": "[[fluid]]", "boundary": "[[boundary]]"}

SECTION_DOCS = {
    "": "Top-level keys (outside any table).",
    "simulation": "The physics: method, resolution, material, duration.",
    "time_step": "Adaptive time step (CFL). method.md section 1.",
    "solver": "Shared by the pressure solvers.",
    "solver.dfsph": "DFSPH pressure and divergence solves (method.md section 2). The divergence "
                    "keys also drive the divergence solve of IPSPH.",
    "solver.pf": "Projective Fluids (method.md section 3); the stiffness also applies to IPSPH.",
    "solver.ipsph": "IPSPH's average-density loop around the PF passes (method.md section 4).",
    "output": "What is written, where and how often.",
    "render": "Offscreen renders of the written frames.",
    "surface": "Surface meshes of the fluid (output.surface, `ipsph surface`), reconstructed by "
               "splashsurf (docs/output-format.md). Lengths are in particle radii r.",
    "fluid": "One [[fluid]] table per fluid body: `box = {min = [..], max = [..]}` or "
             "`mesh = \"file.obj\"`. `fluid[0]` in messages is the first [[fluid]] table.",
    "boundary": "One [[boundary]] table per static wall (Akinci boundary particles on its "
                "surface): a box or a closed mesh, as a container or an obstacle.",
}


def _tree(params: Iterable[Param]) -> dict:
    root: dict = {}
    for p in params:
        node = root
        parts = p.path.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = p
    return root


_ROOT = _tree(p for p in PARAMS if p.path.split(".", 1)[0] not in _ENTITIES)
_ENTITY_TREES = {e: _tree(p for p in PARAMS if p.path.startswith(e + "."))[e] for e in _ENTITIES}
_TOP_KEYS = sorted(set(_ROOT) | set(_ENTITIES))


# ------------------------------------------------------------------------------------------------
# public API
# ------------------------------------------------------------------------------------------------

def default_scene_path() -> Path:
    """The built-in dam break (`ipsph/scenes/default.toml`)."""
    return Path(__file__).resolve().parent / "scenes" / "default.toml"


def load_scene(path: str | Path, overrides: Iterable[str] = ()) -> Scene:
    """Read a scene file (.toml, or .json for SPlisHSPlasH), apply `--set` overrides, validate.

    JSON scenes are converted to the TOML dict form first (`ipsph.splishsplash.scene_dict`), so
    overrides use the same key paths for both (`fluid.0.velocity=[1,0,0]`); the importer's
    warnings are kept in `Scene.warnings`.
    """
    given = Path(path)
    where = str(given)
    suffix = given.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise ConfigError(f"{where}: unknown scene file type {given.suffix or '(none)'!r}: "
                          f"expected .toml (ipsph scene) or .json (SPlisHSPlasH scene)")
    resolved = given.expanduser().resolve()
    if not resolved.is_file():
        raise ConfigError(f"scene file not found: {where} (resolved: {resolved})")
    warnings: tuple[str, ...] = ()
    if suffix == ".toml":
        data = _read_toml(resolved, where)
    else:
        from . import splishsplash
        data, warnings = splishsplash.scene_dict(resolved, where=where)
    data.setdefault("name", resolved.stem)
    data = apply_overrides(data, overrides)
    scene = _build_scene(data, resolved.parent, None, resolved, where)
    return dataclasses.replace(scene, warnings=tuple(warnings)) if warnings else scene


def surface_config(stored: dict | None, overrides: Iterable[str] = (), where: str = "surface") -> SurfaceConfig:
    """The [surface] settings of a stored scene dict (run.json's `scene`), with `--set surface.KEY=VALUE`
    overrides, validated by PARAMS alone: no meshes are resolved (`ipsph surface`, `ipsph render`)."""
    data = apply_overrides({"surface": dict((stored or {}).get("surface") or {})}, overrides)
    other = sorted(set(data) - {"surface"})
    if other:
        raise ConfigError(f"{where}: only surface.* keys can be set here, not {other[0]}")
    values: dict[str, Any] = {}
    _walk(_Ctx(where), data["surface"], _ROOT["surface"], "surface", values)
    return SurfaceConfig(**{PARAM_BY_PATH[k].target.split(".", 1)[1]: v for k, v in values.items()})


def scene_from_dict(data: dict, base_dir: Path | None = None, name: str | None = None, *,
                    source: Path | None = None) -> Scene:
    """Validate a dict in the TOML layout and build the Scene.

    base_dir: folder that relative mesh paths resolve against (default: current directory).
    name: scene name (default: data["name"], else "scene"). source: recorded in Scene.source
    (default: data["source"] if present).
    """
    where = str(source) if source is not None else "scene"
    return _build_scene(data, Path(base_dir) if base_dir is not None else Path.cwd(), name,
                        source, where)


def apply_overrides(data: dict, overrides: Iterable[str]) -> dict:
    """Apply `key.path=value` overrides (CLI `--set`) to a copy of `data`.

    The value is parsed as a TOML value (`1.5`, `true`, `[1, 0, 0]`, `"text"`), falling back to
    the raw string (`out/run1`, `dfsph`, `auto`). Fluid and boundary entries are addressed by
    index: `fluid.0.velocity=[1,0,0]` or `fluid[0].velocity=...`. Setting `mesh` on an entry
    drops its `box` and setting `box.min`/`box.max` drops its `mesh`. The result is validated
    by `scene_from_dict` as a whole.
    """
    import copy
    out = copy.deepcopy(data)
    for item in overrides:
        key, sep, raw = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. "
                              f"simulation.end_time=1.5")
        value = _parse_override_value(raw.strip())
        parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
        if parts[0] in _ENTITIES:
            _override_entity(out, parts, key, value)
            continue
        path = ".".join(parts)
        p = PARAM_BY_PATH.get(path)
        if p is None or path == "source":
            raise ConfigError(f"--set {key}: unknown key{_suggest_path(path)}; see "
                              f"`ipsph --help` or docs/scene-reference.md for the keys")
        node = out
        for i, part in enumerate(parts[:-1]):
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {key}: {'.'.join(parts[:i + 1])} in the scene is "
                                  f"not a table")
            node = nxt
        node[parts[-1]] = value
    return out


def scene_to_dict(scene: Scene) -> dict:
    """The Scene as a JSON-serialisable dict in the TOML layout (None values left out).

    `scene_from_dict(scene_to_dict(s)) == s`. Mesh paths are written absolute, so the dict is
    independent of the folder it is read from; boxes are written already transformed.
    """
    d: dict = {"name": scene.name}
    if scene.source is not None:
        d["source"] = str(scene.source)
    for p in PARAMS:
        if p.path.split(".", 1)[0] in _ENTITIES or p.path in ("name", "source"):
            continue
        value = _get_attr(scene, p.target)
        if value is None:
            continue
        _set_path(d, p.path, _plain(value))
    if scene.fluids:
        d["fluid"] = [_entity_to_dict("fluid", f) for f in scene.fluids]
    if scene.boundaries:
        d["boundary"] = [_entity_to_dict("boundary", b) for b in scene.boundaries]
    return d


def lattice_counts(box_min, box_max, particle_radius: float) -> tuple[int, int, int]:
    """Particles per axis of a box fluid, SPlisHSPlasH's FluidBlocks rule (denseMode 0):
    n = round(extent / 2r) - 1 with C's round (halves away from zero, not Python's banker's
    rounding); the first particle sits at min + 2r."""
    d = 2.0 * particle_radius
    return tuple(int(math.floor((hi - lo) / d + 0.5)) - 1 for lo, hi in zip(box_min, box_max))


def override_help() -> str:
    """One line per settable key, for `--help` (`--set KEY=VALUE`)."""
    lines = []
    for p in PARAMS:
        if p.path == "source":
            continue
        key = p.path
        if key.split(".", 1)[0] in _ENTITIES:
            head, rest = key.split(".", 1)
            key = f"{head}.<i>.{rest}"
        lines.append(f"  {key:<42} {_type_name(p)}, default {_fmt_default(p)}"
                     f"{' ' + p.unit if p.unit and _fmt_default(p) not in ('-', AUTO) else ''}"
                     f"{'; ' + _allowed(p) if _allowed(p) else ''}: {p.doc}")
    return "\n".join(lines)


def reference_markdown() -> str:
    """docs/scene-reference.md, generated from PARAMS (and the importer's notes)."""
    from .splishsplash import IMPORT_NOTES

    out = [
        "# Scene file reference",
        "",
        "<!-- Generated by ipsph.scene.reference_markdown() from the parameter table in "
        "ipsph/scene.py. Do not edit by hand: run `python -m ipsph.scene > "
        "docs/scene-reference.md`. -->",
        "",
        "A scene is a TOML file (start from `ipsph/scenes/default.toml`, the dam break) or a "
        "SPlisHSPlasH JSON scene (see the last section). Units are SI, y is up. Every key is "
        "optional except the shape of each body; a key left out takes the default below.",
        "",
        "- Unknown keys, wrong types and out-of-range values are refused, naming the key path "
        "(`fluid[1].velocity`, counting [[fluid]] tables from 0) and the allowed range; "
        "nothing is clamped. Integers are accepted where floats are expected; booleans are "
        "not numbers.",
        "- `auto` (or leaving the key out) for an optional key means: computed at run time, "
        "as the description says.",
        "- Mesh paths are relative to the scene file's folder. The output folder is relative "
        "to the current working directory when the run starts.",
        "- Any key can be overridden from the command line: `--set simulation.end_time=1.5`, "
        "`--set fluid.0.velocity=[1,0,0]` (values are TOML values; bare words are strings). "
        "Overrides work for SPlisHSPlasH scenes too: they are converted to this layout first.",
        "- Boxes follow SPlisHSPlasH's FluidBlocks: `round(extent / 2r) - 1` particles per axis, "
        "the first at `min + 2r`, so the first layer sits one spacing from walls that coincide "
        "with the box. `translate` and `scale` of a box are applied to its corners at load "
        "time; boxes cannot be rotated (use a mesh).",
        "",
    ]
    sections: dict[str, list[Param]] = {}
    for p in PARAMS:
        head = p.path.rsplit(".", 1)[0] if "." in p.path else ""
        if head.startswith(("fluid", "boundary")):
            head = head.split(".", 1)[0]
        sections.setdefault(head, []).append(p)
    for head, params in sections.items():
        title = {"": "Top level", "fluid": "[[fluid]]", "boundary": "[[boundary]]"}.get(
            head, f"[{head}]")
        out += [f"## {title}", "", SECTION_DOCS[head], "",
                "| key | type | default | unit | allowed | description |",
                "|---|---|---|---|---|---|"]
        for p in params:
            key = p.path[len(head) + 1:] if head else p.path
            cells = (f"`{key}`", _type_name(p), _fmt_default(p), p.unit or "-",
                     _allowed(p) or "-", p.doc)
            out.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        out.append("")
    out.append(IMPORT_NOTES.strip())
    out.append("")
    return "\n".join(out)


# ------------------------------------------------------------------------------------------------
# reading and validating
# ------------------------------------------------------------------------------------------------

def _read_toml(path: Path, where: str) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{where}: cannot read scene file (resolved: {path}): "
                          f"{' '.join(str(exc).split())}") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = " ".join(str(exc).split())
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        if m:
            msg = msg[:m.start()].strip()
            if msg == "Invalid value":
                msg += " (text values need double quotes, e.g. method = \"ipsph\")"
            raise ConfigError(f"{where}:{m.group(1)}:{m.group(2)}: TOML syntax error: {msg}") \
                from exc
        raise ConfigError(f"{where}: TOML syntax error: {msg}") from exc


class _Ctx:
    def __init__(self, where: str):
        self.where = where

    def fail(self, key: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.where}: {key}: {msg}")


def _build_scene(data: dict, base_dir: Path, name: str | None, source: Path | None,
                 where: str) -> Scene:
    ctx = _Ctx(where)
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: a scene must be a table of keys, got {_tname(data)}")
    values: dict[str, Any] = {}
    for key, value in data.items():
        if key in _ENTITIES:
            continue
        if key not in _ROOT:
            raise _unknown(ctx, key, "", _TOP_KEYS)
        node = _ROOT[key]
        if isinstance(node, Param):
            if key == "name":
                if not isinstance(value, str) or not value.strip():
                    raise ctx.fail(key, f"expected a non-empty string, got {_show(value)}")
                values[key] = value
            else:
                values[key] = _convert(ctx, node, value, key)
        else:
            _walk(ctx, value, node, key, values)

    kw: dict[str, Any] = {}
    sub: dict[str, dict] = {"time_step": {}, "solver": {}, "output": {}, "render": {}, "surface": {}}
    for ppath, v in values.items():
        p = PARAM_BY_PATH[ppath]
        head, _, attr = p.target.rpartition(".")
        (sub[head] if head else kw)[attr] = v
    kw["name"] = name or kw.get("name") or "scene"
    if source is not None:
        kw["source"] = Path(source)
    elif kw.get("source") is not None:
        kw["source"] = Path(kw["source"])
    if "method" in kw:
        kw["method"] = Method(kw["method"])
    if "folder" in sub["output"]:
        sub["output"]["folder"] = Path(sub["output"]["folder"]).expanduser()
    time_step = TimeStepConfig(**sub["time_step"])
    solver = SolverConfig(**sub["solver"])
    output = OutputConfig(**sub["output"])
    render = RenderConfig(**sub["render"])
    surface = SurfaceConfig(**sub["surface"])
    r = kw.get("particle_radius", Scene.__dataclass_fields__["particle_radius"].default)

    fluids_raw = _entity_list(ctx, data, "fluid")
    if not fluids_raw:
        raise ConfigError(f"{where}: no [[fluid]] table: a scene needs at least one fluid body "
                          f"(a box or a mesh)")
    fluids = tuple(_entity(ctx, "fluid", i, e, base_dir, r) for i, e in enumerate(fluids_raw))
    try:
        _check_sections(ctx, time_step, solver, render, r)
    except ConfigError:
        # A radius far too small also breaks the auto dt_max; its size is the error to report
        # (the runner checks the count again against --max-particles before sampling).
        from .runner import check_fluid_count
        check_fluid_count(fluids, r, None)
        raise
    boundaries = tuple(_entity(ctx, "boundary", i, e, base_dir, r)
                       for i, e in enumerate(_entity_list(ctx, data, "boundary")))
    for kind, items in (("fluid", fluids), ("boundary", boundaries)):
        seen: dict[str, int] = {}
        for i, item in enumerate(items):
            if item.name in seen:
                raise ctx.fail(f"{kind}[{i}].name", f"{item.name!r} is already the name of "
                               f"{kind}[{seen[item.name]}]; names must be unique")
            seen[item.name] = i
    return Scene(time_step=time_step, solver=solver, output=output, render=render, surface=surface,
                 fluids=fluids, boundaries=boundaries, **kw)


def _walk(ctx: _Ctx, data: Any, tree: dict, prefix: str, out: dict) -> None:
    if not isinstance(data, dict):
        raise ctx.fail(prefix, f"expected a table ([{prefix}]), got {_show(data)}")
    for key, value in data.items():
        shown = f"{prefix}.{key}"
        if key not in tree:
            raise _unknown(ctx, key, prefix, sorted(tree))
        node = tree[key]
        if isinstance(node, Param):
            out[node.path] = _convert(ctx, node, value, shown)
        else:
            _walk(ctx, value, node, shown, out)


def _unknown(ctx: _Ctx, key: str, prefix: str, allowed: list[str]) -> ConfigError:
    shown = f"{prefix}.{key}" if prefix else key
    close = difflib.get_close_matches(key, allowed, n=3, cutoff=0.6)
    if close:
        hint = "; did you mean " + " or ".join(repr(c) for c in close) + "?"
    else:
        # the right key in the wrong table: [simulation] cfl_factor -> time_step.cfl_factor
        elsewhere = [p.path for p in PARAMS if p.key == key and p.path != "source"]
        elsewhere = [re.sub(r"^(fluid|boundary)\.", r"\1[i].", e) for e in elsewhere]
        hint = ("; did you mean " + " or ".join(repr(e) for e in elsewhere) + "?"
                if elsewhere else "")
    where_ = f"[{prefix}]" if prefix else "the top level"
    return ConfigError(f"{ctx.where}: unknown key {shown!r}{hint} (allowed in {where_}: "
                       f"{', '.join(allowed)})")


def _convert(ctx: _Ctx, p: Param, value: Any, shown: str) -> Any:
    """Check one value against its Param; return it in model form."""
    if p.optional and (value is None or value == AUTO):
        return None
    kind = p.kind
    if kind == "float":
        x = _number(ctx, value, shown, p)
        _check_range(ctx, p, x, shown)
        return x
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.fail(shown, f"expected an integer, got {_show(value)}")
        _check_range(ctx, p, value, shown)
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise ctx.fail(shown, f"expected true or false, got {_show(value)}")
        return value
    if kind in ("str", "path"):
        if not isinstance(value, str) or not value.strip():
            raise ctx.fail(shown, f"expected a non-empty string, got {_show(value)}")
        return value
    if kind == "choice":
        if not isinstance(value, str) or value not in p.choices:
            close = difflib.get_close_matches(str(value), p.choices, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ctx.fail(shown, f"{_show(value)} is not one of "
                           f"{', '.join(p.choices)}{hint}")
        return value
    if kind == "vec3":
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise ctx.fail(shown, f"expected 3 numbers [x, y, z], got {_show(value)}")
        v = tuple(_number(ctx, c, f"{shown}[{i}]", p) for i, c in enumerate(value))
        for i, c in enumerate(v):
            _check_range(ctx, p, c, f"{shown}[{i}]")
        return v
    if kind == "range2":
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise ctx.fail(shown, f"expected 2 numbers [min, max], got {_show(value)}")
        lo, hi = (_number(ctx, c, f"{shown}[{i}]", p) for i, c in enumerate(value))
        _check_range(ctx, p, lo, f"{shown}[0]")
        if not lo < hi:
            raise ctx.fail(shown, f"min {_fmt(lo)} must be < max {_fmt(hi)}")
        return (lo, hi)
    if kind == "fields":
        if not isinstance(value, (list, tuple)):
            raise ctx.fail(shown, f"expected a list of field names, got {_show(value)}")
        for i, f in enumerate(value):
            if not isinstance(f, str) or f not in p.choices:
                raise ctx.fail(f"{shown}[{i}]", f"{_show(f)} is not one of "
                               f"{', '.join(p.choices)}")
        dup = sorted({f for f in value if list(value).count(f) > 1})
        if dup:
            raise ctx.fail(shown, f"listed more than once: {', '.join(dup)}")
        return tuple(value)
    raise AssertionError(f"unknown parameter kind {kind!r}")  # programming error, not input


def _number(ctx: _Ctx, value: Any, shown: str, p: Param) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ctx.fail(shown, f"expected a number, got {_show(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ctx.fail(shown, f"expected a finite number, got {_show(value)}")
    return x


def _check_range(ctx: _Ctx, p: Param, x: float, shown: str) -> None:
    bad = ((p.lo is not None and (x < p.lo or (p.lo_open and x == p.lo)))
           or (p.hi is not None and (x > p.hi or (p.hi_open and x == p.hi))))
    if bad:
        unit = f" {p.unit}" if p.unit else ""
        raise ctx.fail(shown, f"{_fmt(x)}{unit} is out of range: allowed {_allowed(p)}")


def _check_sections(ctx: _Ctx, ts: TimeStepConfig, sv: SolverConfig, rd: RenderConfig,
                    r: float) -> None:
    dt_max = ts.resolved_dt_max(r)
    if ts.dt_min > dt_max:
        src = "time_step.dt_max" if ts.dt_max is not None else \
            f"time_step.dt_max (auto: 5 ms * r / 0.025 m = {_fmt(dt_max)} s)"
        raise ctx.fail("time_step.dt_min", f"{_fmt(ts.dt_min)} s is larger than {src}; "
                       f"lower dt_min or raise dt_max")
    if ts.dt_initial is not None and not ts.dt_min <= ts.dt_initial <= dt_max:
        raise ctx.fail("time_step.dt_initial", f"{_fmt(ts.dt_initial)} s is outside "
                       f"[dt_min, dt_max] = [{_fmt(ts.dt_min)}, {_fmt(dt_max)}] s")
    for lo_key, hi_key, lo, hi in (
            ("solver.dfsph.density_min_iterations", "density_max_iterations",
             sv.density_min_iterations, sv.density_max_iterations),
            ("solver.dfsph.divergence_min_iterations", "divergence_max_iterations",
             sv.divergence_min_iterations, sv.divergence_max_iterations),
            ("solver.ipsph.min_passes", "max_passes", sv.ipsph_min_passes,
             sv.ipsph_max_passes)):
        if lo > hi:
            raise ctx.fail(lo_key, f"{lo} is larger than {hi_key} = {hi}")
    if rd.view_up is not None and not any(rd.view_up):
        raise ctx.fail("render.view_up", "must not be the zero vector")
    if (rd.camera_position is not None and rd.focal_point is not None
            and rd.camera_position == rd.focal_point):
        raise ctx.fail("render.camera_position", "equals render.focal_point; the camera needs "
                       "a direction to look in")


def _entity_list(ctx: _Ctx, data: dict, kind: str) -> list:
    raw = data.get(kind, [])
    if isinstance(raw, dict):
        raise ctx.fail(kind, f"expected an array of tables: write [[{kind}]] (double "
                       f"brackets), not [{kind}]")
    if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
        raise ctx.fail(kind, f"expected an array of tables ([[{kind}]]), got {_show(raw)}")
    return raw


def _entity(ctx: _Ctx, kind: str, i: int, entry: dict, base_dir: Path, r: float):
    prefix = f"{kind}[{i}]"
    vals: dict[str, Any] = {}
    _walk(ctx, entry, _ENTITY_TREES[kind], prefix, vals)
    g = lambda key: vals.get(f"{kind}.{key}", PARAM_BY_PATH[f"{kind}.{key}"].default)  # noqa
    name = vals.get(f"{kind}.name") or f"{kind}{i}"
    has_box, has_mesh = "box" in entry, "mesh" in entry
    if has_box == has_mesh:
        raise ctx.fail(prefix, "give exactly one shape: box = {min = [x, y, z], max = "
                       "[x, y, z]} or mesh = \"file.obj\"" + (", not both" if has_box else ""))
    t, s = g("translate"), g("scale")
    axis, deg = g("rotate_axis"), g("rotate_deg")
    if not any(axis):
        raise ctx.fail(f"{prefix}.rotate_axis", "must not be the zero vector")
    extra: dict[str, Any] = {}
    if kind == "fluid":
        extra["velocity"] = g("velocity")
    else:
        extra["role"] = Role(g("role"))
    if has_box:
        for end in ("min", "max"):
            if f"{kind}.box.{end}" not in vals:
                raise ctx.fail(f"{prefix}.box", f"missing {end} = [x, y, z]")
        if deg != 0.0:
            raise ctx.fail(f"{prefix}.rotate_deg", f"{_fmt(deg)}: boxes are axis-aligned and "
                           f"cannot be rotated; use a mesh (e.g. a box .obj) to rotate")
        if kind == "fluid" and f"{kind}.allow_open_mesh" in vals:
            raise ctx.fail(f"{prefix}.allow_open_mesh", "applies to mesh fluids only")
        lo_given, hi_given = vals[f"{kind}.box.min"], vals[f"{kind}.box.max"]
        lo = tuple(si * c + ti for si, c, ti in zip(s, lo_given, t))
        hi = tuple(si * c + ti for si, c, ti in zip(s, hi_given, t))
        note = "" if (t, s) == (_Z3, (1.0, 1.0, 1.0)) else \
            f" (after scale and translate: min {_fmt_vec(lo)}, max {_fmt_vec(hi)})"
        for a in range(3):
            if not lo[a] < hi[a]:
                raise ctx.fail(f"{prefix}.box", f"min {_fmt_vec(lo_given)} must be < max "
                               f"{_fmt_vec(hi_given)} on every axis{note}")
        if kind == "fluid":
            n = lattice_counts(lo, hi, r)
            if min(n) < 1:
                a = n.index(min(n))
                raise ctx.fail(f"{prefix}.box", f"extent {_fmt(hi[a] - lo[a])} m along "
                               f"{'xyz'[a]} holds no particle at particle_radius {_fmt(r)} m "
                               f"(round(extent / 2r) - 1 = {n[a]}); need an extent of at "
                               f"least 3r = {_fmt(3 * r)} m")
        cls = FluidSpec if kind == "fluid" else BoundarySpec
        return cls(name=name, shape="box", box_min=lo, box_max=hi, **extra)
    given = vals[f"{kind}.mesh"]
    mesh = _resolve_mesh(ctx, f"{prefix}.mesh", given, base_dir)
    tf = Transform(translate=t, scale=s, rotate_axis=axis, rotate_deg=deg)
    if kind == "fluid":
        extra["allow_open_mesh"] = g("allow_open_mesh")
        return FluidSpec(name=name, shape="mesh", mesh=mesh, transform=tf, **extra)
    return BoundarySpec(name=name, shape="mesh", mesh=mesh, transform=tf, **extra)


def _resolve_mesh(ctx: _Ctx, key: str, given: str, base_dir: Path) -> Path:
    p = Path(given).expanduser()
    resolved = (p if p.is_absolute() else base_dir / p).resolve()
    if not resolved.is_file():
        what = "is a folder, not a mesh file" if resolved.is_dir() else "mesh file not found"
        raise ctx.fail(key, f"{what}: {given!r} (resolved: {resolved}; relative paths are "
                       f"relative to the scene file's folder {base_dir})")
    return resolved


# ------------------------------------------------------------------------------------------------
# overrides and serialisation helpers
# ------------------------------------------------------------------------------------------------

def _parse_override_value(raw: str) -> Any:
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def _override_entity(out: dict, parts: list[str], key: str, value: Any) -> None:
    kind = parts[0]
    if len(parts) < 3 or not parts[1].isdigit():
        raise ConfigError(f"--set {key}: address a {_ENTITY_TABLE[kind]} entry by index, e.g. "
                          f"{kind}.0.{'velocity' if kind == 'fluid' else 'role'}=...")
    idx = int(parts[1])
    entries = out.get(kind, [])
    if not isinstance(entries, list) or not 0 <= idx < len(entries):
        n = len(entries) if isinstance(entries, list) else 0
        have = f"indices 0..{n - 1}" if n else "none"
        raise ConfigError(f"--set {key}: no {kind} number {idx} in the scene ({n} "
                          f"{_ENTITY_TABLE[kind]} table{'s' if n != 1 else ''}: {have})")
    rest = parts[2:]
    path = ".".join([kind] + rest)
    if path not in PARAM_BY_PATH:
        close = difflib.get_close_matches(path, [p.path for p in PARAMS
                                                 if p.path.startswith(kind + ".")], n=3)
        hint = ("; did you mean " + " or ".join(
            repr(f"{kind}.{idx}.{c.split('.', 1)[1]}") for c in close) + "?") if close else ""
        raise ConfigError(f"--set {key}: unknown key{hint}")
    entry = entries[idx]
    if rest == ["mesh"]:
        entry.pop("box", None)
    elif rest[0] == "box":
        entry.pop("mesh", None)
    node = entry
    for part in rest[:-1]:
        node = node.setdefault(part, {})
    node[rest[-1]] = value


def _suggest_path(path: str) -> str:
    paths = [p.path for p in PARAMS if p.path.split(".", 1)[0] not in _ENTITIES
             and p.path != "source"]
    close = difflib.get_close_matches(path, paths, n=3, cutoff=0.8)
    if not close:
        leaf = path.rsplit(".", 1)[-1]
        close = [p for p in paths if p.rsplit(".", 1)[-1] == leaf]
    return ("; did you mean " + " or ".join(repr(c) for c in close) + "?") if close else ""


def _get_attr(obj: Any, target: str) -> Any:
    for part in target.split("."):
        obj = getattr(obj, part)
    return obj


def _set_path(d: dict, path: str, value: Any) -> None:
    parts = path.split(".")
    for part in parts[:-1]:
        d = d.setdefault(part, {})
    d[parts[-1]] = value


def _plain(v: Any) -> Any:
    if isinstance(v, Enum):
        return v.value
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    return v


def _entity_to_dict(kind: str, e) -> dict:
    d: dict = {"name": e.name}
    if kind == "boundary":
        d["role"] = _plain(e.role)
    tf = e.transform
    if e.shape == "box":
        lo, hi = e.box_min, e.box_max
        if tf != Transform():
            if tf.rotate_deg != 0.0:
                raise ValueError(f"{kind} {e.name!r}: a box with a rotation cannot be written "
                                 f"in the scene format (boxes are axis-aligned)")
            lo = tuple(s * c + t for s, c, t in zip(tf.scale, lo, tf.translate))
            hi = tuple(s * c + t for s, c, t in zip(tf.scale, hi, tf.translate))
        d["box"] = {"min": _plain(lo), "max": _plain(hi)}
    else:
        d["mesh"] = str(e.mesh)
        d["translate"] = _plain(tf.translate)
        d["scale"] = _plain(tf.scale)
        d["rotate_axis"] = _plain(tf.rotate_axis)
        d["rotate_deg"] = tf.rotate_deg
        if kind == "fluid":
            d["allow_open_mesh"] = e.allow_open_mesh
    if kind == "fluid":
        d["velocity"] = _plain(e.velocity)
    return d


# ------------------------------------------------------------------------------------------------
# formatting
# ------------------------------------------------------------------------------------------------

def _fmt(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _fmt_vec(v) -> str:
    return "[" + ", ".join(_fmt(float(c)) for c in v) + "]"


def _tname(v: Any) -> str:
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, int):
        return "an integer"
    if isinstance(v, float):
        return "a float"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, (list, tuple)):
        return "an array"
    if isinstance(v, dict):
        return "a table"
    return type(v).__name__


def _show(v: Any) -> str:
    text = repr(v) if not isinstance(v, bool) else str(v).lower()
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{_tname(v)} ({text})" if not isinstance(v, (list, tuple)) else text


def _type_name(p: Param) -> str:
    return {"float": "float", "int": "integer", "bool": "boolean", "str": "string",
            "path": "path", "choice": "string", "vec3": "[x, y, z]", "range2": "[min, max]",
            "fields": "list of strings"}[p.kind]


def _fmt_default(p: Param) -> str:
    v = p.default
    if v is None:
        return AUTO if p.optional else "-"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (tuple, list)):
        if p.kind == "fields":
            return "[" + ", ".join(f'"{x}"' for x in v) + "]"
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"
    if isinstance(v, (str, Path)):
        return f'"{v}"'
    return repr(v)


def _allowed(p: Param) -> str:
    if p.choices:
        return ("any of " if p.kind == "fields" else "") + ", ".join(p.choices)
    if p.lo is None and p.hi is None:
        return ""
    what = "each component" if p.kind in ("vec3", "range2") else "value"
    lo = "" if p.lo is None else f"{_fmt(p.lo)} {'<' if p.lo_open else '<='} "
    hi = "" if p.hi is None else f" {'<' if p.hi_open else '<='} {_fmt(p.hi)}"
    return f"{lo}{what}{hi}"


if __name__ == "__main__":  # python -m ipsph.scene > docs/scene-reference.md
    print(reference_markdown(), end="")
