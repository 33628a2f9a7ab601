"""The gauges' numerics, written once as numba functions (docs/gauges.md, "What each gauge computes").

Every function reads the fluid as a frame stores it: positions, velocities, densities, pressures and
masses rounded to float32 (`_q`, `FRAME_DTYPE`), so the gauges of a run and `ipsph gauge` on its
frames see the same numbers and agree exactly at frame times; the rounding (6e-8 relative) is far
below what SPH interpolation resolves. Walls are read as the run holds them (float64, boundary.vtu).
The kernel and its support are the solver's (`backends.kernels`). Sums run in a fixed order (the
fluid's index order within cells of a small grid of the gauge's own), so a gauge gives the same
value for the same arrays, whatever the thread count.

    select         one pass over the fluid: per gauge, the particles in its box (CSR, index order)
    point_values   Shepard interpolation at a point: p, v, rho = sum_j V_j f_j W / sum_j V_j W, V_j = m_j / rho_j
    level_value    the height where the fluid fraction c = sum_j V_j W crosses 1/2 going up a vertical line
    flow_value     the volume flux sum_j V_j (v_j . n) F(s_j) through a rectangle (F: W integrated over a plane)
    wall_force     the fluid's pressure force and torque on a wall's particles, the reaction of Akinci's term
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..backends.kernels import grad_w_factor, w

FRAME_DTYPE = np.float32  # what frames store (io.vtu): the precision the gauges read the fluid at
MIN_NEIGHBOURS = 4  # a point gauge with fewer fluid particles within H reports NaN (gauges.point_columns)
LEVEL_FRACTION = 0.5  # the free surface: where the interpolated fluid fraction crosses one half
LEVEL_STEP_R = 0.5  # a level gauge evaluates the fraction every LEVEL_STEP_R r up its line


@njit(inline="always")
def _q(a):
    """A value as a frame stores it (float32), back in float64."""
    return float(np.float32(a))


@njit(cache=True)
def select(x, boxes):
    """(start, idx): for gauge g, idx[start[g]:start[g + 1]] are the particles whose frame position
    lies in boxes[g] = (lo_x, lo_y, lo_z, hi_x, hi_y, hi_z), ascending. One pass over the fluid."""
    k = boxes.shape[0]
    count = np.zeros(k + 1, dtype=np.int64)
    for i in range(x.shape[0]):
        a0, a1, a2 = _q(x[i, 0]), _q(x[i, 1]), _q(x[i, 2])
        for g in range(k):
            b = boxes[g]
            if b[0] <= a0 <= b[3] and b[1] <= a1 <= b[4] and b[2] <= a2 <= b[5]:
                count[g + 1] += 1
    start = np.cumsum(count)
    idx = np.empty(start[k], dtype=np.int64)
    fill = start[:k].copy()
    for i in range(x.shape[0]):
        a0, a1, a2 = _q(x[i, 0]), _q(x[i, 1]), _q(x[i, 2])
        for g in range(k):
            b = boxes[g]
            if b[0] <= a0 <= b[3] and b[1] <= a1 <= b[4] and b[2] <= a2 <= b[5]:
                idx[fill[g]] = i
                fill[g] += 1
    return start, idx


@njit(cache=True)
def point_values(x, v, rho, p, m, start, idx, gauges, points, h, out):
    """For each point gauge k (its index gauges[k] into the CSR start/idx of `select`):
    out[k] = (p, vx, vy, vz, rho, n) at points[k], Shepard-normalised SPH interpolation over the n
    fluid particles within H; NaN values when n < MIN_NEIGHBOURS."""
    for k in range(gauges.shape[0]):
        g = gauges[k]
        q0, q1, q2 = points[k, 0], points[k, 1], points[k, 2]
        n = 0
        s = sp = s0 = s1 = s2 = sr = 0.0
        for t in range(start[g], start[g + 1]):
            j = idx[t]
            d0, d1, d2 = _q(x[j, 0]) - q0, _q(x[j, 1]) - q1, _q(x[j, 2]) - q2
            r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if r < h:
                rj = _q(rho[j])
                wv = _q(m[j]) / rj * w(r, h)
                n += 1
                s += wv
                sp += wv * _q(p[j])
                s0 += wv * _q(v[j, 0])
                s1 += wv * _q(v[j, 1])
                s2 += wv * _q(v[j, 2])
                sr += wv * rj
        out[k, 5] = n
        if n < MIN_NEIGHBOURS or not s > 0.0:
            out[k, :5] = np.nan
        else:
            out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = sp / s, s0 / s, s1 / s, s2 / s, sr / s


@njit(cache=True)
def level_value(x, rho, m, idx, x0, z0, y0, top, step, h):
    """The free-surface height on the vertical line (x0, y, z0), y0 <= y <= top: going up from y0,
    the first wet sample (fluid fraction c >= 1/2) and then the first dry one above it; the
    crossing is interpolated linearly between the two. top if the line is wet to its top, NaN if
    no sample is wet. c(y) = sum_j V_j W is evaluated every `step` metres."""
    nc = idx.shape[0]
    ys = np.empty(nc)
    r2 = np.empty(nc)
    vol = np.empty(nc)
    n = 0
    for k in range(nc):
        j = idx[k]
        d0, d2 = _q(x[j, 0]) - x0, _q(x[j, 2]) - z0
        rr = d0 * d0 + d2 * d2
        if rr < h * h:
            ys[n] = _q(x[j, 1])
            r2[n] = rr
            vol[n] = _q(m[j]) / _q(rho[j])
            n += 1
    order = np.argsort(ys[:n], kind="mergesort")
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


@njit(cache=True)
def flow_value(x, v, rho, m, idx, lo, hi, axis, h):
    """Volume flux through the rectangle lo..hi (flat along `axis`, counted positive along +axis):
    Q = sum_j V_j v_j[axis] F(s_j) over the particles within H of its plane whose projection falls
    inside it (F = plane_kernel, s_j their distance from the plane); V_j = m_j / rho_j."""
    plane = lo[axis]
    total = 0.0
    for k in range(idx.shape[0]):
        j = idx[k]
        inside = True
        for a in range(3):
            if a != axis:
                c = _q(x[j, a])
                if c < lo[a] or c > hi[a]:
                    inside = False
        if not inside:
            continue
        s = _q(x[j, axis]) - plane
        if abs(s) < h:
            total += _q(m[j]) / _q(rho[j]) * _q(v[j, axis]) * plane_kernel(s, h)
    return total


GRID_CELL_H = 0.5  # the gauges' own grids: cells of H/2 (a support sphere scans ~11 H^3 of cells, not 27)


@njit(cache=True)
def _grid(xs, cell):
    """A grid of cubic cells of size `cell` over the points xs, padded by one cell: (origin, dims,
    order, start) with the points of cell c at order[start[c]:start[c + 1]], ascending (a stable
    counting sort)."""
    n = xs.shape[0]
    origin = np.zeros(3)
    dims = np.ones(3, dtype=np.int64)
    for a in range(3):
        lo, hi = np.inf, -np.inf
        for i in range(n):
            lo = min(lo, xs[i, a])
            hi = max(hi, xs[i, a])
        if n == 0:
            lo = hi = 0.0
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


@njit(cache=True)
def wall_force(x, rho, p, m, idx, xw, mw, centre, h, out):
    """The fluid's pressure force on the wall particles xw (masses mw = rho0 Psi_b) and its torque
    about `centre`, out = (Fx, Fy, Fz, Tx, Ty, Tz):

        f_b = sum_i m_i (p_i / rho_i^2) m_b grad W(x_i - x_b),   F = sum_b f_b,   T = sum_b (x_b - c) x f_b

    the reaction of the pressure term the walls exert on the fluid [AIA*12] (rigid.wall_forces
    with the pressure p = k rho^2 each method writes). idx: the fluid candidates; each f_b sums its
    fluid neighbours cell by cell (the wall particles in parallel), then F and T sum the f_b in the
    order given, so the value does not depend on the thread count."""
    nc = idx.shape[0]
    xs = np.empty((nc, 3))
    coeff = np.empty(nc)
    for k in range(nc):
        j = idx[k]
        xs[k, 0], xs[k, 1], xs[k, 2] = _q(x[j, 0]), _q(x[j, 1]), _q(x[j, 2])
        rj = _q(rho[j])
        coeff[k] = _q(m[j]) * _q(p[j]) / (rj * rj)
    cell = GRID_CELL_H * h
    origin, dims, order, start = _grid(xs, cell)
    fw = np.empty((xw.shape[0], 3))
    _wall_particle_forces(xs, coeff, origin, dims, order, start, cell, xw, mw, h, fw)
    out[:] = 0.0
    for b in range(xw.shape[0]):
        add_force_torque(out, xw[b], centre, fw[b, 0], fw[b, 1], fw[b, 2])


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


@njit(parallel=True, cache=True)
def _wall_particle_forces(xs, coeff, origin, dims, order, start, cell, xw, mw, h, fw):
    """fw[b] = f_b of `wall_force` for every wall particle b, each a sum in cell order."""
    hh = h * h
    for b in prange(xw.shape[0]):
        f0 = f1 = f2 = 0.0
        lo0, lo1, lo2, hi0, hi1, hi2 = cell_range(xw[b], origin, dims, cell, h)
        for c2 in range(lo2, hi2 + 1):
            for c1 in range(lo1, hi1 + 1):
                for c0 in range(lo0, hi0 + 1):
                    c = c0 + dims[0] * (c1 + dims[1] * c2)
                    for t in range(start[c], start[c + 1]):
                        i = order[t]
                        d0, d1, d2 = xs[i, 0] - xw[b, 0], xs[i, 1] - xw[b, 1], xs[i, 2] - xw[b, 2]
                        rr = d0 * d0 + d1 * d1 + d2 * d2
                        if rr < hh:  # most candidates of a cell scan lie beyond H: no root for them
                            r = math.sqrt(rr)
                            if r < h:
                                g = coeff[i] * grad_w_factor(r, h)
                                f0 += g * d0
                                f1 += g * d1
                                f2 += g * d2
        fw[b, 0], fw[b, 1], fw[b, 2] = mw[b] * f0, mw[b] * f1, mw[b] * f2
