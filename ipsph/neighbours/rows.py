"""The neighbour search's per-particle bodies, written once: the cell of a point, the row walk
that gathers one particle's fluid neighbours, the gather of its walls from its cell's candidates,
and the stride growth rule.

As `backends/bodies.py` does for the physics, each body is a plain function of one query
particle i over arrays and scalars that writes row i of its output only. The CPU launchers
(`neighbours.cpu`: `prange` over i) inline them; the CUDA launchers (`neighbours.cuda`: one thread
per particle) compile the same functions as device functions. Scalar maths goes through `math`
(`np.sqrt` of a scalar does not compile for CUDA).

`branch_free`: always store the candidate at the row's next slot and advance only on a hit (on
the CPU candidates fail about 3 times in 4, so a branch there mispredicts a lot; `and` would be a
branch too, hence the bitwise & on the comparisons); else store hits only (fewer memory writes, on
a GPU). Both give the same row.
"""

import math

from numba import njit

STRIDE_QUANTUM = 16  # list strides grow to a multiple of this
STRIDE_HEADROOM = 1.25  # ... with this much room over the longest list seen


def grown_stride(k: int, most: int) -> int:
    """The list stride after a build found `most` neighbours for a particle and the stride was `k`:
    the one growth rule of every neighbour search (rare; the caller rebuilds)."""
    return max(k, int(math.ceil(most * STRIDE_HEADROOM / STRIDE_QUANTUM) * STRIDE_QUANTUM))


@njit(inline="always")
def cell_of(p0, p1, p2, origin, inv_cell, dims):
    """The cell (cx, cy, cz) of a point, clamped to the grid: the one binning rule that the sort,
    the row walk and the walls' per-cell candidates all share."""
    cx = min(max(int((p0 - origin[0]) * inv_cell[0]), 0), dims[0] - 1)
    cy = min(max(int((p1 - origin[1]) * inv_cell[1]), 0), dims[1] - 1)
    cz = min(max(int((p2 - origin[2]) * inv_cell[2]), 0), dims[2] - 1)
    return cx, cy, cz


@njit(inline="always")
def append(idx, i, n, j, hit, k_max, branch_free):
    """Row i's next candidate j: kept when `hit`; returns the new count. Branch-free: always store
    at slot n (the last slot once the row is full), advance only on a hit."""
    if branch_free:
        idx[i, min(n, k_max - 1)] = j
        return n + (1 if hit else 0)
    if hit:
        if n < k_max:
            idx[i, n] = j
        return n + 1
    return n


@njit(inline="always")
def fluid_row(i, xq, xs, cell_start, origin, inv_cell, dims, radius, same_set, upper, branch_free, idx):
    """The indices j of points xs with |xq_i - xs_j| < radius into idx[i, :K], ascending; returns
    their true count (rows past the stride K are cut: the caller grows K and rebuilds).

    `xs` is sorted by cell with `cell_start` its CSR offsets. Rows of cells (fixed y, z) that lie
    entirely outside the sphere are skipped and each remaining row is trimmed to the x-extent of
    the sphere's chord, so fewer candidates fall outside the sphere. With `same_set` (xq is xs), i
    itself is skipped; with `upper` too, only j > i are gathered (the rows after i's row, and i's
    own row after i: half the rows and candidates; `cpu.append_lower` completes them).
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    k_max = idx.shape[1]
    r2 = radius * radius
    cell_y, cell_z = 1.0 / inv_cell[1], 1.0 / inv_cell[2]
    reach_y = int(math.ceil(radius * inv_cell[1]))
    reach_z = int(math.ceil(radius * inv_cell[2]))
    xi0 = xq[i, 0]
    xi1 = xq[i, 1]
    xi2 = xq[i, 2]
    _, cy, cz = cell_of(xi0, xi1, xi2, origin, inv_cell, dims)
    n = 0
    for z in range(cz if upper else max(cz - reach_z, 0), min(cz + reach_z, nz - 1) + 1):
        z_lo = origin[2] + z * cell_z
        dz = max(z_lo - xi2, xi2 - (z_lo + cell_z), 0.0)
        for y in range(cy if upper and z == cz else max(cy - reach_y, 0), min(cy + reach_y, ny - 1) + 1):
            y_lo = origin[1] + y * cell_y
            dy = max(y_lo - xi1, xi1 - (y_lo + cell_y), 0.0)
            rest = r2 - dy * dy - dz * dz
            if rest <= 0.0:
                continue
            half = math.sqrt(rest)
            x_lo = min(max(int((xi0 - half - origin[0]) * inv_cell[0]), 0), nx - 1)
            x_hi = min(max(int((xi0 + half - origin[0]) * inv_cell[0]), 0), nx - 1)
            row = (z * ny + y) * nx
            first = cell_start[row + x_lo]
            if upper and z == cz and y == cy:
                first = max(first, i + 1)
            for j in range(first, cell_start[row + x_hi + 1]):
                d0 = xi0 - xs[j, 0]
                d1 = xi1 - xs[j, 1]
                d2 = xi2 - xs[j, 2]
                hit = d0 * d0 + d1 * d1 + d2 * d2 < r2
                if same_set:
                    hit = hit & (j != i)
                n = append(idx, i, n, j, hit, k_max, branch_free)
    return n


@njit(inline="always")
def wall_row(i, xq, xs, start, cand, origin, inv_cell, dims, radius, branch_free, idx):
    """fluid_row for static walls from their per-cell candidates (`search.wall_candidates`): the
    same row, one contiguous candidate range per query point instead of a row walk."""
    nx, ny = dims[0], dims[1]
    k_max = idx.shape[1]
    r2 = radius * radius
    xi0 = xq[i, 0]
    xi1 = xq[i, 1]
    xi2 = xq[i, 2]
    cx, cy, cz = cell_of(xi0, xi1, xi2, origin, inv_cell, dims)
    c = (cz * ny + cy) * nx + cx
    n = 0
    for k in range(start[c], start[c + 1]):
        j = cand[k]
        d0 = xi0 - xs[j, 0]
        d1 = xi1 - xs[j, 1]
        d2 = xi2 - xs[j, 2]
        n = append(idx, i, n, j, d0 * d0 + d1 * d1 + d2 * d2 < r2, k_max, branch_free)
    return n


@njit(inline="always")
def reverse_row(idx, i, lo, hi):
    """Reverse idx[i, lo:hi] in place."""
    hi -= 1
    while lo < hi:
        t = idx[i, lo]
        idx[i, lo] = idx[i, hi]
        idx[i, hi] = t
        lo += 1
        hi -= 1


@njit(inline="always")
def upper_first(i, n, idx):
    """A full ascending row of i's n neighbours ([j < i | j > i]) rotated to the layout the CPU's
    half walk + `append_lower` gives, [j > i ascending | j < i ascending]: three reversals. A row
    cut at the stride is left as it is (the caller rebuilds)."""
    if n > idx.shape[1]:
        return
    n_lower = 0
    while n_lower < n and idx[i, n_lower] < i:
        n_lower += 1
    if 0 < n_lower < n:
        reverse_row(idx, i, 0, n_lower)
        reverse_row(idx, i, n_lower, n)
        reverse_row(idx, i, 0, n)
