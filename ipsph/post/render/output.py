"""Rendering an output folder (`ipsph render OUT`): PNGs of every frame, and videos."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...config import RenderConfig
from ...errors import ConfigError, OutputError
from ...io import STATS_CSV, render_file, video_file
from ...io.pvd import frame_index
from ...io.vtu import read_surface
from ...params import RENDER_MODES
from .frame import FrameRenderer


def _render_config(run: dict, overrides: dict | None) -> RenderConfig:
    fields = {f.name for f in dataclasses.fields(RenderConfig)}
    stored = {k: v for k, v in (run.get("render") or {}).items() if k in fields}
    for k in ("camera_position", "focal_point", "view_up", "speed_range"):
        if stored.get(k) is not None:
            stored[k] = tuple(stored[k])
    overrides = dict(overrides or {})
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ConfigError(f"unknown render setting(s) {', '.join(unknown)}; allowed: {', '.join(sorted(fields))}")
    return dataclasses.replace(RenderConfig(), **{**stored, **overrides})


def _speed_range_for(out: Path, run: dict, frames: list[tuple[float, str]], given) -> tuple[float, float]:
    """Given range, else the max of stats.csv max_speed over the run, else the data's max speed."""
    from ...io.stats import read_stats
    from ...io.vtu import read_particles

    if given is not None:
        return (float(given[0]), float(given[1]))
    stats = out / STATS_CSV
    if stats.is_file():
        s = read_stats(stats)
        v = s.get("max_speed", np.zeros(0))
        v = v[np.isfinite(v)]
        if len(v) and v.max() > 0:
            return (0.0, float(v.max()))
    vmax = 0.0
    for _, f in frames:
        _, fields, _ = read_particles(out / f)
        if "velocity" in fields and len(fields["velocity"]):
            vmax = max(vmax, float(np.linalg.norm(fields["velocity"], axis=1).max()))
    if vmax > 0:
        return (0.0, vmax)
    used = (run.get("render") or {}).get("speed_range")
    return (float(used[0]), float(used[1])) if used else (0.0, 1.0)


def render_output(
    out_dir,
    *,
    speed_range=None,
    config_overrides: dict | None = None,
    video: str | None = None,
    fps: float | None = None,
    frames: slice | None = None,
    progress=None,
    mode: str | None = None,
) -> list[Path]:
    """Render every frame of a finished or still-running output folder to OUT/renders/*.png.

    Reads run.json (render settings, radius, bounds), run.pvd (frames written so far) and
    boundary_surface.vtp. Colour range: `speed_range`, else max of stats.csv `max_speed`, else
    the frames' data. `video` = "mp4" | "gif" also writes OUT/video.<ext>. Returns written paths.
    `mode` = "particles" | "surface" (default: the run's render.mode): "surface" renders
    OUT/surfaces/surface_NNNNNN.vtp, reconstructing first the frames that have none (`ipsph surface`).
    """
    from ...io import BOUNDARY_SURFACE, RUN_JSON, RUN_PVD
    from ...io.provenance import read_run_json
    from ...io.pvd import PvdSeries
    from ...io.vtu import read_particles

    out = Path(out_dir)
    if not (out / RUN_PVD).is_file():
        raise OutputError(
            f"{out} (resolved {out.resolve()}) is not an ipsph output folder: no {RUN_PVD}; "
            f"give the folder that `ipsph run` wrote"
        )
    if video not in (None, "mp4", "gif"):
        raise ConfigError(f"video = {video!r} is not a video format; allowed: mp4, gif")
    run = read_run_json(out / RUN_JSON) if (out / RUN_JSON).is_file() else {}
    config = _render_config(run, config_overrides)
    mode = mode or config.mode
    if mode not in RENDER_MODES:
        raise ConfigError(f"render mode {mode!r} is not one of {', '.join(RENDER_MODES)}")
    if mode == "surface":
        from ..surface import surface_output

        surface_output(out)  # the frames without a surface yet (one warning line per failed frame)
    series = PvdSeries.load(out / RUN_PVD)
    todo = list(enumerate(series.frames))
    if frames is not None:
        todo = todo[frames]
    rng = _speed_range_for(out, run, series.frames, speed_range if speed_range is not None else config.speed_range)
    surface = read_surface(out / BOUNDARY_SURFACE)

    radius = run.get("particle_radius")
    bounds = run.get("domain_bounds")
    if bounds is None or radius is None:  # no provenance: fit the data
        from vtkmodules.util.numpy_support import vtk_to_numpy

        pts = [read_particles(out / f)[0] for _, (_, f) in todo[:1]]
        walls = (
            [vtk_to_numpy(surface.GetPoints().GetData())] if surface is not None and surface.GetNumberOfPoints() else []
        )
        allp = np.concatenate(pts + walls) if pts else np.zeros((1, 3))
        bounds = bounds or [v for i in range(3) for v in (allp[:, i].min(), allp[:, i].max())]
        if radius is None:
            radius = 0.01 * float(np.ptp(allp, axis=0).max() or 1.0)
    scene = run.get("scene") or {}
    title = " - ".join(
        str(x)
        for x in (
            scene.get("name"),
            (run.get("method") or "").upper(),  # no '|': VTK drops it
            "emitters and sinks"
            if run.get("flow")
            # the count varies
            else f"{run['fluid_particles']:,} particles"
            if run.get("fluid_particles")
            else None,
        )
        if x
    )
    if fps is None:
        fps = float((scene.get("output") or {}).get("fps") or 25.0)

    written: list[Path] = []
    pngs: list[Path] = []
    with FrameRenderer(config, bounds, radius, rng, surface, title=title) as r:
        for k, (i, (t, f)) in enumerate(todo):
            png = out / render_file(frame_index(f, i))
            moving = series.frame_parts[i].get("bodies")  # moving walls and bodies, where they are
            if moving is not None and (out / moving).is_file():
                r.set_moving(read_surface(out / moving))
            if mode == "surface":
                r.render_surface(read_surface(out / series.surfaces[t]) if t in series.surfaces else None, png, time=t)
            else:
                pts, fields, _ = read_particles(out / f)
                r.render(pts, fields.get("velocity"), png, time=t)
            pngs.append(png)
            if progress is not None:
                progress(k + 1, len(todo))
    written += pngs
    if video and pngs:
        written.append(make_video(pngs, out / video_file(video), fps))
    return written


def make_video(pngs, path, fps: float) -> Path:
    """Encode PNG frames as MP4 (H.264, yuv420p, imageio-ffmpeg's bundled ffmpeg) or GIF (pillow)."""
    import imageio.v2 as imageio

    path = Path(path)
    pngs = [Path(p) for p in pngs]
    if not pngs:
        raise ValueError("make_video needs at least one frame")
    ext = path.suffix.lower()
    if ext == ".gif":
        writer = imageio.get_writer(path, mode="I", duration=1000.0 / fps, loop=0)
    elif ext == ".mp4":
        writer = imageio.get_writer(
            path,
            fps=fps,
            codec="libx264",
            pixelformat="yuv420p",
            quality=8,
            macro_block_size=1,
            ffmpeg_log_level="error",
        )
    else:
        raise ConfigError(f"video file {path} must end in .mp4 or .gif")
    with writer:
        for p in pngs:
            img = imageio.imread(p)[..., :3]
            if ext == ".mp4":  # yuv420p needs even width and height: pad by edge replication
                h, w = img.shape[:2]
                if h % 2 or w % 2:
                    img = np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
            writer.append_data(img)
    return path
