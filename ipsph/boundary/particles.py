"""Static boundaries as Akinci et al. 2012 particles: the one boundary interface.

Every solver pass sees the walls only as a list of neighbours b with a position x_b and an
effective mass rho0 * Psi_b, where the volume

    Psi_b = 1 / (W(0) + sum_{b'} W(x_b - x_b'))          [AIA*12, eq. 4]

is computed once. No method branches on the boundary: a scene without walls simply has zero
boundary particles. Walls may move rigidly (kinematic walls, rigid bodies: ipsph.boundary.rigid): each
moving wall is its own `group`, whose volumes are summed over its own particles only, so they
are invariant under its motion (a wall sliding past another does not change either's volumes);
its particles carry velocities `v` (zero for static walls), which the density rate sees.

Given the scene's rest lattice (`sampling.rest_lattice`: the fluid's lattice continued over the
free space near the walls), the Akinci volumes are then corrected so that fluid at rest reads
rho0 next to walls too, along edges and in corners included (`fit_volumes`, method.md section 1).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..backends.kernels import w
from ..neighbours import Grid, cell_ids, counting_sort, gather_neighbours


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


@njit(parallel=True, cache=True)
def kernel_rows(xq, xs, nbr, cnt, h, out):
    """out[i, k] = W(|xq_i - xs_nbr[i, k]|): the rows of a sparse kernel matrix."""
    for i in prange(xq.shape[0]):
        for k in range(cnt[i]):
            j = nbr[i, k]
            d0 = xq[i, 0] - xs[j, 0]
            d1 = xq[i, 1] - xs[j, 1]
            d2 = xq[i, 2] - xs[j, 2]
            out[i, k] = w(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)


@njit(parallel=True, cache=True)
def _rows_dot(nbr, cnt, a, v, out):
    """out = A v for the sparse rows (nbr, cnt, a)."""
    for i in prange(nbr.shape[0]):
        s = 0.0
        for k in range(cnt[i]):
            s += a[i, k] * v[nbr[i, k]]
        out[i] = s


@njit(cache=True)
def _dot(a, b):
    """Serial dot product (a fixed summation order, unlike a threaded BLAS)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s


@njit(cache=True)
def _rows_tdot(nbr, cnt, a, y, out):
    """out = A^T y (serial scatter: a fixed summation order, so the fit is reproducible)."""
    out[:] = 0.0
    for i in range(nbr.shape[0]):
        for k in range(cnt[i]):
            out[nbr[i, k]] += a[i, k] * y[i]


