"""ParaView for an output folder: `OUT/paraview_view.py`, a script that opens the run as it was rendered.

`write_view_script(OUT)` fills this run's settings (particle radius, colour range, camera, files,
a default SPH probe line) into the template `view_script.py` and writes OUT/paraview_view.py;
`ipsph run` does it when the run ends, `ipsph paraview OUT` on demand. The script runs in
ParaView's own Python (pvpython, the GUI's Python shell) and imports nothing from ipsph.

ParaView's SPH interpolators need settings their defaults get silently wrong (docs/output-format.md):
the cubic kernel with Spatial Step = H / 2 (VTK's cubic reaches two spatial steps; our support is
H = 4r, kernels.py), Density Array `density`, Mass Array `mass`, and Shepard normalisation.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pprint
from pathlib import Path

import numpy as np

from ... import io as out_io
from ...errors import OutputError

__all__ = ["sph_spatial_step", "frame_field_data", "view_settings", "write_view_script", "TEMPLATE"]

TEMPLATE = Path(__file__).with_name("view_script.py")
SUPPORT_PER_RADIUS = 4.0  # H = 4r (kernels.py, simulation.Simulation.support)
VTK_CUBIC_REACH = 2.0  # vtkSPHCubicKernel is zero beyond 2 x its spatial step
LINE_SAMPLES_PER_RADIUS = 2.0  # default probe line: a sample every r / 2
MAX_LINE_SAMPLES = 2000
DENSITY_ARRAY, MASS_ARRAY = "density", "mass"
DEJAVU_SANS = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"  # Debian's fonts-dejavu-core, a ParaView dependency


def sph_spatial_step(particle_radius: float) -> float:
    """The Spatial Step of VTK's (ParaView's) cubic SPH kernel that matches our kernel: H / 2 = 2r."""
    return SUPPORT_PER_RADIUS * float(particle_radius) / VTK_CUBIC_REACH


def frame_field_data(particle_radius: float) -> dict[str, float]:
    """Field data every particle file carries besides `TimeValue` (m): what SPH filters need.

    The step is Float32 on purpose: meshio (5.3) rewrites raw appended offsets one array at a time
    and looks each old offset up among arrays it has already rewritten; three 16-byte Float64
    field arrays put the first point array at raw offset 48, which the third field array's
    rewritten offset also reads, and meshio then reads `velocity` as 2 values. Float64, Float64,
    Float32 (44 bytes) does not collide; tests/test_end_to_end.py reads every frame with meshio."""
    return {
        "particle_radius": float(particle_radius),
        "sph_spatial_step": np.float32(sph_spatial_step(particle_radius)),
    }


def _render_config(run: dict):
    """The render settings of the run: run.json's `render` (the renders'), else the scene's."""
    from ...config import RenderConfig

    names = {f.name for f in dataclasses.fields(RenderConfig)}
    stored = run.get("render") or {}
    if "width" not in stored:  # --no-render or no GL: the scene's settings
        stored = (run.get("scene") or {}).get("render") or {}
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in stored.items() if k in names}
    return dataclasses.replace(RenderConfig(), **kw)


def _speed_range(out: Path, run: dict, config) -> list[float]:
    """The colour range the run's renders used, else the scene's, else the run's maximum speed."""
    rng = (run.get("render") or {}).get("speed_range") or config.speed_range
    if not rng:
        from ...io.stats import read_stats

        v = np.zeros(0)
        if (out / out_io.STATS_CSV).is_file():
            v = read_stats(out / out_io.STATS_CSV).get("max_speed", v)
            v = v[np.isfinite(v)]
        rng = (0.0, float(v.max()) if len(v) and v.max() > 0 else 1.0)
    return [float(rng[0]), float(rng[1])]


def _probe_line(bounds: np.ndarray, fluid_bounds: np.ndarray, gravity, r: float):
    """Along gravity's axis through the middle of the initial fluid, across the domain (inset by r)."""
    g = np.asarray(gravity, dtype=float)
    axis = int(np.argmax(np.abs(g))) if np.any(g) else 1
    mid = fluid_bounds.mean(axis=1)
    p1, p2 = mid.copy(), mid.copy()
    p1[axis], p2[axis] = bounds[axis, 0] + r, bounds[axis, 1] - r
    if g[axis] > 0:  # from the bottom (against gravity) up
        p1, p2 = p2, p1
    n = int(min(MAX_LINE_SAMPLES, max(10, math.ceil(abs(p2[axis] - p1[axis]) * LINE_SAMPLES_PER_RADIUS / r))))
    return [round(float(v), 6) for v in p1], [round(float(v), 6) for v in p2], n


# Every part of run.pvd (io.PARTS) and the key of `view_settings()["files"]` the script opens it by:
# the script shows every part a run wrote.
PART_FILES = {
    "fluid": "fluid",
    "surface": "surface",
    "boundary": "wall_particles",
    "boundary_surface": "walls",
    "bodies": "bodies",
}


