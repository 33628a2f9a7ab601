"""The neighbour search on the device: the same grid, the same sort and the same lists as
`neighbours.search.NeighbourSearch`, built by CUDA kernels that launch the same per-particle
bodies (`rows`) as the CPU's.

Per step, all on the device:
  1. the cell of every fluid particle (`rows.cell_of`, the one binning rule, as a device
     function);
  2. a counting sort by cell: cell counts by atomic increments, their exclusive prefix sum
     (`exclusive_scan`, chunked and recursive: integer sums, exact in any order), a scatter
     into each cell's range, and a stable placement (each particle's rank among the lower
     indices of its cell), so `perm` is the CPU's stable counting sort bit for bit;
  3. the fluid lists by a row walk over the cells within reach (the CPU's rows and chord
     trimming), every hit ascending, then rotated to the CPU's row layout [neighbours above i,
     ascending | neighbours below, ascending];
  4. the wall lists from the walls' per-cell candidates.
The walls are sorted into the grid and given their per-cell candidates on the host, once
per grid (the CPU code: `NeighbourSearch._fit_grid`; moving walls every step, `_resort_walls`),
and copied to the device then. Only the
fluid's bounding box (a reduction) and the largest list length come back to the host each step.
"""

from __future__ import annotations

import math

import numpy as np

from ..backends._cuda import cuda, device_function
from ..backends.cuda_passes import launch, take_rows
from . import rows
from .search import NeighbourSearch

SCAN_CHUNK = 256


_cell_of = device_function(rows.cell_of)
_fluid_row = device_function(rows.fluid_row)
_wall_row = device_function(rows.wall_row)
_upper_first = device_function(rows.upper_first)


@cuda.jit(cache=True)
def _cell_ids(x, origin, inv_cell, dims, out):
    nx, ny = dims[0], dims[1]
    for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
        cx, cy, cz = _cell_of(x[i, 0], x[i, 1], x[i, 2], origin, inv_cell, dims)
        out[i] = (cz * ny + cy) * nx + cx


@cuda.jit(cache=True)
def _zero(a):
    for i in range(cuda.grid(1), a.shape[0], cuda.gridsize(1)):
        a[i] = 0


@cuda.jit(cache=True)
def _count(cells, counts):
    for i in range(cuda.grid(1), cells.shape[0], cuda.gridsize(1)):
        cuda.atomic.add(counts, cells[i], 1)


@cuda.jit(cache=True)
def _chunk_sums(a, chunk, sums):
    for t in range(cuda.grid(1), sums.shape[0], cuda.gridsize(1)):
        s = 0
        for i in range(t * chunk, min((t + 1) * chunk, a.shape[0])):
            s += a[i]
        sums[t] = s


@cuda.jit(cache=True)
def _chunk_scan(a, chunk, offsets, out):
    """out[i] = offsets[t] + sum of a over chunk t before i; out[n] = the total."""
    n = a.shape[0]
    for t in range(cuda.grid(1), offsets.shape[0] - 1, cuda.gridsize(1)):
        s = offsets[t]
        hi = min((t + 1) * chunk, n)
        for i in range(t * chunk, hi):
            out[i] = s
            s += a[i]
        if hi == n:
            out[n] = s


def exclusive_scan(a, out) -> None:
    """out[:n] = the exclusive prefix sums of a (n entries), out[n] = their total."""
    n = a.shape[0]
    m = max(1, math.ceil(n / SCAN_CHUNK))
    offsets = cuda.device_array(m + 1, dtype=np.int64)
    if m == 1:
        launch(_zero, 2, offsets)
    else:
        sums = cuda.device_array(m, dtype=np.int64)
        launch(_chunk_sums, m, a, SCAN_CHUNK, sums)
        exclusive_scan(sums, offsets)
    launch(_chunk_scan, m, a, SCAN_CHUNK, offsets, out)


@cuda.jit(cache=True)
def _scatter(cells, start, cursor, tmp):
    for i in range(cuda.grid(1), cells.shape[0], cuda.gridsize(1)):
        c = cells[i]
        tmp[start[c] + cuda.atomic.add(cursor, c, 1)] = i


@cuda.jit(cache=True)
def _place(cells, start, tmp, perm):
    """perm[start[c] + rank] = i, rank = how many of cell c's particles have a lower index: the
    stable order of the counting sort, whatever order the atomics scattered them in."""
    for i in range(cuda.grid(1), cells.shape[0], cuda.gridsize(1)):
        c = cells[i]
        rank = 0
        for k in range(start[c], start[c + 1]):
            rank += 1 if tmp[k] < i else 0
        perm[start[c] + rank] = i


@cuda.jit(cache=True)
def _gather_fluid(xs, cell_start, origin, inv_cell, dims, radius, idx, cnt):
    """The CPU's gather_neighbours(same_set=True, upper=True) then append_lower, in one full walk
    per thread: the row ascending, then rotated to [j > i ascending | j < i ascending]."""
    for i in range(cuda.grid(1), xs.shape[0], cuda.gridsize(1)):
        n = _fluid_row(i, xs, xs, cell_start, origin, inv_cell, dims, radius, True, False, False, idx)
        cnt[i] = n
        _upper_first(i, n, idx)


