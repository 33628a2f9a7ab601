"""Offscreen renders of particle frames, and videos of them (VTK through EGL, lazily imported).

Look (the paper's figures): particles coloured by speed, slowest dark blue -> fastest white, over a
colour range fixed for the whole series; particles drawn as lit sphere impostors with their physical
radius; the boundary as a translucent surface of the input meshes; a fixed camera fitted to the scene
bounds; a scalar bar "speed [m/s]" (VTK text drops '|').

Two engines draw the same picture: "splat" (the default) draws the static layers once through VTK
and rasterises the particles with Numba (ipsph.post.render.splat); "vtk" draws everything through VTK
(vtkPointGaussianMapper impostors) and is the reference the tests hold the splat engine to.

Headless facts (ecosystem.md): set VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow before the first
render window; a missing GL stack segfaults, so `gl_available` probes in a subprocess; anti-aliasing
off; one render window reused for the whole series (a new one per frame leaks memory).

    style.py    view names, colours, the speed colour map and its default range, layout
    gl.py       EGL, and the GL probe (in a subprocess)
    camera.py   the series' fixed camera
    text.py     font, scalar bar, text drawn into a frame
    frame.py    FrameRenderer (both engines)
    png.py      PNG files
    output.py   `ipsph render OUT`: every frame of an output folder, and videos
"""

from __future__ import annotations

from .camera import FRAME_LEFT, FRAME_RIGHT, FRAME_V, camera_for_view
from .frame import FrameRenderer
from .gl import GL_HINT, gl_available
from .output import make_video, read_surface, render_output
from .png import save_png
from .style import (
    BACKGROUND,
    EDGE_OPACITY,
    ENGINES,
    SCALAR_BAR_LENGTH,
    SCALAR_BAR_POSITION,
    SPEED_COLOURS,
    SPEED_TITLE,
    SURFACE_COLOUR,
    SURFACE_OPACITY,
    TIME_LABEL_POS,
    TITLE_COLOUR,
    VIEW_ANGLE_DEG,
    VIEWS,
    _rgb,
    default_speed_range,
    speed_colormap,
    speed_lut_rgb,
)
from .text import _font_file

__all__ = [
    "gl_available",
    "speed_colormap",
    "FrameRenderer",
    "default_speed_range",
    "camera_for_view",
    "render_output",
    "make_video",
    "VIEWS",
    "GL_HINT",
    "read_surface",
    "save_png",
    "speed_lut_rgb",
    "BACKGROUND",
    "ENGINES",
    "SPEED_COLOURS",
    "SPEED_TITLE",
    "SURFACE_COLOUR",
    "SURFACE_OPACITY",
    "TIME_LABEL_POS",
    "VIEW_ANGLE_DEG",
    "EDGE_OPACITY",
    "SCALAR_BAR_LENGTH",
    "SCALAR_BAR_POSITION",
    "TITLE_COLOUR",
    "FRAME_LEFT",
    "FRAME_RIGHT",
    "FRAME_V",
    "_rgb",
    "_font_file",
]
