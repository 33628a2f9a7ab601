"""Neighbour search: uniform cell grid, counting sort by cell, fixed-stride neighbour lists.

    rows.py     the per-particle bodies, written once: the cell of a point, the row walk, the wall
                gather, the stride growth rule
    cpu.py      the CPU kernels: binning, counting sort, `prange` launchers of the rows, the walls'
                per-cell candidates
    search.py   NeighbourSearch: the grid, the sorts, the lists (CPU), state_dict; the brute-force oracle
    cuda.py     CUDANeighbourSearch: the same lists built on the device by the same rows

`search_for(backend, support, boundary)` gives the search a backend's arrays need.
"""

from .cpu import append_lower, bounds, cell_ids, counting_sort, counting_sort_into, gather_neighbours, gather_walls
from .search import CELL_SHAPE, Grid, NeighbourLists, NeighbourSearch, brute_force_neighbours, wall_candidates

__all__ = [
    "CELL_SHAPE",
    "Grid",
    "NeighbourLists",
    "NeighbourSearch",
    "append_lower",
    "bounds",
    "brute_force_neighbours",
    "cell_ids",
    "counting_sort",
    "counting_sort_into",
    "gather_neighbours",
    "gather_walls",
    "search_for",
    "wall_candidates",
]


def search_for(backend, support: float, boundary) -> NeighbourSearch:
    """The neighbour search for `backend`'s arrays: the CPU's, or the device's (imported only then)."""
    if backend.name == "cuda":
        from .cuda import CUDANeighbourSearch

        return CUDANeighbourSearch(support, boundary, backend)
    return NeighbourSearch(support, boundary)