@cuda.jit(cache=True)
def _gather_walls(xq, xs, start, cand, origin, inv_cell, dims, radius, idx, cnt):
    """The CPU's gather_walls: each particle tests its own cell's wall candidates."""
    for i in range(cuda.grid(1), xq.shape[0], cuda.gridsize(1)):
        cnt[i] = _wall_row(i, xq, xs, start, cand, origin, inv_cell, dims, radius, False, idx)


class DeviceNeighbourLists:
    """`neighbours.NeighbourLists` with device arrays (the same names, strides and dtypes)."""

    __slots__ = ("fluid", "fluid_count", "boundary", "boundary_count")

    def __init__(self, n: int, k_fluid: int, k_boundary: int):
        self.fluid = cuda.device_array((n, k_fluid), dtype=np.int32)
        self.fluid_count = cuda.device_array(n, dtype=np.int32)
        self.boundary = cuda.device_array((n, k_boundary), dtype=np.int32)
        self.boundary_count = cuda.device_array(n, dtype=np.int32)

    @property
    def nbytes(self) -> int:
        return sum(int(getattr(self, s).nbytes) for s in self.__slots__)


class CUDANeighbourSearch(NeighbourSearch):
    """NeighbourSearch whose per-step sort and lists run on the device (`update(x)` takes and
    returns device arrays); the grid, the strides, the walls' sort and `state_dict` are the
    CPU class's."""

    def __init__(self, support: float, boundary, backend, k_fluid: int = 64, k_boundary: int = 48):
        super().__init__(support, boundary, k_fluid, k_boundary)
        self.be = backend
        self._dev = None  # the grid and the walls' candidates on the device
        self._scratch = None

    def _bounds(self, x):
        return self.be.reducer.bounds(x)

    def use_boundary_sort(self, boundary_start) -> None:
        super().use_boundary_sort(boundary_start)
        g = self.grid
        self._dev = {
            "origin": cuda.to_device(g.origin),
            "inv_cell": cuda.to_device(g.inv_cell),
            "dims": cuda.to_device(g.dims),
            "xb": cuda.to_device(self.boundary.x),
            "start": cuda.to_device(np.ascontiguousarray(self.wall_start, dtype=np.int64)),
            "cand": cuda.to_device(np.ascontiguousarray(self.wall_cand, dtype=np.int32)),
        }
        self._scratch = None

    def update(self, x_fluid):
        self._fit_grid(x_fluid)
        if getattr(self.boundary, "moving", False):
            self._resort_walls(x_fluid)  # on the host, as the CPU's; use_boundary_sort copies them here
        g, d = self.grid, self._dev
        n, n_cells = x_fluid.shape[0], g.n_cells
        if self._scratch is None or self._scratch["cells"].shape[0] != n:
            self._scratch = {
                "cells": cuda.device_array(n, dtype=np.int64),
                "tmp": cuda.device_array(n, dtype=np.int64),
                "counts": cuda.device_array(n_cells + 1, dtype=np.int32),
                "cursor": cuda.device_array(n_cells + 1, dtype=np.int32),
                "start": cuda.device_array(n_cells + 1, dtype=np.int64),
            }
        s = self._scratch
        perm = cuda.device_array(n, dtype=np.int64)  # handed to the caller: a fresh array
        launch(_cell_ids, n, x_fluid, d["origin"], d["inv_cell"], d["dims"], s["cells"])
        launch(_zero, n_cells + 1, s["counts"])
        launch(_zero, n_cells + 1, s["cursor"])
        launch(_count, n, s["cells"], s["counts"])
        exclusive_scan(s["counts"][:n_cells], s["start"])
        launch(_scatter, n, s["cells"], s["start"], s["cursor"], s["tmp"])
        launch(_place, n, s["cells"], s["start"], s["tmp"], perm)
        xs = cuda.device_array_like(x_fluid)
        launch(take_rows, n, x_fluid, perm, xs)
        self._build(xs, s["start"])
        return perm

    def _new_lists(self, n: int) -> DeviceNeighbourLists:
        return DeviceNeighbourLists(n, self.k_fluid, self.k_boundary)

    def _gather(self, xs, fluid_start, nl) -> tuple[int, int]:
        d, n = self._dev, xs.shape[0]
        launch(
            _gather_fluid, n, xs, fluid_start, d["origin"], d["inv_cell"], d["dims"], self.h, nl.fluid, nl.fluid_count
        )
        launch(
            _gather_walls,
            n,
            xs,
            d["xb"],
            d["start"],
            d["cand"],
            d["origin"],
            d["inv_cell"],
            d["dims"],
            self.h,
            nl.boundary,
            nl.boundary_count,
        )
        most_f = int(self.be.reducer.max(nl.fluid_count)) if n else 0
        most_b = int(self.be.reducer.max(nl.boundary_count)) if n else 0
        return most_f, most_b
