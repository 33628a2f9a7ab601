"""The look of every render: view names, colours, the speed colour map and its range, layout."""

from __future__ import annotations

import math

import numpy as np

from ...params import RENDER_VIEWS

VIEWS = RENDER_VIEWS  # name -> (direction from the focal point to the camera, view-up), ipsph.params


VIEW_ANGLE_DEG = 30.0  # VTK's default vertical field of view


BACKGROUND = ("#15181e", "#3b4350")  # bottom, top: dark neutral gradient, white fluid reads on it


SURFACE_COLOUR = "#c9d3df"


SURFACE_OPACITY = 0.18
MOVING_OPACITY = 0.85  # moving walls and rigid bodies (solid; ipsph.io.bodies' surfaces)


EDGE_OPACITY = 0.45  # the walls' outline and creases


SPEED_COLOURS = ("#08183a", "#1f56b4", "#6fb1ee", "#ffffff")  # dark blue -> blue -> light blue -> white


SPEED_TITLE = "speed [m/s]"


SCALAR_BAR_POSITION = (0.885, 0.18)  # lower left corner, normalised viewport


SCALAR_BAR_LENGTH = 0.62  # of the viewport height


TITLE_COLOUR = "#b8c0cc"


ENGINES = ("splat", "vtk")  # splat: particles rasterised by ipsph.post.render.splat over layers VTK drew once


def _ui_scale(height: int) -> float:
    """Text and margins are laid out for 720 rows and scale with the image height."""
    return int(height) / 720.0


def TIME_LABEL_POS(height: int) -> tuple[int, int]:  # noqa: N802 - a constant of the layout
    """Bottom-left corner (display pixels, y up) of the "t = ..." label, top left of the frame."""
    k = _ui_scale(height)
    return (round(18 * k), int(height) - round(42 * k))


def speed_colormap():
    """Slowest dark blue -> blue -> light blue -> fastest white (matplotlib colormap)."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("ipsph_speed", SPEED_COLOURS, N=256)


def default_speed_range(
    initial_speed: float, gravity: float | tuple[float, float, float], fluid_top: float, domain_bottom: float
) -> tuple[float, float]:
    """A-priori colour range (0, v_max) for renders during a run.

    v_max = sqrt(|v0|^2 + 2 |g| (fluid top - domain bottom)): the speed of a particle released from
    the top of the fluid with the largest initial speed and falling to the floor (energy balance).
    A degenerate range (no gravity, fluid at rest) falls back to (0, 1) m/s.
    """
    g = float(np.linalg.norm(np.atleast_1d(np.asarray(gravity, dtype=float))))
    drop = max(float(fluid_top) - float(domain_bottom), 0.0)
    vmax = math.sqrt(float(initial_speed) ** 2 + 2.0 * g * drop)
    return (0.0, vmax if vmax > 0.0 else 1.0)


def _rgb(hex_colour: str) -> tuple[float, float, float]:
    h = hex_colour.lstrip("#")
    return tuple(int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4))


def speed_lut_rgb() -> np.ndarray:
    """The speed colour map as 256 x 3 values in 0..1: SPEED_COLOURS evenly spaced and linearly
    interpolated, as `speed_colormap()` (matplotlib) samples it, without importing matplotlib."""
    stops = np.array([_rgb(c) for c in SPEED_COLOURS])
    x, xp = np.linspace(0.0, 1.0, 256), np.linspace(0.0, 1.0, len(stops))
    return np.stack([np.interp(x, xp, stops[:, c]) for c in range(3)], axis=1)
