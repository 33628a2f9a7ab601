"""Offscreen renders of particle frames, and videos of them (VTK through EGL, lazily imported).

Look (the paper's figures): particles coloured by speed, slowest dark blue -> fastest white, over a
colour range fixed for the whole series; particles drawn as lit sphere impostors with their physical
radius; the boundary as a translucent surface of the input meshes; a fixed camera fitted to the scene
bounds; a scalar bar "speed [m/s]" (VTK text drops '|').

Two engines draw the same picture: "splat" (the default) draws the static layers once through VTK
and rasterises the particles with Numba (ipsph.splat); "vtk" draws everything through VTK
(vtkPointGaussianMapper impostors) and is the reference the tests hold the splat engine to.

Headless facts (ecosystem.md): set VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow before the first
render window; a missing GL stack segfaults, so `gl_available` probes in a subprocess; anti-aliasing
off; one render window reused for the whole series (a new one per frame leaks memory).
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
EDGE_OPACITY = 0.45                        # the walls' outline and creases
SPEED_COLOURS = ("#08183a", "#1f56b4", "#6fb1ee", "#ffffff")  # dark blue -> blue -> light blue -> white
SPEED_TITLE = "speed [m/s]"
SCALAR_BAR_POSITION = (0.885, 0.18)        # lower left corner, normalised viewport
SCALAR_BAR_LENGTH = 0.62                   # of the viewport height
TITLE_COLOUR = "#b8c0cc"
ENGINES = ("splat", "vtk")  # splat: particles rasterised by ipsph.splat over layers VTK drew once


def _ui_scale(height: int) -> float:
    """Text and margins are laid out for 720 rows and scale with the image height."""
    return int(height) / 720.0


def TIME_LABEL_POS(height: int) -> tuple[int, int]:  # noqa: N802 - a constant of the layout
    """Bottom-left corner (display pixels, y up) of the "t = ..." label, top left of the frame."""
    k = _ui_scale(height)
    return (round(18 * k), int(height) - round(42 * k))

GL_HINT = ("install an EGL + Mesa stack (apt-get install -y --no-install-recommends libegl1 "
            "libgl1-mesa-dri)")

_PROBE = """
import os
os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
import vtkmodules.vtkRenderingOpenGL2
from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkRenderer, vtkRenderWindow
src = vtkSphereSource()
mapper = vtkPolyDataMapper()
mapper.SetInputConnection(src.GetOutputPort())
actor = vtkActor()
actor.SetMapper(mapper)
ren = vtkRenderer()
ren.AddActor(actor)
win = vtkRenderWindow()
win.SetOffScreenRendering(True)
win.SetMultiSamples(0)
win.SetSize(32, 24)
win.AddRenderer(ren)
win.Render()
buf = vtkUnsignedCharArray()
win.GetPixelData(0, 0, 31, 23, 1, buf, 0)
assert buf.GetNumberOfTuples() == 32 * 24 and max(buf.GetRange(0)) > 0, "blank probe image"
win.Finalize()
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
        return False, f"offscreen GL probe did not finish in {timeout:.0f} s; {GL_HINT}"
    except OSError as exc:
        return False, f"cannot start the offscreen GL probe: {exc}"
    if proc.returncode == 0 and proc.stdout.strip().endswith("ok"):
        return True, "offscreen rendering available"
    if proc.returncode < 0:
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        return False, f"offscreen GL probe crashed ({name}): no usable GL/EGL stack; {GL_HINT}"
    lines = [ln.strip() for ln in (proc.stderr or proc.stdout).splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {proc.returncode}"
    return False, f"offscreen GL probe failed ({last[:200]}); {GL_HINT}"


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


# The part of the image the domain is framed into, in normalized image coordinates (-1 .. 1):
# right of FRAME_RIGHT is the colour bar (it starts at 88.5 % of the width), FRAME_V leaves the
# top for the time label and the bottom for the title.
FRAME_LEFT, FRAME_RIGHT, FRAME_V = -0.96, 0.74, 0.86


def camera_for_view(bounds, view: str = "front", *, width: int = 1280, height: int = 720,
                    camera_position=None, focal_point=None, view_up=None, margin: float = 1.08):
    """Camera (position, focal point, view up) that frames the box `bounds` for a named view or an
    explicit camera, off the colour bar.

    The view direction is the named view's, or the given camera's (camera_position -> focal_point,
    default the box centre). Along it the camera stands at the smallest distance (times `margin`)
    at which every box corner projects into the frame region (FRAME_LEFT .. FRAME_RIGHT across,
    +-FRAME_V up and down) of the perspective, 30 degree frustum, sliding sideways as needed; an
    explicit camera is never moved closer than it was, and keeps its focal point when the box fits.
    """
    b = np.asarray(bounds, dtype=float).reshape(3, 2)
    centre = b.mean(axis=1) if focal_point is None else np.asarray(focal_point, dtype=float)
    if camera_position is not None:
        pos = np.asarray(camera_position, dtype=float)
        up = np.asarray(view_up if view_up is not None else (0.0, 1.0, 0.0), dtype=float)
        w = pos - centre
        user_dist = float(np.linalg.norm(w))
        if user_dist < 1e-12:
            raise ConfigError("render.camera_position equals the focal point: no view direction")
        w = w / user_dist
        if np.linalg.norm(np.cross(w, up)) < 1e-9 * max(np.linalg.norm(up), 1e-30):
            up = np.array([0.0, 0.0, -1.0])  # looking straight along y
    else:
        if view not in VIEWS:
            raise ConfigError(f"render.view = {view!r} is not a named view; allowed: {', '.join(VIEWS)} "
                              f"(or give render.camera_position)")
        direction, up0 = VIEWS[view]
        w = np.asarray(direction, dtype=float)
        w = w / np.linalg.norm(w)                # camera looks along -w
        up = np.asarray(view_up if view_up is not None else up0, dtype=float)
        user_dist = 0.0
    right = np.cross(up, w)
    right /= np.linalg.norm(right)
    up = np.cross(w, right)
    corners = np.array([[x, y, z] for x in b[0] for y in b[1] for z in b[2]]) - centre
    cr, cu, cd = corners @ right, corners @ up, corners @ w   # cd: towards the camera
    tan_v = math.tan(math.radians(VIEW_ANGLE_DEG) / 2.0)
    tan_h = tan_v * width / height
    a_right, a_left, a_v = FRAME_RIGHT * tan_h, -FRAME_LEFT * tan_h, FRAME_V * tan_v

    def shifts(dist):
        """Feasible sideways (s) and vertical (t) focal shifts at distance `dist`: corner k at depth
        z_k = dist - cd_k projects inside when -a_left z <= cr - s <= a_right z and |cu - t| <= a_v z."""
        z = dist - cd
        return (np.max(cr - a_right * z), np.min(cr + a_left * z), np.max(cu - a_v * z), np.min(cu + a_v * z))

    def fits(dist):
        s_lo, s_hi, t_lo, t_hi = shifts(dist)
        return s_lo <= s_hi and t_lo <= t_hi

    lo = float(cd.max()) + 1e-9 * max(float(np.ptp(corners)), 1e-30)
    hi = max(2.0 * lo, float(np.linalg.norm(corners, axis=1).max()) * 4.0, 1e-6)
    while not fits(hi):
        hi *= 2.0
    for _ in range(60):                          # the smallest distance that fits
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    dist = max(hi * margin, user_dist)
    s_lo, s_hi, t_lo, t_hi = shifts(dist)
    if camera_position is not None:              # keep the user's focal point where it fits
        s, t = float(np.clip(0.0, s_lo, s_hi)), float(np.clip(0.0, t_lo, t_hi))
    else:                                        # centred in the frame region
        s, t = 0.5 * (s_lo + s_hi), 0.5 * (t_lo + t_hi)
    focal = centre + s * right + t * up
    pos = focal + dist * w
    return tuple(float(v) for v in pos), tuple(float(v) for v in focal), tuple(float(v) for v in up)


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


@functools.cache
def _font_file() -> str | None:
    """DejaVu Sans as matplotlib ships it, found without importing matplotlib (~0.3 s)."""
    import importlib.util

    spec = importlib.util.find_spec("matplotlib")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        path = os.path.join(folder, "mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
        if os.path.isfile(path):
            return path
    return None


def _set_font(prop) -> None:
    """DejaVu Sans from matplotlib's data (VTK's embedded font draws '[' like '(')."""
    font = _font_file()
    if font:
        prop.SetFontFamily(4)  # VTK_FONT_FILE
        prop.SetFontFile(font)
    else:
        prop.SetFontFamilyToArial()


def _scalar_bar(lut, scale: float = 1.0):
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
    bar.GetPositionCoordinate().SetValue(*SCALAR_BAR_POSITION)
    bar.SetWidth(0.09)
    bar.SetHeight(SCALAR_BAR_LENGTH)
    bar.SetBarRatio(0.3)
    bar.SetVerticalTitleSeparation(round(14 * scale))
    bar.SetTextPad(round(6 * scale))
    bar.UnconstrainedFontSizeOn()
    for prop, size in ((bar.GetTitleTextProperty(), 20), (bar.GetLabelTextProperty(), 16)):
        prop.SetColor(1.0, 1.0, 1.0)
        prop.SetFontSize(max(round(size * scale), 6))
        _set_font(prop)
        prop.ShadowOff()
        prop.BoldOff()
        prop.ItalicOff()
    return bar


def _rgb(hex_colour: str) -> tuple[float, float, float]:
    h = hex_colour.lstrip("#")
    return tuple(int(h[i:i + 2], 16) / 255.0 for i in (0, 2, 4))


def speed_lut_rgb() -> np.ndarray:
    """The speed colour map as 256 x 3 values in 0..1: SPEED_COLOURS evenly spaced and linearly
    interpolated, as `speed_colormap()` (matplotlib) samples it, without importing matplotlib."""
    stops = np.array([_rgb(c) for c in SPEED_COLOURS])
    x, xp = np.linspace(0.0, 1.0, 256), np.linspace(0.0, 1.0, len(stops))
    return np.stack([np.interp(x, xp, stops[:, c]) for c in range(3)], axis=1)


class FrameRenderer:
    """One offscreen VTK render window reused for a series of frames (fixed camera and colour range).

    Plain VTK classes rather than a pyvista Plotter: importing pyvista's plotting layer imports
    matplotlib.pyplot, ~1.2 s of CPU in every render process, a third of what the renders of the
    default scene cost in all (docs/rendering.md). pyvista still reads and filters the meshes.
    """

    def __init__(self, config: RenderConfig, bounds, particle_radius: float,
                 speed_range: tuple[float, float], surface=None, *, title: str | None = None,
                 engine: str = "splat"):
        if engine not in ENGINES:
            raise ConfigError(f"render engine {engine!r} is not one of {', '.join(ENGINES)}")
        lo, hi = (float(v) for v in speed_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ConfigError(f"render speed_range = ({lo}, {hi}) m/s must be finite with lo < hi")
        _use_egl()
        import vtkmodules.vtkRenderingFreeType  # noqa: F401 - text
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - the OpenGL (EGL) render window
        from vtkmodules.vtkCommonCore import vtkLookupTable
        from vtkmodules.vtkCommonDataModel import vtkPolyData
        from vtkmodules.vtkRenderingCore import vtkActor, vtkLightKit, vtkRenderer, vtkRenderWindow
        from vtkmodules.vtkRenderingOpenGL2 import vtkOpenGLPointGaussianMapper

        self.config = config
        self.engine = engine
        self.speed_range = (lo, hi)
        self.particle_radius = float(particle_radius)
        w, h = int(config.width), int(config.height)
        ren = vtkRenderer()
        ren.SetBackground(*_rgb(BACKGROUND[0]))
        ren.SetBackground2(*_rgb(BACKGROUND[1]))
        ren.GradientBackgroundOn()
        ren.SetDitherGradient(False)  # rows of equal pixels: PNG and video compress them fast
        vtkLightKit().AddLightsToRenderer(ren)
        ren.LightFollowCameraOn()
        win = vtkRenderWindow()
        win.SetOffScreenRendering(True)
        win.SetMultiSamples(0)  # anti-aliasing off
        win.SetSize(w, h)
        win.AddRenderer(ren)
        self.renderer, self.window = ren, win

        # particles (engine "vtk"): lit sphere impostors of world radius r
        self._lut_rgb = speed_lut_rgb()
        lut = vtkLookupTable()
        lut.SetNumberOfTableValues(256)
        for i, (r, g, b) in enumerate(self._lut_rgb):
            lut.SetTableValue(i, r, g, b, 1.0)
        lut.SetTableRange(lo, hi)
        self._lut = lut
        self._mesh_actor = None  # render.mode = "surface": the fluid's surface mesh (surface_image)
        self._poly = vtkPolyData()
        mapper = vtkOpenGLPointGaussianMapper()
        mapper.SetInputData(self._poly)
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(lo, hi)
        mapper.SetScalarModeToUsePointData()        # the active point scalars: "speed"
        mapper.SetColorModeToMapScalars()
        mapper.ScalarVisibilityOn()
        mapper.SetEmissive(False)
        mapper.SetScaleFactor(self.particle_radius)  # splat radius in world units = particle radius
        mapper.SetSplatShaderCode(_SPHERE_SPLAT)
        # the impostor is cut at radius 1: a quad just around it, not the 3-sigma gaussian default
        getattr(mapper, "SetBoundScale", getattr(mapper, "SetTriangleScale", None))(1.0)
        actor = vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetAmbient(0.0)
        prop.SetDiffuse(1.0)
        prop.SetSpecular(0.0)
        ren.AddActor(actor)
        self._actor, self._mapper = actor, mapper
        self._keep: tuple = ()
        self._set_particles(np.zeros((0, 3)), np.zeros(0))

        k = _ui_scale(h)
        bar = _scalar_bar(lut, k)
        ren.AddViewProp(bar)
        self._overlays = [bar]   # 2D actors drawn over everything
        self._walls = []         # the boundary surface and its edges
        if surface is not None and surface.GetNumberOfPoints():
            from vtkmodules.vtkFiltersCore import vtkFeatureEdges

            self._walls.append(self._add_surface(surface, SURFACE_OPACITY, lighting=True, cull_front=True))
            fe = vtkFeatureEdges()  # outline and creases sharper than 40 degrees
            fe.SetInputData(surface)
            fe.BoundaryEdgesOn()
            fe.FeatureEdgesOn()
            fe.ManifoldEdgesOff()
            fe.NonManifoldEdgesOn()
            fe.SetFeatureAngle(40.0)
            fe.ColoringOff()
            fe.Update()
            edges = fe.GetOutput()
            if edges.GetNumberOfPoints():
                self._walls.append(self._add_surface(edges, EDGE_OPACITY, lighting=False, cull_front=False))

        self._time_text = self._add_text("", TIME_LABEL_POS(h), max(round(28 * k), 6), "#ffffff")
        if title:
            self._overlays.append(self._add_text(title, (round(18 * k), round(14 * k)), max(round(20 * k), 6),
                                                 TITLE_COLOUR))
        self._layers = None      # the static layers of the splat engine, drawn at the first frame

        pos, focal, up = camera_for_view(bounds, config.view, width=w, height=h,
                                         camera_position=config.camera_position,
                                         focal_point=config.focal_point, view_up=config.view_up)
        cam = ren.GetActiveCamera()
        cam.SetPosition(*pos)
        cam.SetFocalPoint(*focal)
        cam.SetViewUp(*up)
        cam.SetViewAngle(VIEW_ANGLE_DEG)
        extent = np.ptp(np.asarray(bounds, dtype=float).reshape(3, 2), axis=1).max()
        dist = float(np.linalg.norm(np.subtract(pos, focal)))
        self._clipping = (max(dist - 4 * extent, dist * 1e-3), dist + 4 * extent)
        cam.SetClippingRange(*self._clipping)

    def _add_surface(self, mesh, opacity: float, *, lighting: bool, cull_front: bool):
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

        mapper = vtkPolyDataMapper()
        mapper.SetInputData(mesh)
        mapper.ScalarVisibilityOff()
        actor = vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetColor(*_rgb(SURFACE_COLOUR))
        prop.SetOpacity(opacity)
        prop.SetInterpolationToFlat()
        prop.SetAmbient(0.0)
        prop.SetDiffuse(1.0)
        prop.SetSpecular(0.0)
        prop.SetLineWidth(1.0)
        prop.SetLighting(lighting)
        prop.SetFrontfaceCulling(cull_front)  # a cutaway: faces turned towards the camera are left out
        self.renderer.AddActor(actor)
        return actor

    def _add_text(self, text: str, position: tuple[int, int], size: int, colour: str):
        from vtkmodules.vtkRenderingCore import vtkTextActor

        actor = vtkTextActor()
        actor.SetInput(text)
        actor.SetPosition(*position)
        prop = actor.GetTextProperty()
        prop.SetFontSize(size)
        prop.SetColor(*_rgb(colour))
        _set_font(prop)
        self.renderer.AddViewProp(actor)
        return actor

    def render(self, points: np.ndarray, velocities: np.ndarray | None, out_png, *,
               time: float | None = None) -> Path:
        """Render one frame to `out_png` (parent folders are created); return its path."""
        return save_png(self.image(points, velocities, time=time), out_png)

    def image(self, points: np.ndarray, velocities: np.ndarray | None, *, time: float | None = None) -> np.ndarray:
        """One frame as a new (h, w, 3) uint8 array (rows top down), not yet written."""
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        speed = (np.linalg.norm(velocities, axis=1) if velocities is not None and len(velocities)
                 else np.zeros(len(pts)))
        label = "" if time is None else f"t = {time:.3f} s"
        return self._splat_frame(pts, speed, label) if self.engine == "splat" else self._vtk_frame(pts, speed, label)

    def surface_image(self, mesh, *, time: float | None = None) -> np.ndarray:
        """One frame of the fluid's surface mesh (render.mode = "surface"; vtkPolyData with "speed" on the
        vertices, as ipsph.surface writes it, or None for a frame without one) drawn through VTK:
        smooth-shaded, coloured by speed over the particle frames' colour map and range, behind the same
        translucent walls, colour bar, title and camera."""
        from vtkmodules.vtkCommonDataModel import vtkPolyData
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

        if self._mesh_actor is None:
            mapper = vtkPolyDataMapper()
            mapper.SetLookupTable(self._lut)
            mapper.SetScalarRange(*self.speed_range)
            mapper.UseLookupTableScalarRangeOff()
            mapper.InterpolateScalarsBeforeMappingOn()  # colours follow the speed across a triangle
            mapper.SetScalarModeToUsePointFieldData()
            mapper.SelectColorArray("speed")
            actor = vtkActor()
            actor.SetMapper(mapper)
            prop = actor.GetProperty()
            prop.SetInterpolationToGouraud()  # with the mesh's smoothed normals
            prop.SetColor(*_rgb(SPEED_COLOURS[2]))
            prop.SetAmbient(0.08)
            prop.SetDiffuse(0.85)
            prop.SetSpecular(0.35)        # a wet highlight
            prop.SetSpecularPower(40.0)
            self.renderer.AddActor(actor)
            self._mesh_actor = actor
        mesh = mesh if mesh is not None else vtkPolyData()
        mapper = self._mesh_actor.GetMapper()
        mapper.SetInputData(mesh)
        mapper.SetScalarVisibility(mesh.GetPointData().GetArray("speed") is not None)
        self._actor.SetVisibility(False)
        self._mesh_actor.SetVisibility(True)
        self._time_text.SetInput("" if time is None else f"t = {time:.3f} s")
        try:
            return self._grab()
        finally:  # the particle engines' state as it was
            self._mesh_actor.SetVisibility(False)
            self._actor.SetVisibility(True)
            self._time_text.SetInput("")

    def render_surface(self, mesh, out_png, *, time: float | None = None) -> Path:
        """Render one surface frame to `out_png`; return its path."""
        return save_png(self.surface_image(mesh, time=time), out_png)

    def _vtk_frame(self, pts: np.ndarray, speed: np.ndarray, label: str) -> np.ndarray:
        """The whole frame through VTK (sprites by vtkPointGaussianMapper): the reference the splat
        engine is tested against."""
        self._set_particles(pts, speed)
        self._time_text.SetInput(label)
        return self._grab()

    # -- splat engine: static layers drawn once through VTK, particles rasterised by ipsph.splat ----

    def _grab(self) -> np.ndarray:
        """Render and read the window back: (h, w, 3) uint8, rows top down."""
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

        w, h = int(self.config.width), int(self.config.height)
        self.renderer.GetActiveCamera().SetClippingRange(*self._clipping)  # a stable frame-to-frame image
        self.window.Render()
        buf = vtkUnsignedCharArray()
        self.window.GetPixelData(0, 0, w - 1, h - 1, 1, buf, 0)
        return vtk_to_numpy(buf).reshape(h, w, 3)[::-1].copy()

    def _set_background(self, colour: str | None) -> None:
        """A plain background colour, or None for the frames' gradient."""
        ren = self.renderer
        if colour is None:
            ren.SetBackground(*_rgb(BACKGROUND[0]))
            ren.GradientBackgroundOn()
        else:
            ren.SetBackground(*_rgb(colour))
            ren.GradientBackgroundOff()

    def _over_black_and_white(self) -> tuple[np.ndarray, np.ndarray]:
        """What is visible drawn over black, and its transmittance x 255 (over white minus over
        black): both exact in 8 bits, since both come from 8-bit images."""
        self._set_background("#000000")
        black = self._grab()
        self._set_background("#ffffff")
        white = self._grab()
        return black, np.maximum(white, black) - black

    def _wall_depth(self) -> np.ndarray:
        """Eye distance of the nearest wall per pixel (walls drawn opaque), inf where none."""
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkFloatArray

        w, h = int(self.config.width), int(self.config.height)
        saved = [a.GetProperty().GetOpacity() for a in self._walls]
        for a in self._walls:
            a.GetProperty().SetOpacity(1.0)
        self._grab()
        buf = vtkFloatArray()
        self.window.GetZbufferData(0, 0, w - 1, h - 1, buf)
        for a, o in zip(self._walls, saved):
            a.GetProperty().SetOpacity(o)
        zb = vtk_to_numpy(buf).reshape(h, w)[::-1]
        near, far = self._clipping
        dist = np.empty((h, w), np.float32)
        for r in range(0, h, 128):  # row blocks: no full-frame float64 temporaries
            z = zb[r:r + 128].astype(np.float64)
            d = 2.0 * near * far / ((far + near) - (2.0 * z - 1.0) * (far - near))
            dist[r:r + 128] = np.where(z >= 1.0, np.inf, d)
        return dist

    def _bake(self) -> None:
        """Draw the static layers once (see ipsph.splat): walls, their transmittance and depth,
        background, overlays, and the composed empty frame."""
        from . import splat

        show = lambda actors, on: [a.SetVisibility(on) for a in actors]  # noqa: E731
        self._actor.SetVisibility(False)
        self._time_text.SetVisibility(False)
        show(self._overlays, False)
        wall_rgb, wall_t = self._over_black_and_white()
        wall_depth = self._wall_depth()
        show(self._walls, False)
        self._set_background(None)
        background = self._grab()
        show(self._overlays, True)
        over_rgb, over_t = self._over_black_and_white()
        show(self._walls, True)
        self._set_background(None)
        self._actor.SetVisibility(True)
        self._time_text.SetVisibility(True)
        static = np.empty_like(background)
        k = np.float32(1.0 / 255.0)
        for r in range(0, static.shape[0], 128):  # row blocks: no full-frame float temporaries
            rows = slice(r, r + 128)
            f = wall_rgb[rows] + wall_t[rows] * k * background[rows].astype(np.float32)
            f = over_rgb[rows] + over_t[rows] * k * f
            static[rows] = np.clip(f + 0.5, 0, 255).astype(np.uint8)

        cam = self.renderer.GetActiveCamera()
        view = np.array([[cam.GetViewTransformMatrix().GetElement(i, j) for j in range(4)]
                         for i in range(4)])
        h, w = int(self.config.height), int(self.config.width)
        f_px = 0.5 * h / math.tan(math.radians(cam.GetViewAngle()) / 2.0)
        self._layers = dict(static=static, wall_rgb=wall_rgb, wall_t=wall_t, wall_depth=wall_depth,
                            over_rgb=over_rgb, over_t=over_t, view=view, f_px=f_px,
                            colours=(255.0 * self._lut_rgb).astype(np.float32),
                            zbuf=np.full((h, w), np.inf, np.float32), owner=np.full((h, w), -1, np.int32),
                            shade=np.empty((h, w), np.float32), light=splat.LIGHT.copy())

    def prepare(self) -> None:
        """Open the GL context and draw the static layers now rather than at the first frame."""
        if self.engine == "splat" and self._layers is None:
            self._bake()
        elif self.engine == "vtk":
            self.window.Render()

    def _splat_frame(self, pts: np.ndarray, speed: np.ndarray, label: str) -> np.ndarray:
        from . import splat

        if self._layers is None:
            self._bake()
        L = self._layers
        n = len(pts)
        h, w = L["zbuf"].shape
        sx, sy, dist, rad = (np.empty(n) for _ in range(4))
        splat.project(pts, L["view"], L["f_px"], 0.5 * w, 0.5 * h, self.particle_radius, sx, sy, dist, rad)
        lo, hi = self.speed_range
        k = np.clip((speed - lo) * (256.0 / (hi - lo)), 0, 255).astype(np.intp)  # as vtkLookupTable
        # front to back: a pixel already covered by a nearer sphere is skipped before any shading
        order = np.argsort(dist, kind="stable")
        sx, sy, dist, rad, colour = sx[order], sy[order], dist[order], rad[order], L["colours"][k[order]]
        box = splat.splat(sx, sy, dist, rad, self.particle_radius, L["light"], L["zbuf"], L["owner"],
                          L["shade"])
        img = L["static"].copy()
        splat.composite(box, L["owner"], L["shade"], L["zbuf"], colour, L["wall_depth"],
                        L["wall_rgb"], L["wall_t"], L["over_rgb"], L["over_t"], img)
        if label:
            _draw_text(img, label, self._time_text.GetTextProperty(), TIME_LABEL_POS(h))
        return img

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
        if self.window is not None:
            self.window.Finalize()
            self.window = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _draw_text(img: np.ndarray, text: str, prop, position: tuple[int, int]) -> None:
    """Alpha-blend `text`, rasterised by VTK's FreeType text renderer with the text property of
    the label actor (same font, size and colour), into `img` with its bottom-left at `position`
    (display pixels, y up), as a vtkTextActor at that position would draw it."""
    import vtkmodules.vtkRenderingFreeType  # noqa: F401 - registers the FreeType text renderer
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkRenderingCore import vtkTextRenderer

    tr = vtkTextRenderer()
    data = vtkImageData()
    dims = [0, 0]
    if not tr.RenderString(prop, text, data, dims, 72):
        return
    nx, ny, _ = data.GetDimensions()
    rgba = vtk_to_numpy(data.GetPointData().GetScalars()).reshape(ny, nx, -1)[::-1].astype(np.float32)
    h, w = img.shape[:2]
    x0, top = position[0], h - position[1] - ny  # rows of the text image, top down
    ys, xs = slice(max(top, 0), min(top + ny, h)), slice(max(x0, 0), min(x0 + nx, w))
    patch = rgba[ys.start - top:ys.stop - top, xs.start - x0:xs.stop - x0]
    a = patch[..., 3:4] / 255.0
    dst = img[ys, xs].astype(np.float32)
    img[ys, xs] = np.clip(patch[..., :3] * a + dst * (1.0 - a) + 0.5, 0, 255).astype(np.uint8)


def save_png(img: np.ndarray, path) -> Path:
    """PNG through `ipsph.splat.encode_png` (Up filter, zlib level 1: ~2.5x faster than Pillow's
    fastest level here), renamed into place so a viewer never sees half a file; parent folders
    are created. Releases the GIL for most of its time (the filter is nogil, zlib too)."""
    from .splat import encode_png

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = encode_png(np.ascontiguousarray(np.asarray(img)[..., :3]))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def read_surface(path):
    """The boundary surface (.vtp) the run wrote, or None; plain VTK (no pyvista import, ~0.35 s)."""
    path = Path(path)
    if not path.is_file():
        return None
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


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
                  frames: slice | None = None, progress=None, mode: str | None = None) -> list[Path]:
    """Render every frame of a finished or still-running output folder to OUT/renders/*.png.

    Reads run.json (render settings, radius, bounds), run.pvd (frames written so far) and
    boundary_surface.vtp. Colour range: `speed_range`, else max of stats.csv `max_speed`, else
    the frames' data. `video` = "mp4" | "gif" also writes OUT/video.<ext>. Returns written paths.
    `mode` = "particles" | "surface" (default: the run's render.mode): "surface" renders
    OUT/surfaces/surface_NNNNNN.vtp, reconstructing first the frames that have none (`ipsph surface`).
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
    mode = mode or config.mode
    if mode not in ("particles", "surface"):
        raise ConfigError(f"render mode {mode!r} is not one of particles, surface")
    if mode == "surface":
        from .surface import surface_output
        surface_output(out)  # the frames without a surface yet (one warning line per failed frame)
    series = PvdSeries.load(out / RUN_PVD)
    todo = list(enumerate(series.frames))
    if frames is not None:
        todo = todo[frames]
    rng = _speed_range_for(out, run, series.frames, speed_range if speed_range is not None
                           else config.speed_range)
    surface = read_surface(out / BOUNDARY_SURFACE)

    radius = run.get("particle_radius")
    bounds = run.get("domain_bounds")
    if bounds is None or radius is None:  # no provenance: fit the data
        from vtkmodules.util.numpy_support import vtk_to_numpy
        pts = [read_particles(out / f)[0] for _, (_, f) in todo[:1]]
        walls = [vtk_to_numpy(surface.GetPoints().GetData())] if surface is not None and surface.GetNumberOfPoints() else []
        allp = np.concatenate(pts + walls) if pts else np.zeros((1, 3))
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
            png = out / RENDERS_DIR / f"frame_{_frame_index(f, i):06d}.png"
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
