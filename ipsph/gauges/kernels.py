"""The gauges' numerics for one fluid particle or one gauge, written once as numba functions (docs/gauges.md,
"What each gauge computes"); `passes` runs them over the fluid.

Every function reads the fluid as a frame stores it: positions, velocities, densities, pressures and
masses rounded to float32 (`_q`, `FRAME_DTYPE`), so the gauges of a run and `ipsph gauge` on its
frames see the same numbers and agree exactly at frame times; the rounding (6e-8 relative) is far
below what SPH interpolation resolves. Walls are read as the run holds them (float64, boundary.vtu).
The kernel and its support are the solver's (`backends.kernels`). Each gauge sums its particles in
the fluid's index order (a force gauge: each particle's wall neighbours in the wall's canonical order),
so a gauge gives the same value for the same arrays, whatever the thread count.

    point_add      Shepard interpolation at a point: p, v, rho = sum_j V_j f_j W / sum_j V_j W, V_j = m_j / rho_j
    level_walk     the height where the fluid fraction c = sum_j V_j W crosses 1/2 going up a vertical line
    flow_add       the volume flux sum_j V_j (v_j . n) F(s_j) through a rectangle (F: W integrated over a plane)
    force_at       the pressure force of one fluid particle on a wall, the reaction of Akinci's term
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..backends.kernels import grad_w_factor, w

FRAME_DTYPE = np.float32  # what frames store (io.vtu): the precision the gauges read the fluid at
MIN_NEIGHBOURS = 4  # a point gauge with fewer fluid particles within H reports NaN (gauges.point_columns)
LEVEL_FRACTION = 0.5  # the free surface: where the interpolated fluid fraction crosses one half
LEVEL_STEP_R = 0.5  # a level gauge evaluates the fraction every LEVEL_STEP_R r up its line


@njit(inline="always")
def _q(a):
    """A value as a frame stores it (float32), back in float64."""
    return float(np.float32(a))


@njit(inline="always")
def point_add(acc, a0, a1, a2, q0, q1, q2, v, rho, p, m, j, h):
    """Fluid particle j (at a0, a1, a2) into the point gauge at q: acc = (sum V W, sum V W p,
    sum V W v (3), sum V W rho, n), over the particles within H."""
    d0, d1, d2 = a0 - q0, a1 - q1, a2 - q2
    r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if r < h:
        rj = _q(rho[j])
        wv = _q(m[j]) / rj * w(r, h)
        acc[0] += wv
        acc[1] += wv * _q(p[j])
        acc[2] += wv * _q(v[j, 0])
        acc[3] += wv * _q(v[j, 1])
        acc[4] += wv * _q(v[j, 2])
        acc[5] += wv * rj
        acc[6] += 1.0


@njit(inline="always")
def point_finish(acc):
    """acc of `point_add` -> (p, vx, vy, vz, rho) in acc[:5]; NaN with fewer than MIN_NEIGHBOURS particles."""
    s = acc[0]
    if acc[6] < MIN_NEIGHBOURS or not s > 0.0:
        acc[:5] = np.nan
    else:
        acc[0], acc[1], acc[2], acc[3], acc[4] = acc[1] / s, acc[2] / s, acc[3] / s, acc[4] / s, acc[5] / s


@njit(inline="always")
def level_walk(ys, r2, vol, order, n, y0, top, step, h):
    """The free-surface height on a vertical line from y0 to top, given its n fluid particles within
    H of the line (heights ys, squared distances r2 from it, volumes vol; `order` sorts them by
    height, stably): going up from y0, the first wet sample (fluid fraction c >= 1/2) and then the
    first dry one above it; the crossing is interpolated linearly between the two. top if the line
    is wet to its top, NaN if no sample is wet. c(y) = sum_j V_j W is evaluated every `step` metres."""
    ns = max(int(math.ceil((top - y0) / step)), 1) + 1
    dy = (top - y0) / (ns - 1)
    lo = 0
    prev = 0.0
    wet = False
    for s in range(ns):
        y = y0 + s * dy
        while lo < n and ys[order[lo]] <= y - h:
            lo += 1
        c = 0.0
        k = lo
        while k < n and ys[order[k]] < y + h:
            j = order[k]
            e = ys[j] - y
            c += vol[j] * w(math.sqrt(r2[j] + e * e), h)
            k += 1
        if c >= LEVEL_FRACTION:
            wet = True
        elif wet:
            return y - dy + (prev - LEVEL_FRACTION) / (prev - c) * dy
        prev = c
    return top if wet else np.nan


@njit(inline="always")
def plane_kernel(s, h):
    """F(s) = integral of W over the plane at distance s (2 pi int_|s|^H W(r) r dr): integrates to 1 over s."""
    a = abs(s) / h
    big = max(1.0 - a, 0.0)
    small = max(0.5 - a, 0.0)
    b4, s4 = big**4, small**4
    return 32.0 / h * (b4 / 4.0 - b4 * big / 5.0 - 4.0 * (s4 / 8.0 - s4 * small / 5.0))


@njit(inline="always")
def flow_add(x, v, rho, m, j, lo, hi, axis, h):
    """Fluid particle j's share of the volume flux through the rectangle lo..hi (flat along `axis`,
    counted positive along +axis): V_j v_j[axis] F(s_j) when it lies within H of the plane and its
    projection inside the rectangle (F = plane_kernel, s_j its distance from the plane), else 0."""
    for a in range(3):
        if a != axis:
            c = _q(x[j, a])
            if c < lo[a] or c > hi[a]:
                return 0.0
    s = _q(x[j, axis]) - lo[axis]
    if abs(s) < h:
        return _q(m[j]) / _q(rho[j]) * _q(v[j, axis]) * plane_kernel(s, h)
    return 0.0


@njit(inline="always")
def force_at(a0, a1, a2, coeff, xw, mw, cand, first, last, h, buf):
    """F_i = sum_b f_ib, the pressure force of the fluid particle i at a on the wall particles
    b = cand[first:last] (a superset of its wall neighbours):

        f_ib = m_i (p_i / rho_i^2) m_b grad W(x_i - x_b) = coeff m_b grad W(x_i - x_b)

    the reaction of the pressure term the walls exert on the fluid [AIA*12] (rigid.wall_forces with
    the pressure p = k rho^2 each method writes). f_ib acts along x_i - x_b, so its torque about a
    centre c at x_b is the one at x_i: the torque of the wall's f_ib is (x_i - c) x F_i. As the
    solver's bodies do, the neighbours within H are first gathered into `buf` (x_i - x_b, m_b), then
    the kernel is evaluated over that contiguous block; the pairs are summed in `cand`'s order."""
    hh = h * h
    n = 0
    for t in range(first, last):
        b = cand[t]
        d0, d1, d2 = a0 - xw[b, 0], a1 - xw[b, 1], a2 - xw[b, 2]
        if d0 * d0 + d1 * d1 + d2 * d2 < hh:
            buf[0, n], buf[1, n], buf[2, n], buf[3, n] = d0, d1, d2, mw[b]
            n += 1
    f0 = f1 = f2 = 0.0
    for k in range(n):
        d0, d1, d2 = buf[0, k], buf[1, k], buf[2, k]
        g = buf[3, k] * grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
        f0 += g * d0
        f1 += g * d1
        f2 += g * d2
    return coeff * f0, coeff * f1, coeff * f2


