"""The CPU kernels of the neighbour search (numba): cell binning, the counting sort by cell
(a prefix sum over cells: the layout a device search shares), the launchers of the row walk and
the wall gather (`rows`: the per-particle bodies, shared with `neighbours.cuda`), the walls'
per-cell candidates. `neighbours.search.NeighbourSearch` drives them.
"""

import numpy as np
from numba import njit, prange

from .rows import cell_of as _cell_of
from .rows import fluid_row, wall_row


@njit(cache=True)
def cell_ids(x, origin, inv_cell, dims, out):
    """Linear cell index (x fastest) of every point; points outside are clamped to the edge.
    `inv_cell`: 1 / cell size per axis."""
    nx, ny = dims[0], dims[1]
    for i in range(x.shape[0]):
        cx, cy, cz = _cell_of(x[i, 0], x[i, 1], x[i, 2], origin, inv_cell, dims)
        out[i] = (cz * ny + cy) * nx + cx


@njit(cache=True)
def bounds(x):
    """(lo, hi) corners of the points' bounding box; NaN in both if any coordinate is not finite.

    One pass instead of numpy's axis-0 min and max (two passes, each slower: docs/performance.md).
    """
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(x.shape[0]):
        for c in range(3):
            v = x[i, c]
            if not np.isfinite(v):
                lo[:] = np.nan
                hi[:] = np.nan
                return lo, hi
            lo[c] = min(lo[c], v)
            hi[c] = max(hi[c], v)
    return lo, hi


@njit(cache=True)
def counting_sort_into(cells, n_cells, order, cell_start):
    """Stable counting sort: `order` lists point indices by cell; `cell_start` (n_cells + 2
    entries, kept by the caller) becomes the CSR offsets: cell c holds order[cell_start[c]:
    cell_start[c + 1]]. Counts go one slot ahead, so after the prefix sum cell_start[c + 1] is
    cell c's start and serves as its fill cursor, ending at its end: no separate cursor array
    (faster than with one: docs/performance.md).
    """
    cell_start[:] = 0
    for i in range(cells.shape[0]):
        cell_start[cells[i] + 2] += 1
    for c in range(n_cells):
        cell_start[c + 2] += cell_start[c + 1]
    for i in range(cells.shape[0]):
        c = cells[i]
        order[cell_start[c + 1]] = i
        cell_start[c + 1] += 1


def counting_sort(cells, n_cells: int, order) -> np.ndarray:
    """counting_sort_into with a fresh offsets array, which it returns."""
    cell_start = np.empty(n_cells + 2, dtype=np.int64)
    counting_sort_into(cells, n_cells, order, cell_start)
    return cell_start


@njit(inline="always")
def _largest(cnt):
    """The largest list length, so the caller can see a stride overflow and rebuild."""
    best = 0
    for i in range(cnt.shape[0]):
        best = max(best, cnt[i])
    return best


@njit(parallel=True, cache=True)
def gather_neighbours(xq, xs, cell_start, origin, inv_cell, dims, radius, same_set, upper, idx, cnt):
    """For each query point i, the indices j of points xs with |xq_i - xs_j| < radius
    (`rows.fluid_row`; with `upper`, j > i only: see `append_lower`). Static walls use
    `gather_walls` instead. Writes the first K = idx.shape[1] indices and the true count; returns
    the largest count so the caller can detect an overflow.
    """
    for i in prange(xq.shape[0]):
        cnt[i] = fluid_row(i, xq, xs, cell_start, origin, inv_cell, dims, radius, same_set, upper, True, idx)
    return _largest(cnt)


@njit(cache=True)
def near_cells(cell_start, dims, reach):
    """One flag per cell: 1 where a cell holding points (cell_start's CSR) lies within `reach`
    cells per axis, i.e. every cell whose row walk in gather_neighbours can meet a point."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    near = np.zeros(nx * ny * nz, dtype=np.uint8)
    for z in range(nz):
        for y in range(ny):
            row = (z * ny + y) * nx
            for x in range(nx):
                if cell_start[row + x + 1] == cell_start[row + x]:
                    continue
                for zz in range(max(z - reach[2], 0), min(z + reach[2], nz - 1) + 1):
                    for yy in range(max(y - reach[1], 0), min(y + reach[1], ny - 1) + 1):
                        r2 = (zz * ny + yy) * nx
                        for xx in range(max(x - reach[0], 0), min(x + reach[0], nx - 1) + 1):
                            near[r2 + xx] = 1
    return near


CANDIDATE_PAD = 1e-7  # relative: wall candidates within (1 + pad) H of a cell's box


@njit(parallel=True, cache=True)
def _wall_candidate_pass(xs, cell_start, origin, cell, dims, reach, radius, near, start, out):
    """Count (out empty) or write (into out[start[c]:]) the points of xs within `radius` of each
    near cell's closed box, in ascending index order (rows of cells ascending, as xs is sorted)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    # padded: a query point binned into cell c by rounding may lie a few ulps outside its box
    r2 = (radius * (1.0 + CANDIDATE_PAD)) ** 2
    for c in prange(nx * ny * nz):
        if not near[c]:
            continue
        cx = c % nx
        cy = (c // nx) % ny
        cz = c // (nx * ny)
        lo0, lo1, lo2 = origin[0] + cx * cell[0], origin[1] + cy * cell[1], origin[2] + cz * cell[2]
        hi0, hi1, hi2 = lo0 + cell[0], lo1 + cell[1], lo2 + cell[2]
        n = 0
        for z in range(max(cz - reach[2], 0), min(cz + reach[2], nz - 1) + 1):
            for y in range(max(cy - reach[1], 0), min(cy + reach[1], ny - 1) + 1):
                row = (z * ny + y) * nx
                x_lo = max(cx - reach[0], 0)
                x_hi = min(cx + reach[0], nx - 1)
                for j in range(cell_start[row + x_lo], cell_start[row + x_hi + 1]):
                    d0 = max(lo0 - xs[j, 0], xs[j, 0] - hi0, 0.0)
                    d1 = max(lo1 - xs[j, 1], xs[j, 1] - hi1, 0.0)
                    d2 = max(lo2 - xs[j, 2], xs[j, 2] - hi2, 0.0)
                    if d0 * d0 + d1 * d1 + d2 * d2 < r2:
                        if out.shape[0] > 0:
                            out[start[c] + n] = j
                        n += 1
        if out.shape[0] == 0:
            start[c + 1] = n


@njit(parallel=True, cache=True)
def gather_walls(xq, xs, start, cand, origin, inv_cell, dims, radius, idx, cnt):
    """gather_neighbours for static walls from their per-cell candidates (`rows.wall_row`)."""
    for i in prange(xq.shape[0]):
        cnt[i] = wall_row(i, xq, xs, start, cand, origin, inv_cell, dims, radius, True, idx)
    return _largest(cnt)


@njit(cache=True)
def append_lower(idx, cnt):
    """Complete upper-half lists (j > i, from gather_neighbours(upper=True)) to full lists.

    Appends i to the row of each of its upper neighbours j, serially in ascending i, so every
    row reads [its neighbours above, ascending | its neighbours below, ascending] whatever the
    thread count. `cnt` becomes the full counts; returns the largest (rows past the stride
    are cut, so the caller can grow the stride and rebuild).
    """
    k_max = idx.shape[1]
    n_upper = cnt.copy()
    for i in range(cnt.shape[0]):
        for k in range(min(n_upper[i], k_max)):
            j = idx[i, k]
            c = cnt[j]
            idx[j, min(c, k_max - 1)] = i
            cnt[j] = c + 1
    return _largest(cnt)
