"""Every gauge of a sample in two compiled passes over the fluid (docs/gauges.md, "Cost").

`wall_forces` (parallel over blocks of particles) gives every fluid particle within reach of a
force gauge's wall its force on that wall, F_i (`kernels.force_at`): the particle looks up the wall
particles near it in the wall's cell lists (`wall_cells`, built once per static wall) and sums its
pairs. `sample` (serial) then visits each fluid particle once: it rounds its position as a frame
stores it, tests it against every due gauge's box and hands it to that gauge's body (`kernels`):
a point gauge, a flow rectangle and a force gauge (F += F_i, T += (x_i - c) x F_i) sum it at once,
a level gauge lists it (its line is walked after the pass, over its particles sorted by height).
Sums run in the fluid's index order, so neither the thread count nor the fluid's whereabouts change
a value. Outputs go into arrays the caller allocated once (`acc`, F_i, the level lists and their
scratch): nothing is allocated per sample.

The force gauges' walls are one joined set (`walls.WallGrids`): positions `wx`, masses `wm`;
force gauge f's grid has its origin `worigin[f]`, its cell counts `wdims[f]` and its cell lists
`wcand[wstart[woff[f] + c] : wstart[woff[f] + c + 1]]` (indices into wx, ascending).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..backends import kernels as sph_kernels
from ..backends._cache import depend_on
from ..backends.kernels import FASTMATH
from . import kernels
from .kernels import _q, flow_add, force_at, level_walk, point_add, point_finish

POINT, LEVEL, FLOW, FORCE = 0, 1, 2, 3  # a gauge's kind in `kinds`
ACC = 12  # acc's columns: point (p, vx, vy, vz, rho), level (level, level_max), flow (Q), force (F, T, F_visc, T_visc)
WALL_CELL_H = 0.5  # a force gauge's wall cells: cubes of H/2 (a particle tests ~16 wall candidates per wall layer)
BLOCKS = 64  # wall_forces' blocks of particles, each with its own scratch (as backends.cpu_passes.CHUNKS)


@njit(cache=True)
def wall_cells(xw, h, cell):
    """A wall's particles by cell: (origin, dims, start, cand), cubic cells of size `cell` over the
    wall padded by H + cell, so that a point outside the grid has no wall particle within H; cell c
    lists the wall particles within H of its box (with a 1e-9 H margin for rounding), ascending:
    cand[start[c]:start[c + 1]]. Built once per static wall (and per sample for a moving one)."""
    n = xw.shape[0]
    pad = h + cell
    reach = h * (1.0 + 1e-9)
    origin = np.zeros(3)
    dims = np.ones(3, dtype=np.int64)
    for a in range(3):
        lo, hi = kernels.axis_bounds(xw, a)
        origin[a] = lo - pad
        dims[a] = int((hi - lo + 2.0 * pad) / cell) + 1
    start = np.zeros(dims[0] * dims[1] * dims[2] + 1, dtype=np.int64)
    cand = np.empty(0, dtype=np.int32)
    for fill in range(2):  # count, then fill
        for b in range(n):
            lo0, hi0 = _span(xw[b, 0], reach, origin[0], cell, dims[0])
            lo1, hi1 = _span(xw[b, 1], reach, origin[1], cell, dims[1])
            lo2, hi2 = _span(xw[b, 2], reach, origin[2], cell, dims[2])
            for c2 in range(lo2, hi2 + 1):
                e2 = _gap(xw[b, 2], origin[2] + c2 * cell, cell)
                for c1 in range(lo1, hi1 + 1):
                    e1 = _gap(xw[b, 1], origin[1] + c1 * cell, cell)
                    for c0 in range(lo0, hi0 + 1):
                        e0 = _gap(xw[b, 0], origin[0] + c0 * cell, cell)
                        if e0 * e0 + e1 * e1 + e2 * e2 <= reach * reach:
                            k = c0 + dims[0] * (c1 + dims[1] * c2)
                            if fill:
                                cand[start[k]] = b
                                start[k] += 1
                            else:
                                start[k + 1] += 1
        if not fill:
            for k in range(start.shape[0] - 1):
                start[k + 1] += start[k]
            cand = np.empty(start[-1], dtype=np.int32)
    for k in range(start.shape[0] - 1, 0, -1):  # the fill advanced each cell's start to its end
        start[k] = start[k - 1]
    start[0] = 0
    return origin, dims, start, cand


@njit(inline="always")
def _span(c, reach, lo, cell, n):
    """The cells [first, last] of an axis (n cells of `cell` from lo) within `reach` of the coordinate c."""
    return max(int(math.floor((c - reach - lo) / cell)), 0), min(int(math.floor((c + reach - lo) / cell)), n - 1)


@njit(inline="always")
def _gap(c, lo, cell):
    """The distance of the coordinate c from the interval [lo, lo + cell] (0 inside)."""
    return max(lo - c, c - (lo + cell), 0.0)


@njit(inline="always")
def _wall_cell(a0, a1, a2, origin, dims, cell):
    """The linear cell of the point a in a wall grid, or -1 outside it (no wall particle within H)."""
    f0 = math.floor((a0 - origin[0]) / cell)
    f1 = math.floor((a1 - origin[1]) / cell)
    f2 = math.floor((a2 - origin[2]) / cell)
    if f0 < 0 or f1 < 0 or f2 < 0 or f0 >= dims[0] or f1 >= dims[1] or f2 >= dims[2]:
        return -1
    return int(f0) + dims[0] * (int(f1) + dims[1] * int(f2))


@njit(inline="always")
def _stable_order(ys, n, order, tmp):
    """order[:n] = the indices 0..n-1 sorted by ys, ties in index order (a bottom-up merge sort in place)."""
    for k in range(n):
        order[k] = k
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            a, b, k = lo, mid, lo
            while a < mid and b < hi:
                if ys[order[b]] < ys[order[a]]:
                    tmp[k] = order[b]
                    b += 1
                else:
                    tmp[k] = order[a]
                    a += 1
                k += 1
            while a < mid:
                tmp[k] = order[a]
                a += 1
                k += 1
            while b < hi:
                tmp[k] = order[b]
                b += 1
                k += 1
        for k in range(n):
            order[k] = tmp[k]
        width *= 2


@njit(parallel=True, fastmath=FASTMATH, cache=True)
def wall_forces(x, rho, p, m, boxes, kinds, slot, due, h, wx, wm, worigin, wdims, wstart, woff, wcand, wcell, wbuf, fi):
    """fi[i, f] = F_i (`kernels.force_at`) of every fluid particle i on force gauge f's wall (0 out of
    its reach or when the gauge is not due): prange over blocks of particles, each with its own
    scratch wbuf[block], writing row i only; `sample` then sums the rows in index order, so the
    value does not depend on the thread count."""
    n, blocks = x.shape[0], wbuf.shape[0]
    per = (n + blocks - 1) // blocks
    for blk in prange(blocks):
        buf = wbuf[blk]
        for i in range(blk * per, min(n, (blk + 1) * per)):
            a0, a1, a2 = _q(x[i, 0]), _q(x[i, 1]), _q(x[i, 2])
            rj = _q(rho[i])
            coeff = _q(m[i]) * _q(p[i]) / (rj * rj)
            for g in range(kinds.shape[0]):
                if kinds[g] != FORCE:
                    continue
                f, s = slot[g], woff[slot[g]]
                fi[i, f, 0] = fi[i, f, 1] = fi[i, f, 2] = 0.0
                if not (due[g] and boxes[g, 0] <= a0 <= boxes[g, 3] and boxes[g, 1] <= a1 <= boxes[g, 4]):
                    continue
                if not boxes[g, 2] <= a2 <= boxes[g, 5]:
                    continue
                c = _wall_cell(a0, a1, a2, worigin[f], wdims[f], wcell)
                if c >= 0 and wstart[s + c + 1] > wstart[s + c]:
                    fi[i, f, 0], fi[i, f, 1], fi[i, f, 2] = force_at(
                        a0, a1, a2, coeff, wx, wm, wcand, wstart[s + c], wstart[s + c + 1], h, buf
                    )


@njit(cache=True)
def sample(x, v, rho, p, m, boxes, kinds, par, slot, due, h, step, fi, lvl_idx, lvl_count, lvl_real, lvl_int, acc):
    """acc[g] = the values of every due gauge g for the fluid's arrays (layout: ACC), the force gauges'
    from `wall_forces`' rows fi; returns the most particles a level line holds: when above lvl_idx's
    width its lists were cut, and the caller widens them and samples again.

    boxes[g]: (lo, hi) of the fluid that can reach gauge g; par[g]: point q; level (x0, y0, z0, top);
    flow (lo, hi, axis); force: its centre of torque. slot[g]: a level gauge's row of lvl_idx, a
    force gauge's column of fi."""
    acc[:] = 0.0
    lvl_count[:] = 0
    cap = lvl_idx.shape[1]
    n_g = kinds.shape[0]
    for i in range(x.shape[0]):
        a0, a1, a2 = _q(x[i, 0]), _q(x[i, 1]), _q(x[i, 2])
        for g in range(n_g):
            if not (due[g] and boxes[g, 0] <= a0 <= boxes[g, 3] and boxes[g, 1] <= a1 <= boxes[g, 4]):
                continue
            if not boxes[g, 2] <= a2 <= boxes[g, 5]:  # (six chained bounds in one test: a slower pass)
                continue
            kind = kinds[g]
            if kind == POINT:
                point_add(acc[g], a0, a1, a2, par[g, 0], par[g, 1], par[g, 2], v, rho, p, m, i, h)
            elif kind == LEVEL:
                d0, d2 = a0 - par[g, 0], a2 - par[g, 2]
                if d0 * d0 + d2 * d2 < h * h:
                    s, c = slot[g], lvl_count[slot[g]]
                    if c < cap:
                        lvl_idx[s, c] = i
                    lvl_count[s] = c + 1
            elif kind == FLOW:
                acc[g, 0] += flow_add(x, v, rho, m, i, par[g, :3], par[g, 3:6], int(par[g, 6]), h)
            else:  # F += F_i, T += (x_i - c) x F_i
                f0, f1, f2 = fi[i, slot[g], 0], fi[i, slot[g], 1], fi[i, slot[g], 2]
                e0, e1, e2 = a0 - par[g, 0], a1 - par[g, 1], a2 - par[g, 2]
                acc[g, 0] += f0
                acc[g, 1] += f1
                acc[g, 2] += f2
                acc[g, 3] += e1 * f2 - e2 * f1
                acc[g, 4] += e2 * f0 - e0 * f2
                acc[g, 5] += e0 * f1 - e1 * f0
    most = 0
    for s in range(lvl_count.shape[0]):
        most = max(most, lvl_count[s])
    for g in range(n_g):
        if not due[g]:
            continue
        if kinds[g] == POINT:
            point_finish(acc[g])
        elif kinds[g] == LEVEL and most <= cap:
            s = slot[g]
            n = lvl_count[s]
            ys, r2, vol = lvl_real[0], lvl_real[1], lvl_real[2]
            for k in range(n):
                j = lvl_idx[s, k]
                d0, d2 = _q(x[j, 0]) - par[g, 0], _q(x[j, 2]) - par[g, 2]
                ys[k], r2[k], vol[k] = _q(x[j, 1]), d0 * d0 + d2 * d2, _q(m[j]) / _q(rho[j])
            _stable_order(ys, n, lvl_int[0], lvl_int[1])
            acc[g, 0] = level_walk(ys, r2, vol, lvl_int[0], n, par[g, 1], par[g, 3], step, h)
    return most


# cache=True keys a pass's cache on this file only: it also depends on the bodies it inlines
depend_on((sample, wall_forces, wall_cells), (__file__, kernels.__file__, sph_kernels.__file__))
