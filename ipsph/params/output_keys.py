"""The [output], [render] and [surface] keys."""

from __future__ import annotations

from pathlib import Path

from .facts import OUTPUT_FIELDS, RENDER_MODES, RENDER_VIEWS
from .schema import _P, Param

KEYS: tuple[Param, ...] = (
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
)
