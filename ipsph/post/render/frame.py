"""FrameRenderer: one offscreen VTK window reused for a series of frames, two engines
("splat": static layers once through VTK, particles by render.splat, composed in render.layers; "vtk": all through VTK, the
reference the tests hold the splat engine to), and the surface mode."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...config import RenderConfig
from ...errors import ConfigError
from .camera import camera_for_view
from .gl import _use_egl
from .layers import SplatLayers
from .png import save_png
from .style import (
    BACKGROUND,
    EDGE_OPACITY,
    ENGINES,
    SPEED_COLOURS,
    SURFACE_COLOUR,
    SURFACE_OPACITY,
    TIME_LABEL_POS,
    TITLE_COLOUR,
    VIEW_ANGLE_DEG,
    _rgb,
    _ui_scale,
    speed_lut_rgb,
)
from .text import _scalar_bar, _set_font

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


class FrameRenderer(SplatLayers):
    """One offscreen VTK render window reused for a series of frames (fixed camera and colour range).

    Plain VTK classes rather than a pyvista Plotter: importing pyvista's plotting layer imports
    matplotlib.pyplot, ~1.2 s of CPU in every render process, a third of what the renders of the
    default scene cost in all (docs/rendering.md). pyvista still reads and filters the meshes.
    """

    def __init__(
        self,
        config: RenderConfig,
        bounds,
        particle_radius: float,
        speed_range: tuple[float, float],
        surface=None,
        *,
        title: str | None = None,
        engine: str = "splat",
    ):
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
        mapper.SetScalarModeToUsePointData()  # the active point scalars: "speed"
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
        self._overlays = [bar]  # 2D actors drawn over everything
        self._walls = []  # the boundary surface and its edges
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
            self._overlays.append(
                self._add_text(title, (round(18 * k), round(14 * k)), max(round(20 * k), 6), TITLE_COLOUR)
            )
        self._layers = None  # the static layers of the splat engine, drawn at the first frame

        pos, focal, up = camera_for_view(
            bounds,
            config.view,
            width=w,
            height=h,
            camera_position=config.camera_position,
            focal_point=config.focal_point,
            view_up=config.view_up,
        )
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

    def set_moving(self, mesh) -> None:
        """The moving walls' surfaces of the next frame (OUT/bodies/*.vtp): drawn like the walls,
        but opaque (they are solid bodies); the splat engine redraws its wall layers for them."""
        from .style import MOVING_OPACITY

        if getattr(self, "_moving", None) is None:
            self._moving = self._add_surface(mesh, MOVING_OPACITY, lighting=True, cull_front=False)
            self._walls.append(self._moving)
        else:
            self._moving.GetMapper().SetInputData(mesh)
        self._layers = None

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

    def render(self, points: np.ndarray, velocities: np.ndarray | None, out_png, *, time: float | None = None) -> Path:
        """Render one frame to `out_png` (parent folders are created); return its path."""
        return save_png(self.image(points, velocities, time=time), out_png)

    def image(self, points: np.ndarray, velocities: np.ndarray | None, *, time: float | None = None) -> np.ndarray:
        """One frame as a new (h, w, 3) uint8 array (rows top down), not yet written."""
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        speed = np.linalg.norm(velocities, axis=1) if velocities is not None and len(velocities) else np.zeros(len(pts))
        label = "" if time is None else f"t = {time:.3f} s"
        return self._splat_frame(pts, speed, label) if self.engine == "splat" else self._vtk_frame(pts, speed, label)

    def surface_image(self, mesh, *, time: float | None = None) -> np.ndarray:
        """One frame of the fluid's surface mesh (render.mode = "surface"; vtkPolyData with "speed" on the
        vertices, as ipsph.post.surface writes it, or None for a frame without one) drawn through VTK:
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
            prop.SetSpecular(0.35)  # a wet highlight
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

    # -- splat engine: static layers drawn once through VTK, particles rasterised by ipsph.post.render.splat ----

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

    def prepare(self) -> None:
        """Open the GL context and draw the static layers now rather than at the first frame."""
        if self.engine == "splat" and self._layers is None:
            self._bake()
        elif self.engine == "vtk":
            self.window.Render()

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
