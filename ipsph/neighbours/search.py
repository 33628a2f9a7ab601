"""The neighbour search's driver: uniform cell grid, counting sort by cell, fixed-stride neighbour lists.

Particles are binned into cells of H/4 x H x H (H the kernel support), sorted by cell with a
stable counting sort (so the state arrays can be reordered for memory locality), and every
query particle gathers the candidates of the cells its support sphere touches. Cells are
numbered x-fastest, so a row of cells is one contiguous range of the sorted arrays: one
range per (y, z) row, trimmed to the sphere's chord at H/4 resolution.

Static walls need no walk at each step: once per grid, every cell near a wall gets the list of
wall particles within H of its box (`wall_candidates`, ascending), and a fluid particle tests
its cell's candidates only (`gather_walls`): the same lists as the row walk, at a third of its
time on the stock scenes.

The lists are stored with a fixed stride K per particle (`idx[i, :cnt[i]]`), which keeps
every later pass a plain gather (`prange` over i, writes to i only). When a particle has
more than K neighbours the build reports it and the caller grows K and rebuilds.

`brute_force_neighbours` is the O(N M) oracle the tests compare against.
"""

from __future__ import annotations

import numpy as np

from ..errors import NumericalFailure
from .cpu import (
    _wall_candidate_pass,
    append_lower,
    bounds,
    cell_ids,
    counting_sort,
    counting_sort_into,
    gather_neighbours,
    gather_walls,
    near_cells,
)
from .rows import grown_stride

# Cell size per axis, in units of the support H. Short cells along x (the axis along which a
# row of cells is contiguous in memory) cut each row's candidate range close to the sphere's
# chord without adding rows (docs/performance.md, "Measured design choices").
CELL_SHAPE = (0.25, 1.0, 1.0)


class Grid:
    """A uniform grid of box cells (`cell`: one size or one per axis) covering [lo, hi], padded by one cell."""

    __slots__ = ("origin", "cell", "dims")

    def __init__(self, lo, hi, cell):
        cell = np.broadcast_to(np.asarray(cell, dtype=np.float64), (3,)).copy()
        lo = np.asarray(lo, dtype=np.float64) - cell
        hi = np.asarray(hi, dtype=np.float64) + cell
        self.cell = cell
        self.origin = lo
        self.dims = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)

    @classmethod
    def from_arrays(cls, origin, cell, dims) -> "Grid":
        """The grid with exactly these origin, cell sizes and cell counts (a saved state)."""
        g = cls.__new__(cls)
        g.origin = np.ascontiguousarray(origin, dtype=np.float64)
        g.cell = np.ascontiguousarray(cell, dtype=np.float64)
        g.dims = np.ascontiguousarray(dims, dtype=np.int64)
        return g

    @classmethod
    def for_support(cls, lo, hi, support: float) -> "Grid":
        return cls(lo, hi, support * np.asarray(CELL_SHAPE))

    @property
    def inv_cell(self) -> np.ndarray:
        return 1.0 / self.cell

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.dims))

    def contains(self, lo, hi) -> bool:
        top = self.origin + self.dims * self.cell
        return bool(np.all(lo >= self.origin) and np.all(hi < top))


def wall_candidates(xs, cell_start, grid: "Grid", radius: float, near) -> tuple[np.ndarray, np.ndarray]:
    """Static walls: for every cell (CSR `start`, `cand`), the wall points within `radius` of the
    cell's box, ascending. A query point in the cell finds all its wall neighbours among them, in
    the order the row walk would (so the lists are identical), without the walk."""
    reach = np.ceil(radius * grid.inv_cell).astype(np.int64)
    start = np.zeros(grid.n_cells + 1, dtype=np.int64)
    none = np.zeros(0, dtype=np.int32)
    _wall_candidate_pass(xs, cell_start, grid.origin, grid.cell, grid.dims, reach, radius, near, start, none)
    np.cumsum(start, out=start)
    cand = np.empty(int(start[-1]), dtype=np.int32)
    if len(cand):
        _wall_candidate_pass(xs, cell_start, grid.origin, grid.cell, grid.dims, reach, radius, near, start, cand)
    if start[-1] < 2**31:  # half the memory of the offsets (8 B per cell, ~13 cells per particle)
        start = start.astype(np.int32)
    return start, cand


def brute_force_neighbours(xq, xs, radius, same_set):
    """O(N M) oracle: sorted index lists of points within `radius` (strict)."""
    out = []
    for i in range(len(xq)):
        d2 = np.sum((xs - xq[i]) ** 2, axis=1)
        j = np.nonzero(d2 < radius * radius)[0]
        if same_set:
            j = j[j != i]
        out.append(np.sort(j))
    return out


