"""A wall object's field grid read at one body-frame point: the kernel integral I of its solid and
its signed distance φ (design brief boundary-fields.md section 7; built by boundary/mesh_field.py).

Device functions in the rules of `bodies` (plain `math`, no numpy calls, no allocation, no
globals but integer constants), so the CPU passes inline them and numba-cuda compiles them as
device functions. Arithmetic is float64 whatever the pool's dtype.

Layout. One flat pool (float32 or float64) holds every grid, node after node, each node the pair
(φ, I): pool[2 k] = φ, pool[2 k + 1] = I at node k = offset + ix + nx (iy + ny iz) (x fastest),
node (ix, iy, iz) at origin + h_g (ix, iy, iz). Row g of a (n_grids, HEADER) float64 header:

    [HDR_OX, HDR_OY, HDR_OZ]   origin, body frame (m)
    HDR_INV_H                  1 / h_g (1/m)
    [HDR_NX, HDR_NY, HDR_NZ]   nodes per axis (≥ 4; whole numbers stored as floats)
    HDR_OFFSET                 the grid's first node in the pool (nodes, not floats)
    HDR_PAD                    how far the grid's faces lie outside the solid (≥ H + 2 h_g, m)

Conventions: φ > 0 outside the solid (in the fluid, for an obstacle or a body), I ∈ [0, 1] the
solid's kernel mass at the point; a container inverts both (−φ, 1 − I) in its caller.
Interpolation: I and ∇I by tricubic Catmull–Rom (64 nodes, C¹; node indices clamped at the faces,
where the padding leaves I constant), φ and ∇φ trilinear (∇φ the interpolant's gradient, constant
per cell along each axis). Outside the grid the point is outside the solid by at least the padding:
I = 0, ∇I = 0, φ = HDR_PAD + the distance to the grid's box (a lower bound of the true distance,
never below H), ∇φ the unit vector away from the box.
"""

import math

from numba import njit

HDR_OX, HDR_OY, HDR_OZ, HDR_INV_H, HDR_NX, HDR_NY, HDR_NZ, HDR_OFFSET, HDR_PAD = 0, 1, 2, 3, 4, 5, 6, 7, 8
HEADER = 9  # floats per header row
PHI, KI = 0, 1  # a node's slots in the pool: signed distance, kernel integral


@njit(inline="always")
def _node(pool, k, slot):
    """Node k's value in `slot`, as float64 (a float32 pool is widened before any arithmetic)."""
    return float(pool[2 * k + slot])


@njit(inline="always")
def _cell(u, n):
    """(cell index in [0, n − 2], fraction in [0, 1]) of grid coordinate u ∈ [0, n − 1]."""
    i = min(max(int(math.floor(u)), 0), n - 2)
    return i, u - i


@njit(inline="always")
def _cr(t, m):
    """Catmull–Rom weight of stencil node m (nodes i − 1 .. i + 2 as m = 0 .. 3) at t, and its d/dt."""
    t2 = t * t
    if m == 0:
        return 0.5 * (-t2 * t + 2.0 * t2 - t), 0.5 * (-3.0 * t2 + 4.0 * t - 1.0)
    if m == 1:
        return 0.5 * (3.0 * t2 * t - 5.0 * t2 + 2.0), 0.5 * (9.0 * t2 - 10.0 * t)
    if m == 2:
        return 0.5 * (-3.0 * t2 * t + 4.0 * t2 + t), 0.5 * (-9.0 * t2 + 8.0 * t + 1.0)
    return 0.5 * (t2 * t - t2), 0.5 * (3.0 * t2 - 2.0 * t)


@njit(inline="always")
def _outside(hdr, g, u, v, w, nx, ny, nz):
    """(φ, ∇φ) off the grid: the padding plus the distance to the grid's box (grid units u, v, w)."""
    h = 1.0 / hdr[g, HDR_INV_H]
    ex = (min(u, 0.0) + max(u - (nx - 1), 0.0)) * h
    ey = (min(v, 0.0) + max(v - (ny - 1), 0.0)) * h
    ez = (min(w, 0.0) + max(w - (nz - 1), 0.0)) * h
    dist = math.sqrt(ex * ex + ey * ey + ez * ez)
    return hdr[g, HDR_PAD] + dist, ex / dist, ey / dist, ez / dist


