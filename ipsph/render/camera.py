"""The fixed camera of a series: a named view fitted to the scene bounds, or the scene's own."""
from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .style import VIEW_ANGLE_DEG, VIEWS


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