def view_settings(out_dir) -> dict:
    """The values paraview_view.py needs, from the run in `out_dir` (run.json, frame 0, stats)."""
    from ...io.provenance import read_run_json
    from ...io.pvd import PvdSeries
    from ...io.vtu import read_particles
    from .. import render

    out = Path(out_dir)
    if not (out / out_io.RUN_JSON).is_file() or not (out / out_io.RUN_PVD).is_file():
        raise OutputError(
            f"{out} (resolved {out.resolve()}) holds no run.json and run.pvd: give the output folder of `ipsph run`"
        )
    run = read_run_json(out / out_io.RUN_JSON)
    series = PvdSeries.load(out / out_io.RUN_PVD)
    if not series.frames:
        raise OutputError(f"{out / out_io.RUN_PVD} lists no frame yet")
    r = float(run["particle_radius"])
    scene = run.get("scene") or {}
    sim = scene.get("simulation") or {}
    config = _render_config(run)
    bounds = np.asarray(run["domain_bounds"], dtype=float).reshape(3, 2)
    x0 = read_particles(out / series.frames[0][1])[0]
    fluid_bounds = np.stack([x0.min(axis=0), x0.max(axis=0)], axis=1) if len(x0) else bounds
    gravity = sim.get("gravity", (0.0, -9.81, 0.0))
    p1, p2, n = _probe_line(bounds, fluid_bounds, gravity, r)
    pos, focal, up = render.camera_for_view(
        bounds,
        config.view,
        width=config.width,
        height=config.height,
        camera_position=config.camera_position,
        focal_point=config.focal_point,
        view_up=config.view_up,
    )
    fluid_series = out_io.part("fluid").series

    def series_of(name: str) -> str | None:  # a per-frame part's own series, when the run wrote it
        f = out_io.part(name).series
        return f if (out / f).is_file() else None

    title = " - ".join(
        str(x)
        for x in (
            scene.get("name"),
            (run.get("method") or "").upper(),
            f"{run['fluid_particles']:,} particles" if run.get("fluid_particles") else None,
        )
        if x
    )
    return {
        "folder": str(out.resolve()),
        "files": {
            "fluid": fluid_series,
            "walls": out_io.BOUNDARY_SURFACE if (out / out_io.BOUNDARY_SURFACE).is_file() else None,
            "wall_particles": out_io.BOUNDARY_VTU if (out / out_io.BOUNDARY_VTU).is_file() else None,
            "surface": series_of("surface"),
            "bodies": series_of("bodies"),
        },
        "surface_visible": config.mode == "surface",
        "particle_radius": r,
        "density0": float(sim.get("density0", 1000.0)),
        "gravity": [float(v) for v in gravity],
        "speed_range": _speed_range(out, run, config),
        "speed_colours": [list(render._rgb(c)) for c in render.SPEED_COLOURS],
        "speed_title": render.SPEED_TITLE,
        "scalar_bar": {"position": list(render.SCALAR_BAR_POSITION), "length": render.SCALAR_BAR_LENGTH},
        "background": [list(render._rgb(c)) for c in render.BACKGROUND],
        "wall_colour": list(render._rgb(render.SURFACE_COLOUR)),
        "wall_opacity": render.SURFACE_OPACITY,
        "edge_opacity": render.EDGE_OPACITY,
        "title": title,
        "title_colour": list(render._rgb(render.TITLE_COLOUR)),
        "font_files": [render._font_file(), DEJAVU_SANS],
        "image_size": [int(config.width), int(config.height)],
        "camera": {
            "position": [float(v) for v in pos],
            "focal_point": [float(v) for v in focal],
            "view_up": [float(v) for v in up],
            "view_angle": render.VIEW_ANGLE_DEG,
        },
        "sph": {
            "point1": p1,
            "point2": p2,
            "resolution": n,
            "spatial_step": sph_spatial_step(r),
            "density_array": DENSITY_ARRAY,
            "mass_array": MASS_ARRAY,
        },
    }


def write_view_script(out_dir) -> Path:
    """Write OUT/paraview_view.py (atomically) for the run in `out_dir`; return its path.

    A folder from before run.pvd named its parts (no fluid.pvd) gets its series rewritten first."""
    from ...io.pvd import PvdSeries

    out = Path(out_dir)
    settings = view_settings(out)
    if not (out / settings["files"]["fluid"]).is_file():
        PvdSeries.load(out / out_io.RUN_PVD).write()
    text = TEMPLATE.read_text()
    marker = "SETTINGS = {}  # filled in by ipsph.post.paraview.write_view_script"
    if marker not in text:  # pragma: no cover - the template and this module change together
        raise RuntimeError(f"{TEMPLATE} lacks its SETTINGS line")
    filled = "SETTINGS = " + pprint.pformat(json.loads(json.dumps(settings)), sort_dicts=False, width=100)
    path = out / out_io.PARAVIEW_SCRIPT
    with out_io.atomic_path(path, "ParaView script") as tmp:
        tmp.write_text(text.replace(marker, filled))
    return path