@njit(inline="always")
def _coords(hdr, g, x, y, z):
    """Grid coordinates of body-frame point (x, y, z), the grid's sizes, and whether it is on the grid."""
    inv_h = hdr[g, HDR_INV_H]
    u = (x - hdr[g, HDR_OX]) * inv_h
    v = (y - hdr[g, HDR_OY]) * inv_h
    w = (z - hdr[g, HDR_OZ]) * inv_h
    nx, ny, nz = int(hdr[g, HDR_NX]), int(hdr[g, HDR_NY]), int(hdr[g, HDR_NZ])
    inside = u >= 0.0 and v >= 0.0 and w >= 0.0 and u <= nx - 1 and v <= ny - 1 and w <= nz - 1
    return u, v, w, nx, ny, nz, inside


@njit(inline="always")
def grid_kernel_integral(hdr, g, pool, x, y, z):
    """(I, dI/dx, dI/dy, dI/dz) of grid g at body-frame point (x, y, z): tricubic Catmull–Rom."""
    u, v, w, nx, ny, nz, on = _coords(hdr, g, x, y, z)
    if not on:
        return 0.0, 0.0, 0.0, 0.0
    inv_h = hdr[g, HDR_INV_H]
    off = int(hdr[g, HDR_OFFSET])
    i, tx = _cell(u, nx)
    j, ty = _cell(v, ny)
    k, tz = _cell(w, nz)
    wx0, dx0 = _cr(tx, 0)
    wx1, dx1 = _cr(tx, 1)
    wx2, dx2 = _cr(tx, 2)
    wx3, dx3 = _cr(tx, 3)
    i0, i1, i2, i3 = max(i - 1, 0), i, i + 1, min(i + 2, nx - 1)
    val = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for c in range(4):
        wz, dz = _cr(tz, c)
        kk = min(max(k - 1 + c, 0), nz - 1)
        for b in range(4):
            wy, dy = _cr(ty, b)
            jj = min(max(j - 1 + b, 0), ny - 1)
            row = off + nx * (jj + ny * kk)
            f0 = _node(pool, row + i0, KI)
            f1 = _node(pool, row + i1, KI)
            f2 = _node(pool, row + i2, KI)
            f3 = _node(pool, row + i3, KI)
            s = wx0 * f0 + wx1 * f1 + wx2 * f2 + wx3 * f3
            ds = dx0 * f0 + dx1 * f1 + dx2 * f2 + dx3 * f3
            val += wy * wz * s
            gx += wy * wz * ds
            gy += dy * wz * s
            gz += wy * dz * s
    return val, gx * inv_h, gy * inv_h, gz * inv_h


@njit(inline="always")
def grid_distance(hdr, g, pool, x, y, z):
    """(φ, dφ/dx, dφ/dy, dφ/dz) of grid g at body-frame point (x, y, z): trilinear."""
    u, v, w, nx, ny, nz, on = _coords(hdr, g, x, y, z)
    if not on:
        return _outside(hdr, g, u, v, w, nx, ny, nz)
    inv_h = hdr[g, HDR_INV_H]
    off = int(hdr[g, HDR_OFFSET])
    i, tx = _cell(u, nx)
    j, ty = _cell(v, ny)
    k, tz = _cell(w, nz)
    n00 = off + i + nx * (j + ny * k)
    n10 = n00 + nx
    n01 = n00 + nx * ny
    n11 = n01 + nx
    a000, a100 = _node(pool, n00, PHI), _node(pool, n00 + 1, PHI)
    a010, a110 = _node(pool, n10, PHI), _node(pool, n10 + 1, PHI)
    a001, a101 = _node(pool, n01, PHI), _node(pool, n01 + 1, PHI)
    a011, a111 = _node(pool, n11, PHI), _node(pool, n11 + 1, PHI)
    # along x, then y, then z; the gradient from the same factors
    c00 = a000 + tx * (a100 - a000)
    c10 = a010 + tx * (a110 - a010)
    c01 = a001 + tx * (a101 - a001)
    c11 = a011 + tx * (a111 - a011)
    c0 = c00 + ty * (c10 - c00)
    c1 = c01 + ty * (c11 - c01)
    val = c0 + tz * (c1 - c0)
    d00 = a100 - a000
    d10 = a110 - a010
    d01 = a101 - a001
    d11 = a111 - a011
    d0 = d00 + ty * (d10 - d00)
    d1 = d01 + ty * (d11 - d01)
    gx = d0 + tz * (d1 - d0)
    gy = (c10 - c00) + tz * ((c11 - c01) - (c10 - c00))
    gz = c1 - c0
    return val, gx * inv_h, gy * inv_h, gz * inv_h
