"""Offscreen renders of particle frames, and videos of them (pyvista through EGL, lazily imported).

Look (the paper's figures): particles coloured by speed, slowest dark blue -> fastest white, over a
colour range fixed for the whole series; particles drawn as lit sphere impostors with their physical
radius (vtkPointGaussianMapper, world-space size); the boundary as a translucent surface of the input
meshes; a fixed camera fitted to the scene bounds; a scalar bar "speed [m/s]" (VTK text drops '|').

Headless facts (ecosystem.md): set VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow before the first
plotter; a missing GL stack segfaults, so `gl_available` probes in a subprocess; anti-aliasing off;
one plotter reused for the whole series (a new plotter per frame leaks memory).
"""
from __future__ import annotations

import dataclasses
import functools
import math
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np

from .errors import ConfigError, OutputError
from .model import RenderConfig

__all__ = [
    "gl_available", "speed_colormap", "FrameRenderer", "default_speed_range", "camera_for_view",
    "render_output", "make_video", "VIEWS",
]

# direction from the focal point to the camera, and the view-up vector (y is up)
VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "back": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "top": ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    "iso": ((0.75, 0.55, 1.0), (0.0, 1.0, 0.0)),
}
VIEW_ANGLE_DEG = 30.0                      # VTK's default vertical field of view
BACKGROUND = ("#15181e", "#3b4350")        # bottom, top: dark neutral gradient, white fluid reads on it
SURFACE_COLOUR = "#c9d3df"
SURFACE_OPACITY = 0.18
SPEED_COLOURS = ("#08183a", "#1f56b4", "#6fb1ee", "#ffffff")  # dark blue -> blue -> light blue -> white
SPEED_TITLE = "speed [m/s]"

_GL_HINT = ("install an EGL + Mesa stack (apt-get install -y --no-install-recommends libegl1 "
            "libgl1-mesa-dri)")

_PROBE = """
import os
os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
import pyvista as pv
p = pv.Plotter(off_screen=True, window_size=(32, 24))
p.disable_anti_aliasing()
p.add_mesh(pv.Sphere(), color="white")
img = p.screenshot(return_img=True)
p.close()
assert img.shape[:2] == (24, 32) and img.max() > 0, "blank probe image"
print("ok")
"""


def _use_egl() -> None:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


