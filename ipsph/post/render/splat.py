"""Software sphere splatting and compositing for the renders (Numba, one thread).

Software OpenGL (llvmpipe) costs ~0.15 s of CPU to draw one 1280x720 frame of sphere sprites over
translucent walls, which on a machine without a GPU roughly doubles a small run's wall time. The
static part of a frame (background, walls, their edges, scalar bar, title) never changes during a
series, so `ipsph.post.render.FrameRenderer` draws it once through VTK into layers, and per frame only
the particles are rasterised here and composited over those layers:

- `S`, `T`: the walls drawn over black, and their per-pixel transmittance (from drawing them over
  black and over white: T = (white - black) / 255, kept as the 8-bit difference). A pixel seen
  through the walls is S + T * C.
- `Zs`: eye distance of the nearest wall surface per pixel (walls drawn opaque once); a particle
  nearer than it is in front of every wall at that pixel.
- `O`, `To`: the 2D overlays (scalar bar, title) and their transmittance, drawn on top of all.

Particles are lit spheres of their physical radius r (the projected disc of radius f r / depth,
the same footprint as VTK's point-gaussian impostors), shaded 0.42 + 0.58 max(n . L, 0) by a key
light from the upper left, depth-tested per pixel against each other. No anti-aliasing.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numba import njit

# key light direction in eye space (x right, y up, z towards the viewer), as the VTK splat shader
_L = np.array([-0.35, 0.55, 0.75])
LIGHT = _L / np.linalg.norm(_L)
AMBIENT, DIFFUSE = 0.42, 0.58


@njit(cache=True, nogil=True)
def project(points, view, f_px, cx, cy, radius, sx, sy, dist, rad_px):  # pragma: no cover - jit
    """Eye-space projection: pixel centre (sx, sy; y down), eye distance, disc radius in pixels.

    `view` is the 4x4 world-to-eye matrix (the camera looks along -z). Points behind the camera
    get rad_px = -1 and are not drawn.
    """
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        ex = view[0, 0] * x + view[0, 1] * y + view[0, 2] * z + view[0, 3]
        ey = view[1, 0] * x + view[1, 1] * y + view[1, 2] * z + view[1, 3]
        ez = view[2, 0] * x + view[2, 1] * y + view[2, 2] * z + view[2, 3]
        d = -ez
        dist[i] = d
        if d <= radius:
            rad_px[i] = -1.0
            continue
        s = f_px / d
        sx[i] = cx + s * ex
        sy[i] = cy - s * ey
        rad_px[i] = s * radius


@njit(cache=True, nogil=True)
def splat(sx, sy, dist, rad_px, radius, light, zbuf, owner, shade):  # pragma: no cover - jit
    """Depth-tested lit discs: per pixel the nearest particle (`owner`), its shade and depth.
    Returns the bounding box (y0, y1, x0, x1) of the pixels it may have drawn (empty: y0 > y1).

    A disc covers the pixels whose centres lie within rad_px of (sx, sy); a disc smaller than
    that still covers the pixel holding its centre, so no particle vanishes at a distance.
    """
    h, w = zbuf.shape
    lx, ly, lz = light[0], light[1], light[2]
    by0, by1, bx0, bx1 = h, -1, w, -1  # bounding box of the pixels drawn
    for i in range(sx.shape[0]):
        rp = rad_px[i]
        if rp < 0.0:
            continue
        cx, cy, d = sx[i], sy[i], dist[i]
        if rp < 0.75:  # sub-pixel: the centre pixel, lit head-on
            x, y = int(np.floor(cx)), int(np.floor(cy))
            if 0 <= x < w and 0 <= y < h:
                z = d - radius
                if z < zbuf[y, x]:
                    zbuf[y, x] = z
                    owner[y, x] = i
                    shade[y, x] = AMBIENT + DIFFUSE * max(lz, 0.0)
                by0, by1, bx0, bx1 = min(by0, y), max(by1, y), min(bx0, x), max(bx1, x)
            continue
        x0 = max(int(np.floor(cx - rp)), 0)
        x1 = min(int(np.ceil(cx + rp)), w - 1)
        y0 = max(int(np.floor(cy - rp)), 0)
        y1 = min(int(np.ceil(cy + rp)), h - 1)
        if x0 > x1 or y0 > y1:
            continue
        by0, by1, bx0, bx1 = min(by0, y0), max(by1, y1), min(bx0, x0), max(bx1, x1)
        inv = 1.0 / rp
        front = d - radius
        for y in range(y0, y1 + 1):
            ny = (cy - (y + 0.5)) * inv  # eye-space y is up, image rows go down
            if ny * ny > 1.0:
                continue
            half = rp * np.sqrt(1.0 - ny * ny)  # the disc's pixel-centre span on this row
            xa = max(x0, int(np.ceil(cx - half - 0.5)))
            xb = min(x1, int(np.floor(cx + half - 0.5)))
            for x in range(xa, xb + 1):
                if zbuf[y, x] <= front:  # hidden even at the sphere's nearest point
                    continue
                nx = (x + 0.5 - cx) * inv
                r2 = min(nx * nx + ny * ny, 1.0)
                nz = np.sqrt(1.0 - r2)
                z = d - radius * nz
                if z < zbuf[y, x]:
                    zbuf[y, x] = z
                    owner[y, x] = i
                    shade[y, x] = AMBIENT + DIFFUSE * max(nx * lx + ny * ly + nz * lz, 0.0)
    return by0, by1, bx0, bx1


@njit(cache=True, nogil=True)
def composite(
    box, owner, shade, zbuf, colour, wall_depth, wall_rgb, wall_t, over_rgb, over_t, out
):  # pragma: no cover - jit
    """Within `box` (y0, y1, x0, x1), put each particle pixel's lit colour into `out` (which holds
    the static frame) behind or in front of the walls by depth, under the 2D overlays; reset the
    pixel's `owner` and `zbuf` for the next frame. Layers are uint8: colours over black and
    transmittances x 255."""
    y0, y1, x0, x1 = box
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            i = owner[y, x]
            if i < 0:
                continue
            behind = zbuf[y, x] > wall_depth[y, x]
            s = shade[y, x]
            for c in range(3):
                v = colour[i, c] * s
                if behind:
                    v = wall_rgb[y, x, c] + wall_t[y, x, c] * v * (1.0 / 255.0)
                v = over_rgb[y, x, c] + over_t[y, x, c] * v * (1.0 / 255.0)
                v = min(max(v, 0.0), 255.0)
                out[y, x, c] = np.uint8(v + 0.5)
            owner[y, x] = -1
            zbuf[y, x] = np.inf


@njit(cache=True, nogil=True)
def _up_filter(img, raw):  # pragma: no cover - jit
    """PNG filter type 2 (Up) rows: each byte minus the one above; smooth backgrounds become runs
    of zeros, which zlib compresses fast."""
    h = img.shape[0]
    n = img.shape[1] * img.shape[2]
    flat = img.reshape(h, n)
    for y in range(h):
        raw[y, 0] = 2
        if y == 0:
            for k in range(n):
                raw[y, k + 1] = flat[y, k]
        else:
            for k in range(n):
                raw[y, k + 1] = np.uint8((np.int32(flat[y, k]) - np.int32(flat[y - 1, k])) & 0xFF)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(img: np.ndarray, level: int = 1) -> bytes:
    """An 8-bit RGB PNG of `img` (h, w, 3 uint8): Up-filtered rows, zlib `level`.

    ~2.5x faster than Pillow's PNG writer at its fastest level on a 1280x720 render, for a file of
    the same size (Pillow tries every filter per row).
    """
    img = np.ascontiguousarray(img, dtype=np.uint8)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"encode_png takes an (h, w, 3) image, got shape {img.shape}")
    h, w = img.shape[:2]
    raw = np.empty((h, 3 * w + 1), dtype=np.uint8)
    _up_filter(img, raw)
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8-bit truecolour, no interlace
    return (
        b"\x89PNG\r\n\x1a\n"
        + _chunk(b"IHDR", header)
        + _chunk(b"IDAT", zlib.compress(raw.data, level))
        + _chunk(b"IEND", b"")
    )


def warm_up() -> None:
    """Load (or compile) every kernel on a tiny frame, so the first real frame pays nothing."""
    h = w = 4
    zbuf, owner = np.full((h, w), np.inf, np.float32), np.full((h, w), -1, np.int32)
    shade, img = np.zeros((h, w), np.float32), np.zeros((h, w, 3), np.uint8)
    one = np.ones(1)
    sx, sy, dist, rad = (np.empty(1) for _ in range(4))
    project(np.zeros((1, 3)), np.eye(4), 1.0, 2.0, 2.0, 0.1, sx, sy, dist, rad)
    box = splat(2.0 * one, 2.0 * one, one, 1.5 * one, 0.1, LIGHT, zbuf, owner, shade)
    layer, t = np.zeros((h, w, 3), np.uint8), np.full((h, w, 3), 255, np.uint8)
    composite(box, owner, shade, zbuf, np.ones((1, 3), np.float32), zbuf.copy(), layer, t, layer, t, img)
    encode_png(img)
