"""The splat engine's side of FrameRenderer: the static layers baked once through VTK (walls,
their transmittance and depth, background, overlays) and each frame's particles splatted by
`render.splat` and composed over them. A mixin of `frame.FrameRenderer`, whose VTK window it reads.
"""

from __future__ import annotations

import math

import numpy as np

from .style import TIME_LABEL_POS
from .text import _draw_text


class SplatLayers:
    """Baking the static layers and composing a splatted frame over them."""

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
            z = zb[r : r + 128].astype(np.float64)
            d = 2.0 * near * far / ((far + near) - (2.0 * z - 1.0) * (far - near))
            dist[r : r + 128] = np.where(z >= 1.0, np.inf, d)
        return dist

    def _bake(self) -> None:
        """Draw the static layers once (see ipsph.post.render.splat): walls, their transmittance and depth,
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
        view = np.array([[cam.GetViewTransformMatrix().GetElement(i, j) for j in range(4)] for i in range(4)])
        h, w = int(self.config.height), int(self.config.width)
        f_px = 0.5 * h / math.tan(math.radians(cam.GetViewAngle()) / 2.0)
        self._layers = dict(
            static=static,
            wall_rgb=wall_rgb,
            wall_t=wall_t,
            wall_depth=wall_depth,
            over_rgb=over_rgb,
            over_t=over_t,
            view=view,
            f_px=f_px,
            colours=(255.0 * self._lut_rgb).astype(np.float32),
            zbuf=np.full((h, w), np.inf, np.float32),
            owner=np.full((h, w), -1, np.int32),
            shade=np.empty((h, w), np.float32),
            light=splat.LIGHT.copy(),
        )

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
        box = splat.splat(sx, sy, dist, rad, self.particle_radius, L["light"], L["zbuf"], L["owner"], L["shade"])
        img = L["static"].copy()
        splat.composite(
            box,
            L["owner"],
            L["shade"],
            L["zbuf"],
            colour,
            L["wall_depth"],
            L["wall_rgb"],
            L["wall_t"],
            L["over_rgb"],
            L["over_t"],
            img,
        )
        if label:
            _draw_text(img, label, self._time_text.GetTextProperty(), TIME_LABEL_POS(h))
        return img