@functools.cache
def gl_available(timeout: float = 60.0) -> tuple[bool, str]:
    """Can this machine render offscreen?  (ok, reason); probed once per process, in a subprocess.

    A missing GL stack segfaults VTK instead of raising, so the probe renders a 32x24 frame in a
    child process and reports how it died.
    """
    env = dict(os.environ)
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, f"offscreen GL probe did not finish in {timeout:.0f} s; {_GL_HINT}"
    except OSError as exc:
        return False, f"cannot start the offscreen GL probe: {exc}"
    if proc.returncode == 0 and proc.stdout.strip().endswith("ok"):
        return True, "offscreen rendering available"
    if proc.returncode < 0:
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        return False, f"offscreen GL probe crashed ({name}): no usable GL/EGL stack; {_GL_HINT}"
    lines = [ln.strip() for ln in (proc.stderr or proc.stdout).splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {proc.returncode}"
    return False, f"offscreen GL probe failed ({last[:200]}); {_GL_HINT}"


def speed_colormap():
    """Slowest dark blue -> blue -> light blue -> fastest white (matplotlib colormap)."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("ipsph_speed", SPEED_COLOURS, N=256)


def default_speed_range(initial_speed: float, gravity: float | tuple[float, float, float],
                        fluid_top: float, domain_bottom: float) -> tuple[float, float]:
    """A-priori colour range (0, v_max) for renders during a run.

    v_max = sqrt(|v0|^2 + 2 |g| (fluid top - domain bottom)): the speed of a particle released from
    the top of the fluid with the largest initial speed and falling to the floor (energy balance).
    A degenerate range (no gravity, fluid at rest) falls back to (0, 1) m/s.
    """
    g = float(np.linalg.norm(np.atleast_1d(np.asarray(gravity, dtype=float))))
    drop = max(float(fluid_top) - float(domain_bottom), 0.0)
    vmax = math.sqrt(float(initial_speed) ** 2 + 2.0 * g * drop)
    return (0.0, vmax if vmax > 0.0 else 1.0)


def camera_for_view(bounds, view: str = "front", *, width: int = 1280, height: int = 720,
                    camera_position=None, focal_point=None, view_up=None, margin: float = 1.08):
    """Camera (position, focal point, view up) that frames the box `bounds` for a named view.

    The focal point is the box centre; the distance is the smallest at which every box corner
    projects inside the (perspective, 30 degree) frustum, shrunk horizontally to leave room for the
    scalar bar, times `margin`. An explicit `camera_position` wins over the named view.
    """
    b = np.asarray(bounds, dtype=float).reshape(3, 2)
    centre = b.mean(axis=1) if focal_point is None else np.asarray(focal_point, dtype=float)
    if camera_position is not None:
        pos = np.asarray(camera_position, dtype=float)
        up = np.asarray(view_up if view_up is not None else (0.0, 1.0, 0.0), dtype=float)
        d = centre - pos
        if np.linalg.norm(np.cross(d, up)) < 1e-9 * max(np.linalg.norm(d), 1e-30):
            up = np.array([0.0, 0.0, -1.0])  # looking straight along y
        return tuple(pos), tuple(centre), tuple(up)
    if view not in VIEWS:
        raise ConfigError(f"render.view = {view!r} is not a named view; allowed: {', '.join(VIEWS)} "
                          f"(or give render.camera_position)")
    direction, up0 = VIEWS[view]
    w = np.asarray(direction, dtype=float)
    w /= np.linalg.norm(w)                       # camera looks along -w
    up = np.asarray(view_up if view_up is not None else up0, dtype=float)
    right = np.cross(up, w)
    right /= np.linalg.norm(right)
    up = np.cross(w, right)
    corners = np.array([[x, y, z] for x in b[0] for y in b[1] for z in b[2]]) - centre
    tan_v = math.tan(math.radians(VIEW_ANGLE_DEG) / 2.0)
    tan_h = tan_v * width / height
    tan_v *= 0.92                                # room for the time label
    tan_h *= 0.80                                # room for the vertical scalar bar on the right
    depth = corners @ w                          # towards the camera
    dist = np.max(np.maximum(np.abs(corners @ right) / tan_h, np.abs(corners @ up) / tan_v) + depth)
    dist = max(float(dist) * margin, 1e-6)
    pos = centre + dist * w
    return tuple(pos), tuple(centre), tuple(up)


# Lit sphere impostor for vtkPointGaussianMapper splats: a normal from the splat offset, Lambert
# shading from a fixed key light (upper left, towards the viewer) plus ambient.
_SPHERE_SPLAT = """//VTK::Color::Impl
float dist = dot(offsetVCVSOutput.xy, offsetVCVSOutput.xy);
if (dist > 1.0) { discard; }
vec3 n = vec3(offsetVCVSOutput.xy, sqrt(1.0 - dist));
float shade = 0.42 + 0.58 * max(dot(n, normalize(vec3(-0.35, 0.55, 0.75))), 0.0);
ambientColor *= shade;
diffuseColor *= shade;
"""


def _set_font(prop) -> None:
    """DejaVu Sans from matplotlib's data (VTK's embedded font draws '[' like '(')."""
    try:
        from matplotlib import font_manager

        font = font_manager.findfont("DejaVu Sans", fallback_to_default=True)
    except Exception:  # noqa: BLE001 - any failure: keep VTK's embedded font
        font = None
    if font and os.path.isfile(font):
        prop.SetFontFamily(4)  # VTK_FONT_FILE
        prop.SetFontFile(font)
    else:
        prop.SetFontFamilyToArial()


def _scalar_bar(lut):
    """Vertical bar on the right, white text, title "speed [m/s]", five labels."""
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle(SPEED_TITLE)
    bar.SetNumberOfLabels(5)
    bar.SetLabelFormat("%.2f")
    bar.SetMaximumNumberOfColors(256)
    bar.SetOrientationToVertical()
    bar.SetTextPositionToSucceedScalarBar()  # labels right of the bar, never over it
    bar.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    bar.GetPositionCoordinate().SetValue(0.885, 0.18)
    bar.SetWidth(0.09)
    bar.SetHeight(0.62)
    bar.SetBarRatio(0.3)
    bar.SetVerticalTitleSeparation(14)
    bar.SetTextPad(6)
    bar.UnconstrainedFontSizeOn()
    for prop, size in ((bar.GetTitleTextProperty(), 20), (bar.GetLabelTextProperty(), 16)):
        prop.SetColor(1.0, 1.0, 1.0)
        prop.SetFontSize(size)
        _set_font(prop)
        prop.ShadowOff()
        prop.BoldOff()
        prop.ItalicOff()
    return bar


class FrameRenderer:
    """One offscreen plotter reused for a series of frames (fixed camera and colour range)."""

    def __init__(self, config: RenderConfig, bounds, particle_radius: float,
                 speed_range: tuple[float, float], surface=None, *, title: str | None = None):
        _use_egl()
        import pyvista as pv

        lo, hi = (float(v) for v in speed_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ConfigError(f"render speed_range = ({lo}, {hi}) m/s must be finite with lo < hi")
        self.config = config
        self.speed_range = (lo, hi)
        self.particle_radius = float(particle_radius)
        p = pv.Plotter(off_screen=True, window_size=(int(config.width), int(config.height)))
        p.disable_anti_aliasing()
        p.set_background(BACKGROUND[0], top=BACKGROUND[1])
        self.plotter = p

        # particles: a raw VTK pipeline (pyvista's points_gaussian path bakes colours into an
        # "__rgba__" array at add time, which would not follow per-frame data)
        from vtkmodules.vtkCommonDataModel import vtkPolyData
        from vtkmodules.vtkRenderingCore import vtkActor
        from vtkmodules.vtkRenderingOpenGL2 import vtkOpenGLPointGaussianMapper

        lut = pv.LookupTable(cmap=speed_colormap(), n_values=256, scalar_range=self.speed_range)
        self._poly = vtkPolyData()
        mapper = vtkOpenGLPointGaussianMapper()  # (pyvista's wrapper of it segfaults here)
        mapper.SetInputData(self._poly)
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(*self.speed_range)
        mapper.SetScalarModeToUsePointData()        # the active point scalars: "speed"
        mapper.SetColorModeToMapScalars()
        mapper.ScalarVisibilityOn()
        mapper.SetEmissive(False)
        mapper.SetScaleFactor(self.particle_radius)  # splat radius in world units = particle radius
        mapper.SetSplatShaderCode(_SPHERE_SPLAT)
        actor = vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetAmbient(0.0)
        prop.SetDiffuse(1.0)
        prop.SetSpecular(0.0)
        p.add_actor(actor, reset_camera=False, pickable=False)
        self._actor, self._mapper, self._lut = actor, mapper, lut
        self._keep: tuple = ()
        self._set_particles(np.zeros((0, 3)), np.zeros(0))
        p.add_actor(_scalar_bar(lut), reset_camera=False, pickable=False)

        if surface is not None and surface.n_points:
            p.add_mesh(surface, color=SURFACE_COLOUR, opacity=SURFACE_OPACITY, smooth_shading=False,
                       show_scalar_bar=False, lighting=True, culling="front")
            edges = surface.extract_feature_edges(boundary_edges=True, feature_edges=True,
                                                  manifold_edges=False, feature_angle=40)
            if edges.n_points:
                p.add_mesh(edges, color=SURFACE_COLOUR, opacity=0.45, line_width=1.0,
                           show_scalar_bar=False, lighting=False)

        self._time_text = p.add_text("", position=(18, int(config.height) - 42), font_size=14,
                                     color="white")
        _set_font(self._time_text.GetTextProperty())
        if title:
            t = p.add_text(title, position=(18, 14), font_size=10, color="#b8c0cc")
            _set_font(t.GetTextProperty())

        pos, focal, up = camera_for_view(bounds, config.view, width=int(config.width),
                                         height=int(config.height),
                                         camera_position=config.camera_position,
                                         focal_point=config.focal_point, view_up=config.view_up)
        p.camera.position, p.camera.focal_point, p.camera.up = pos, focal, up
        p.camera.view_angle = VIEW_ANGLE_DEG
        extent = np.ptp(np.asarray(bounds, dtype=float).reshape(3, 2), axis=1).max()
        dist = float(np.linalg.norm(np.subtract(pos, focal)))
        p.camera.clipping_range = (max(dist - 4 * extent, dist * 1e-3), dist + 4 * extent)
        self._clipping = p.camera.clipping_range

    def render(self, points: np.ndarray, velocities: np.ndarray | None, out_png, *,
               time: float | None = None) -> Path:
        """Render one frame to `out_png` (parent folders are created); return its path."""
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        speed = (np.linalg.norm(velocities, axis=1) if velocities is not None and len(velocities)
                 else np.zeros(len(pts)))
        self._set_particles(pts, speed)
        self._time_text.SetInput("" if time is None else f"t = {time:.3f} s")
        self.plotter.camera.clipping_range = self._clipping  # keep the frame-to-frame image stable
        out_png = Path(out_png)
        out_png.parent.mkdir(parents=True, exist_ok=True)
        self.plotter.render()
        img = self.plotter.screenshot(return_img=True)
        _save_png(img, out_png)
        return out_png

    def _set_particles(self, pts: np.ndarray, speed: np.ndarray) -> None:
        from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
        from vtkmodules.vtkCommonCore import vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkCellArray

        speed = np.ascontiguousarray(speed, dtype=np.float64)
        vpts = vtkPoints()
        vpts.SetData(numpy_to_vtk(pts, deep=False))
        arr = numpy_to_vtk(speed, deep=False)
        arr.SetName("speed")
        pd = self._poly.GetPointData()
        pd.RemoveArray("speed")
        pd.SetScalars(arr)
        ids = np.arange(len(pts) + 1, dtype=np.int64)
        verts = vtkCellArray()  # one vertex per point: the gaussian mapper draws verts
        verts.SetData(numpy_to_vtkIdTypeArray(ids, deep=True), numpy_to_vtkIdTypeArray(ids[:-1], deep=True))
        self._poly.SetPoints(vpts)
        self._poly.SetVerts(verts)
        self._poly.Modified()
        self._keep = (pts, speed)  # the VTK arrays share this memory

    def close(self) -> None:
        if self.plotter is not None:
            self.plotter.close()
            self.plotter = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _save_png(img: np.ndarray, path: Path) -> None:
    """PNG with zlib level 1 (PIL's default level 6 costs ~0.3 s per 1280x720 frame), renamed into
    place so a viewer never sees half a file."""
    from PIL import Image

    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        Image.fromarray(np.ascontiguousarray(img[..., :3])).save(tmp, format="PNG", compress_level=1)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _read_surface(path: Path):
    if not path.is_file():
        return None
    import pyvista as pv

    return pv.read(path)


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


def _frame_index(file: str, position: int) -> int:
    m = re.search(r"(\d+)\.vtu$", file)
    return int(m.group(1)) if m else position


def _speed_range_for(out: Path, run: dict, frames: list[tuple[float, str]], given) -> tuple[float, float]:
    """Given range, else the max of stats.csv max_speed over the run, else the data's max speed."""
    from .io.stats import read_stats
    from .io.vtu import read_particles

    if given is not None:
        return (float(given[0]), float(given[1]))
    stats = out / "stats.csv"
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


def render_output(out_dir, *, speed_range=None, config_overrides: dict | None = None,
                  video: str | None = None, fps: float | None = None,
                  frames: slice | None = None, progress=None) -> list[Path]:
    """Render every frame of a finished or still-running output folder to OUT/renders/*.png.

    Reads run.json (render settings, radius, bounds), run.pvd (frames written so far) and
    boundary_surface.vtp. Colour range: `speed_range`, else max of stats.csv `max_speed`, else
    the frames' data. `video` = "mp4" | "gif" also writes OUT/video.<ext>. Returns written paths.
    """
    from .io import BOUNDARY_SURFACE, RENDERS_DIR, RUN_JSON, RUN_PVD
    from .io.provenance import read_run_json
    from .io.pvd import PvdSeries
    from .io.vtu import read_particles

    out = Path(out_dir)
    if not (out / RUN_PVD).is_file():
        raise OutputError(f"{out} (resolved {out.resolve()}) is not an ipsph output folder: no {RUN_PVD}; "
                          f"give the folder that `ipsph run` wrote")
    if video not in (None, "mp4", "gif"):
        raise ConfigError(f"video = {video!r} is not a video format; allowed: mp4, gif")
    run = read_run_json(out / RUN_JSON) if (out / RUN_JSON).is_file() else {}
    config = _render_config(run, config_overrides)
    series = PvdSeries.load(out / RUN_PVD)
    todo = list(enumerate(series.frames))
    if frames is not None:
        todo = todo[frames]
    rng = _speed_range_for(out, run, series.frames, speed_range if speed_range is not None
                           else config.speed_range)
    surface = _read_surface(out / BOUNDARY_SURFACE)

    radius = run.get("particle_radius")
    bounds = run.get("domain_bounds")
    if bounds is None or radius is None:  # no provenance: fit the data
        pts = [read_particles(out / f)[0] for _, (_, f) in todo[:1]]
        allp = np.concatenate(pts + ([surface.points] if surface is not None else [])) if pts else np.zeros((1, 3))
        bounds = bounds or [v for i in range(3) for v in (allp[:, i].min(), allp[:, i].max())]
        if radius is None:
            radius = 0.01 * float(np.ptp(allp, axis=0).max() or 1.0)
    scene = run.get("scene") or {}
    title = " - ".join(str(x) for x in (scene.get("name"), (run.get("method") or "").upper(),  # no '|': VTK drops it
                                        f"{run['fluid_particles']:,} particles" if run.get("fluid_particles") else None)
                       if x)
    if fps is None:
        fps = float((scene.get("output") or {}).get("fps") or 25.0)

    written: list[Path] = []
    pngs: list[Path] = []
    with FrameRenderer(config, bounds, radius, rng, surface, title=title) as r:
        for k, (i, (t, f)) in enumerate(todo):
            pts, fields, _ = read_particles(out / f)
            png = out / RENDERS_DIR / f"frame_{_frame_index(f, i):06d}.png"
            r.render(pts, fields.get("velocity"), png, time=t)
            pngs.append(png)
            if progress is not None:
                progress(k + 1, len(todo))
    written += pngs
    if video and pngs:
        written.append(make_video(pngs, out / f"video.{video}", fps))
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
        writer = imageio.get_writer(path, fps=fps, codec="libx264", pixelformat="yuv420p",
                                    quality=8, macro_block_size=1, ffmpeg_log_level="error")
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
