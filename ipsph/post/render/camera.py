"""The fixed camera of a series: a named view or the scene's own, framed off the colour bar."""

from __future__ import annotations

import math

import numpy as np

from ...errors import ConfigError
from .style import VIEW_ANGLE_DEG, VIEWS

# The part of the image the domain is framed into, in normalized image coordinates (-1 .. 1):
# right of FRAME_RIGHT is the colour bar (it starts at 88.5 % of the width), FRAME_V leaves the
# top for the time label and the bottom for the title.
FRAME_LEFT, FRAME_RIGHT, FRAME_V = -0.96, 0.74, 0.86


def camera_for_view(
    bounds,
    view: str = "front",
    *,
    width: int = 1280,
    height: int = 720,
    camera_position=None,
    focal_point=None,
    view_up=None,
    margin: float = 1.08,
):
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
            raise ConfigError(
                f"render.view = {view!r} is not a named view; allowed: {', '.join(VIEWS)} "
                f"(or give render.camera_position)"
            )
        direction, up0 = VIEWS[view]
        w = np.asarray(direction, dtype=float)
        w = w / np.linalg.norm(w)  # camera looks along -w
        up = np.asarray(view_up if view_up is not None else up0, dtype=float)
        user_dist = 0.0
    right = np.cross(up, w)
    right /= np.linalg.norm(right)
    up = np.cross(w, right)
    corners = np.array([[x, y, z] for x in b[0] for y in b[1] for z in b[2]]) - centre
    cr, cu, cd = corners @ right, corners @ up, corners @ w  # cd: towards the camera
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
    for _ in range(60):  # the smallest distance that fits
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    dist = max(hi * margin, user_dist)
    s_lo, s_hi, t_lo, t_hi = shifts(dist)
    if camera_position is not None:  # keep the user's focal point where it fits
        s, t = float(np.clip(0.0, s_lo, s_hi)), float(np.clip(0.0, t_lo, t_hi))
    else:  # centred in the frame region
        s, t = 0.5 * (s_lo + s_hi), 0.5 * (t_lo + t_hi)
    focal = centre + s * right + t * up
    pos = focal + dist * w
    return tuple(float(v) for v in pos), tuple(float(v) for v in focal), tuple(float(v) for v in up)