def radius_lists(xq: np.ndarray, points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(order, nbr, cnt): for each query i, the indices into points[order] closer than radius."""
    n = len(points)
    lo = np.minimum(points.min(axis=0), xq.min(axis=0))
    hi = np.maximum(points.max(axis=0), xq.max(axis=0))
    grid = Grid.for_support(lo, hi, radius)
    cells = np.empty(n, dtype=np.int64)
    cell_ids(points, grid.origin, grid.inv_cell, grid.dims, cells)
    order = np.empty(n, dtype=np.int64)
    start = counting_sort(cells, grid.n_cells, order)
    xs = np.ascontiguousarray(points[order])
    same = xq is points
    k = 64
    while True:
        nbr = np.zeros((len(xq), k), dtype=np.int32)
        cnt = np.zeros(len(xq), dtype=np.int32)
        most = gather_neighbours(
            xs if same else xq, xs, start, grid.origin, grid.inv_cell, grid.dims, radius, same, False, nbr, cnt
        )
        if most <= k:
            return order, nbr, cnt
        k = int(most + 16)


# Regularisation of the wall-volume fit, relative to the mean diagonal of A^T A: small enough that
# the rest lattice reads rho0 to ~1e-4 next to walls, large enough that wall particles the lattice
# barely sees keep their Akinci volume (method.md section 1).
FIT_REGULARISATION = 1e-3
FIT_ITERATIONS = 400
# The fitted volumes stay within [0, FIT_MAX_RATIO] x Akinci's: on box walls 0.1 d behind the
# surface the fit needs 0.986-1.011 (the tank, the default dam break), so it never makes a wall
# much heavier than Akinci's for a fluid that sits farther away than the lattice.
FIT_MAX_RATIO = 1.05


def fit_volumes(
    xb: np.ndarray, psi_akinci: np.ndarray, lattice: np.ndarray, spacing: float, h: float
) -> tuple[np.ndarray, dict]:
    """Wall volumes psi >= 0 with which the rest lattice reads rho0 next to the walls.

    For every lattice point i within H of a wall particle the walls must supply what the lattice
    lacks there: tau_i = 1 - d^3 sum_j W_ij (j over the lattice, i itself included). psi minimises

        |A psi - tau|^2 + mu |psi - psi_akinci|^2,      A_ib = W(x_i - x_b),

    by conjugate gradients on the normal equations (mu = FIT_REGULARISATION * mean diag A^T A),
    then clips to [0, FIT_MAX_RATIO psi_akinci], so a lattice that sits farther than d from a wall
    (a misaligned or obstacle-only scene) never makes walls much heavier.
    Every sum has a fixed order, so the volumes do not depend on the thread count.
    Returns psi and a report of the fit (rest densities at the probes before and after).
    """
    probe_order, fnbr, fcnt = radius_lists(lattice, lattice, h)
    xs_lat = np.ascontiguousarray(lattice[probe_order])
    bord, bnbr, bcnt = radius_lists(xs_lat, xb, h)
    probes = np.flatnonzero(bcnt > 0)
    report = {"probes": int(len(probes))}
    if len(probes) == 0:
        return psi_akinci, report
    xs_b = np.ascontiguousarray(xb[bord])
    # fluid part of the rest density at the probes (the self term arrives as W(0) at distance 0)
    wf = np.zeros(fnbr.shape)
    kernel_rows(xs_lat, xs_lat, fnbr, fcnt, h, wf)
    fluid = spacing**3 * (wf.sum(axis=1) + w(0.0, h))
    # the probes were gathered in lattice order; restrict to those near walls
    nbr, cnt = np.ascontiguousarray(bnbr[probes]), np.ascontiguousarray(bcnt[probes])
    a = np.zeros(nbr.shape)
    kernel_rows(np.ascontiguousarray(xs_lat[probes]), xs_b, nbr, cnt, h, a)
    tau = 1.0 - fluid[probes]
    p0 = np.ascontiguousarray(psi_akinci[bord])
    diag = np.zeros(len(xb))
    _rows_tdot(nbr, cnt, a * a, np.ones(len(probes)), diag)
    mu = FIT_REGULARISATION * float(diag[diag > 0].mean())
    ap = np.empty(len(probes))
    _rows_dot(nbr, cnt, a, p0, ap)
    report["rest_density_akinci"] = (float((fluid[probes] + ap).min()), float((fluid[probes] + ap).max()))

    def normal(v, out):  # (A^T A + mu) v
        _rows_dot(nbr, cnt, a, v, ap)
        _rows_tdot(nbr, cnt, a, ap, out)
        out += mu * v

    # solve for the correction dpsi = psi - psi_akinci: (A^T A + mu) dpsi = A^T (tau - A p0)
    _rows_dot(nbr, cnt, a, p0, ap)
    rhs = np.empty(len(xb))
    _rows_tdot(nbr, cnt, a, tau - ap, rhs)
    x = np.zeros(len(xb))
    res = rhs.copy()
    dirn = res.copy()
    q = np.empty(len(xb))
    rr = _dot(res, res)
    rr0 = rr
    it = 0
    while it < FIT_ITERATIONS and rr > 1e-24 * rr0:
        normal(dirn, q)
        step = rr / _dot(dirn, q)
        x += step * dirn
        res -= step * q
        rr_new = _dot(res, res)
        dirn = res + (rr_new / rr) * dirn
        rr = rr_new
        it += 1
    psi_sorted = np.clip(p0 + x, 0.0, FIT_MAX_RATIO * p0)
    _rows_dot(nbr, cnt, a, psi_sorted, ap)
    rest = fluid[probes] + ap
    report.update(
        iterations=it,
        rest_density=(float(rest.min()), float(rest.max())),
        volume_ratio=(
            float((psi_sorted / np.maximum(p0, 1e-300)).min()),
            float((psi_sorted / np.maximum(p0, 1e-300)).max()),
        ),
    )
    psi = np.empty(len(xb))
    psi[bord] = psi_sorted
    return psi, report


class Boundary:
    """Boundary particles: positions `x`, volumes `psi`, masses `m = rho0 * psi`, velocities `v`.

    psi are Akinci's volumes, fitted to `rest_lattice` when one is given (`fit_volumes`).
    `groups` (optional, one int per particle): 0 for static walls, k > 0 for the k-th moving wall;
    volumes are computed per group. Without groups every wall is static (`moving` False, `v` 0).
    """

    def __init__(
        self,
        x: np.ndarray,
        support: float,
        rho0: float,
        rest_lattice: np.ndarray | None = None,
        spacing: float | None = None,
        groups: np.ndarray | None = None,
        depth: np.ndarray | None = None,
    ):
        self.x = np.array(x, dtype=np.float64).reshape(-1, 3)  # a copy: moving walls write into it
        self.field = None  # the walls as fields (boundary.field_walls.FieldWalls) under the "field" model
        self.h = float(support)
        self.rho0 = float(rho0)
        self.v = np.zeros_like(self.x)
        self.groups = None if groups is None else np.ascontiguousarray(groups, dtype=np.int32)
        self.x0 = None if groups is None else self.x.copy()  # placement at t = 0 (moving walls)
        # with moving walls: each particle's distance behind its wall's surface (contacts act on surfaces)
        self.depth = None if groups is None else np.zeros(len(self.x)) if depth is None else np.array(depth, float)
        self.moving = self.groups is not None and bool(np.any(self.groups > 0))
        self.psi = self._volumes()
        self.fit_report: dict = {}
        if rest_lattice is not None and len(rest_lattice) and self.n:
            # static walls only: moving walls and bodies keep Akinci's volumes (the fit lightens walls,
            # and a lightened body let a sinking 2000 kg/m^3 sphere fill with fluid, method.md section 9)
            fixed = slice(None) if self.groups is None else np.flatnonzero(self.groups == 0)
            psi_fit, self.fit_report = fit_volumes(
                np.ascontiguousarray(self.x[fixed]),
                self.psi[fixed],
                rest_lattice,
                self.h / 2.0 if spacing is None else spacing,
                self.h,
            )
            if self.groups is None:
                self.psi = psi_fit
            else:
                self.psi[fixed] = psi_fit
        self.m = self.rho0 * self.psi

    @property
    def n(self) -> int:
        return len(self.x)

    def _volumes(self) -> np.ndarray:
        if self.groups is not None:
            psi = np.zeros(len(self.x))
            for k in np.unique(self.groups):
                sel = np.flatnonzero(self.groups == k)
                psi[sel] = self._group_volumes(self.x[sel])
            return psi
        return self._group_volumes(self.x)

    def _group_volumes(self, x: np.ndarray) -> np.ndarray:
        n = len(x)
        psi = np.zeros(n)
        if n == 0:
            return psi
        x = np.ascontiguousarray(x)
        order, nbr, cnt = radius_lists(x, x, self.h)
        xs = np.ascontiguousarray(x[order])
        psi_sorted = np.zeros(n)
        akinci_volumes(xs, nbr, cnt, self.h, psi_sorted)
        psi[order] = psi_sorted
        return psi

    def state_dict(self) -> dict[str, np.ndarray]:
        """Positions, volumes and masses in their current (cell-sorted) order: the volumes were
        summed in the original order, so a continuation takes them as they are."""
        d = {"x": self.x.copy(), "psi": self.psi.copy(), "m": self.m.copy()}
        if self.moving:
            d.update(v=self.v.copy(), groups=self.groups.copy(), x0=self.x0.copy(), depth=self.depth.copy())
        return d

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        if len(d["x"]) != len(self.x):
            raise ValueError(f"saved boundary has {len(d['x'])} particles, this scene {len(self.x)}")
        self.x = np.array(d["x"], dtype=np.float64)  # a copy: moving walls write into it
        self.psi = np.ascontiguousarray(d["psi"], dtype=np.float64)
        self.m = np.ascontiguousarray(d["m"], dtype=np.float64)
        if self.moving:
            self.v = np.ascontiguousarray(d["v"], dtype=np.float64)
            self.groups = np.ascontiguousarray(d["groups"], dtype=np.int32)
            self.x0 = np.ascontiguousarray(d["x0"], dtype=np.float64)
            self.depth = np.ascontiguousarray(d["depth"], dtype=np.float64)
        else:
            self.v = np.zeros_like(self.x)

    def reorder(self, order: np.ndarray) -> None:
        """Follow the neighbour search's boundary sort (new[i] = old[order[i]])."""
        self.x = np.ascontiguousarray(self.x[order])
        self.psi = np.ascontiguousarray(self.psi[order])
        self.m = np.ascontiguousarray(self.m[order])
        self.v = np.ascontiguousarray(self.v[order])
        if self.groups is not None:
            self.groups = np.ascontiguousarray(self.groups[order])
            self.x0 = np.ascontiguousarray(self.x0[order])
            self.depth = np.ascontiguousarray(self.depth[order])