GRID_CELL_H = 0.5  # the viscous part's own grids: cells of H/2 (a support sphere scans ~11 H^3 of cells, not 27)


@njit(cache=True)
def axis_bounds(xs, a):
    """(min, max) of the points' coordinate a; (0, 0) for no points (the gauges' grids)."""
    if xs.shape[0] == 0:
        return 0.0, 0.0
    lo, hi = np.inf, -np.inf
    for i in range(xs.shape[0]):
        lo = min(lo, xs[i, a])
        hi = max(hi, xs[i, a])
    return lo, hi


@njit(cache=True)
def _grid(xs, cell):
    """A grid of cubic cells of size `cell` over the points xs, padded by one cell: (origin, dims,
    order, start) with the points of cell c at order[start[c]:start[c + 1]], ascending (a stable
    counting sort)."""
    n = xs.shape[0]
    origin = np.zeros(3)
    dims = np.ones(3, dtype=np.int64)
    for a in range(3):
        lo, hi = axis_bounds(xs, a)
        origin[a] = lo - cell
        dims[a] = int((hi - lo) / cell) + 3
    cells = np.empty(n, dtype=np.int64)
    count = np.zeros(dims[0] * dims[1] * dims[2] + 1, dtype=np.int64)
    for i in range(n):
        c0 = int((xs[i, 0] - origin[0]) / cell)
        c1 = int((xs[i, 1] - origin[1]) / cell)
        c2 = int((xs[i, 2] - origin[2]) / cell)
        cells[i] = c0 + dims[0] * (c1 + dims[1] * c2)
        count[cells[i] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[fill[cells[i]]] = i
        fill[cells[i]] += 1
    return origin, dims, order, start


@njit(inline="always")
def cell_range(p, origin, dims, cell, h):
    """The cells of a grid (`_grid`) that the sphere of radius h around p touches: lo0, lo1, lo2, hi0, hi1, hi2."""
    lo0 = max(int((p[0] - h - origin[0]) / cell), 0)
    lo1 = max(int((p[1] - h - origin[1]) / cell), 0)
    lo2 = max(int((p[2] - h - origin[2]) / cell), 0)
    hi0 = min(int((p[0] + h - origin[0]) / cell), dims[0] - 1)
    hi1 = min(int((p[1] + h - origin[1]) / cell), dims[1] - 1)
    hi2 = min(int((p[2] + h - origin[2]) / cell), dims[2] - 1)
    return lo0, lo1, lo2, hi0, hi1, hi2


@njit(inline="always")
def add_force_torque(out, at, centre, f0, f1, f2):
    """out (Fx, Fy, Fz, Tx, Ty, Tz) += the force f acting at `at` and its torque about `centre`."""
    e0, e1, e2 = at[0] - centre[0], at[1] - centre[1], at[2] - centre[2]
    out[0] += f0
    out[1] += f1
    out[2] += f2
    out[3] += e1 * f2 - e2 * f1
    out[4] += e2 * f0 - e0 * f2
    out[5] += e0 * f1 - e1 * f0
