"""Static boundaries as Akinci et al. 2012 particles: the one boundary interface.

Every solver pass sees the walls only as a list of neighbours b with a position x_b and an
effective mass rho0 * Psi_b, where the volume

    Psi_b = 1 / (W(0) + sum_{b'} W(x_b - x_b'))          [AIA*12, eq. 4]

is computed once (the walls never move). No method branches on the boundary: a scene
without walls simply has zero boundary particles.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from .kernels import w
from .neighbours import Grid, cell_ids, counting_sort, gather_neighbours


@njit(parallel=True, cache=True)
def akinci_volumes(xb, nbr, cnt, h, psi):
    """Psi_b = 1 / (W(0) + sum_b' W_bb') for every boundary particle b."""
    w0 = w(0.0, h)
    for b in prange(xb.shape[0]):
        s = w0
        for k in range(cnt[b]):
            j = nbr[b, k]
            d0 = xb[b, 0] - xb[j, 0]
            d1 = xb[b, 1] - xb[j, 1]
            d2 = xb[b, 2] - xb[j, 2]
            s += w(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
        psi[b] = 1.0 / s


class Boundary:
    """Boundary particles: positions `x`, Akinci volumes `psi` and masses `m = rho0 * psi`."""

    def __init__(self, x: np.ndarray, support: float, rho0: float):
        self.x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1, 3)
        self.h = float(support)
        self.rho0 = float(rho0)
        self.psi = self._volumes()
        self.m = self.rho0 * self.psi

    @property
    def n(self) -> int:
        return len(self.x)

    def _volumes(self) -> np.ndarray:
        n = len(self.x)
        psi = np.zeros(n)
        if n == 0:
            return psi
        grid = Grid.for_support(self.x.min(axis=0), self.x.max(axis=0), self.h)
        cells = np.empty(n, dtype=np.int64)
        cell_ids(self.x, grid.origin, grid.inv_cell, grid.dims, cells)
        order = np.empty(n, dtype=np.int64)
        start = counting_sort(cells, grid.n_cells, order)
        xs = np.ascontiguousarray(self.x[order])
        k = 64
        while True:
            nbr = np.zeros((n, k), dtype=np.int32)
            cnt = np.zeros(n, dtype=np.int32)
            most = gather_neighbours(xs, xs, start, grid.origin, grid.inv_cell, grid.dims, self.h, True, False,
                                     nbr, cnt)
            if most <= k:
                break
            k = int(most + 16)
        psi_sorted = np.zeros(n)
        akinci_volumes(xs, nbr, cnt, self.h, psi_sorted)
        psi[order] = psi_sorted
        return psi

    def state_dict(self) -> dict[str, np.ndarray]:
        """Positions, volumes and masses in their current (cell-sorted) order: the volumes were
        summed in the original order, so a continuation takes them as they are."""
        return {"x": self.x.copy(), "psi": self.psi.copy(), "m": self.m.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        if len(d["x"]) != len(self.x):
            raise ValueError(f"saved boundary has {len(d['x'])} particles, this scene {len(self.x)}")
        self.x = np.ascontiguousarray(d["x"], dtype=np.float64)
        self.psi = np.ascontiguousarray(d["psi"], dtype=np.float64)
        self.m = np.ascontiguousarray(d["m"], dtype=np.float64)

    def reorder(self, order: np.ndarray) -> None:
        """Follow the neighbour search's boundary sort (new[i] = old[order[i]])."""
        self.x = np.ascontiguousarray(self.x[order])
        self.psi = np.ascontiguousarray(self.psi[order])
        self.m = np.ascontiguousarray(self.m[order])