class NeighbourLists:
    """Fluid->fluid and fluid->boundary lists in fixed-stride form (indices into sorted arrays)."""

    __slots__ = ("fluid", "fluid_count", "boundary", "boundary_count")

    def __init__(self, n: int, k_fluid: int, k_boundary: int):
        self.fluid = np.zeros((n, k_fluid), dtype=np.int32)
        self.fluid_count = np.zeros(n, dtype=np.int32)
        self.boundary = np.zeros((n, k_boundary), dtype=np.int32)
        self.boundary_count = np.zeros(n, dtype=np.int32)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, s).nbytes for s in self.__slots__)


class NeighbourSearch:
    """Owns the grid, the cell sort, the walls' per-cell candidates and the lists; `update` sorts
    the fluid and rebuilds the lists.

    Static walls are sorted into the grid once (and again only if the grid has to grow because
    fluid left it), in place through `boundary.reorder`; with moving walls (`boundary.moving`)
    they are sorted again at every `update` (`_resort_walls`). `update` returns the permutation to
    apply to the fluid, so the caller reorders every per-particle array with it.
    """

    # Cells beyond this many per particle mean the fluid blew apart (a runaway particle).
    MAX_CELLS_PER_PARTICLE = 256

    def __init__(self, support: float, boundary, k_fluid: int = 64, k_boundary: int = 48):
        self.h = float(support)
        self.boundary = boundary  # has `.x` and `.reorder(order)`; resorted here when the grid changes
        self.k_fluid = k_fluid
        self.k_boundary = k_boundary if boundary.n else 0  # no wall particles (field walls): no wall lists
        self.grid: Grid | None = None
        self.wall_start = self.wall_cand = None  # per-cell wall candidates (wall_candidates)
        self.lists: NeighbourLists | None = None
        self._sort = None  # (cells, fluid_start) scratch of `update`

    # -- grid ---------------------------------------------------------------------------------
    def _bounds(self, x_fluid):
        """(lo, hi) of the fluid, NaN if a coordinate is not finite (a device search reduces on the device)."""
        return bounds(x_fluid)

    def _fit_grid(self, x_fluid: np.ndarray) -> None:
        """Make sure the grid covers fluid and boundary; resort the boundary if the grid changed."""
        lo, hi = self._bounds(x_fluid) if len(x_fluid) else (np.zeros(3), np.zeros(3))
        if self.grid is not None and self.grid.contains(lo, hi):
            return
        xb = self.boundary.x
        if len(xb):
            lo = np.minimum(lo, xb.min(axis=0))
            hi = np.maximum(hi, xb.max(axis=0))
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise NumericalFailure("neighbour search: non-finite particle position")
        grid = Grid.for_support(lo, hi, self.h)
        limit = self.MAX_CELLS_PER_PARTICLE * (len(x_fluid) + len(xb)) + 1_000_000
        if grid.n_cells > limit:
            ext = hi - lo
            raise NumericalFailure(
                f"neighbour search: the particles spread over {ext[0]:.3g} x {ext[1]:.3g} x {ext[2]:.3g} m "
                f"({grid.n_cells:.3g} cells); a particle has run away"
            )
        self.grid = grid
        self._sort_walls()

    def use_boundary_sort(self, boundary_start: np.ndarray) -> None:
        """Given the walls' cell offsets in the current grid, list each cell's wall candidates
        (`wall_candidates`): the walls are static, so this happens once per grid, and a fluid
        particle out of every wall's reach finds an empty range (in a deep or spread-out scene
        most of them). Neither the offsets nor the near-cell flags are kept."""
        g = self.grid
        reach = np.ceil(self.h * g.inv_cell).astype(np.int64)  # as gather_neighbours' row walk
        near = near_cells(boundary_start, g.dims, reach)
        self.wall_start, self.wall_cand = wall_candidates(self.boundary.x, boundary_start, g, self.h, near)

    def _resort_walls(self, x_fluid) -> None:
        """Moving walls: sort the walls into the grid again at their new positions (refitting the
        grid if they left it) and rebuild the per-cell candidates. Every step, so its cost is the
        price of a moving wall (`python -m benchmarks moving-walls`)."""
        xb = self.boundary.x
        lo, hi = bounds(xb) if len(xb) else (np.zeros(3), np.zeros(3))
        if not self.grid.contains(lo, hi):
            self.grid = None
            self._fit_grid(x_fluid)  # a grid over fluid and walls, the walls sorted into it
            return
        self._sort_walls()

    def _sort_walls(self) -> None:
        """Sort the walls into the current grid (stable, deterministic) and list each cell's wall
        candidates."""
        xb, g = self.boundary.x, self.grid
        cells = np.empty(len(xb), dtype=np.int64)
        cell_ids(xb, g.origin, g.inv_cell, g.dims, cells)
        order = np.empty(len(xb), dtype=np.int64)
        start = counting_sort(cells, g.n_cells, order)
        self.boundary.reorder(order)
        self.use_boundary_sort(start)

    # -- state ------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """What a continuation needs to see the same neighbour order: the grid and the strides
        (the lists are rebuilt by the next `update`; the walls' order is the boundary's)."""
        g = self.grid
        return {
            "k_fluid": int(self.k_fluid),
            "k_boundary": int(self.k_boundary),
            "grid": None if g is None else {"origin": g.origin.copy(), "cell": g.cell.copy(), "dims": g.dims.copy()},
        }

    def load_state_dict(self, d: dict) -> None:
        """Put the grid and strides back, before any `update`. The boundary must already be in
        the saved order (`Boundary.load_state_dict`): it is sorted into that grid, so its stable
        sort is the identity; ValueError if it is not."""
        self.k_fluid, self.k_boundary = int(d["k_fluid"]), int(d["k_boundary"])
        self.lists = None
        self._sort = None
        if d["grid"] is None:
            self.grid = None
            self.wall_start = self.wall_cand = None
            return
        g = self.grid = Grid.from_arrays(**d["grid"])
        xb = self.boundary.x
        cells = np.empty(len(xb), dtype=np.int64)
        cell_ids(xb, g.origin, g.inv_cell, g.dims, cells)
        order = np.empty(len(xb), dtype=np.int64)
        start = counting_sort(cells, g.n_cells, order)
        if not np.array_equal(order, np.arange(len(xb))):
            raise ValueError("the boundary is not sorted into the saved grid")
        self.use_boundary_sort(start)

    # -- public -------------------------------------------------------------------------------
    def update(self, x_fluid: np.ndarray) -> np.ndarray:
        """Sort the fluid by cell and rebuild both lists at `x_fluid`.

        Returns `perm`: the caller must apply it to every fluid array (the lists index the
        permuted order: new[i] = old[perm[i]]).
        """
        self._fit_grid(x_fluid)
        if getattr(self.boundary, "moving", False):
            self._resort_walls(x_fluid)
        g = self.grid
        n = len(x_fluid)
        if self._sort is None or len(self._sort[0]) != n or len(self._sort[1]) != g.n_cells + 2:
            # per-step scratch, kept: the cell offsets are 8 bytes per cell (~13 cells per particle)
            self._sort = (np.empty(n, dtype=np.int64), np.empty(g.n_cells + 2, dtype=np.int64))
        cells, fluid_start = self._sort
        perm = np.empty(n, dtype=np.int64)  # handed to the caller: a fresh array
        cell_ids(x_fluid, g.origin, g.inv_cell, g.dims, cells)
        counting_sort_into(cells, g.n_cells, perm, fluid_start)
        xs = np.take(x_fluid, perm, axis=0)
        self._build(xs, fluid_start)
        return perm

    def _build(self, xs, fluid_start):
        """Both lists at the sorted positions `xs`, growing the strides until every row fits."""
        n = xs.shape[0]
        while True:
            nl = self.lists
            if nl is None or nl.fluid.shape != (n, self.k_fluid) or nl.boundary.shape != (n, self.k_boundary):
                self.lists = self._new_lists(n)
            most_f, most_b = self._gather(xs, fluid_start, self.lists)
            if most_f <= self.k_fluid and most_b <= self.k_boundary:
                return
            # grow the stride and rebuild; rare
            self.k_fluid = grown_stride(self.k_fluid, most_f)
            self.k_boundary = grown_stride(self.k_boundary, most_b)

    def _new_lists(self, n: int) -> NeighbourLists:
        return NeighbourLists(n, self.k_fluid, self.k_boundary)

    def _gather(self, xs, fluid_start, lists) -> tuple[int, int]:
        """Fill both lists; returns the longest fluid and wall rows (the true counts)."""
        g = self.grid
        # fluid pairs are symmetric: gather j > i in parallel, then append each pair to the
        # lower particle's row serially (cheaper than a full gather: docs/performance.md)
        gather_neighbours(
            xs, xs, fluid_start, g.origin, g.inv_cell, g.dims, self.h, True, True, lists.fluid, lists.fluid_count
        )
        most_f = append_lower(lists.fluid, lists.fluid_count)
        most_b = gather_walls(
            xs,
            self.boundary.x,
            self.wall_start,
            self.wall_cand,
            g.origin,
            g.inv_cell,
            g.dims,
            self.h,
            lists.boundary,
            lists.boundary_count,
        )
        return most_f, most_b
