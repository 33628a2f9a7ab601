"""Point-cloud kernels of the sampler (numba): the greedy Poisson-disk filter and the nearest
distance within a cutoff, both on a uniform cell table."""

from __future__ import annotations

import math

import numba as nb
import numpy as np


def poisson_filter(candidates: np.ndarray, radius: float) -> np.ndarray:
    """Indices of a maximal subset with pairwise distance >= radius, taken greedily in input order
    (earlier candidates win). Every rejected candidate lies within radius of a kept one."""
    c = np.ascontiguousarray(candidates, dtype=np.float64)
    if len(c) == 0:
        return np.empty(0, dtype=np.int64)
    cell_of, nbr = _cell_table(c, radius)
    keep = np.zeros(len(c), dtype=np.bool_)
    overflow = np.zeros(1, dtype=np.int64)
    _greedy_kernel(c, cell_of, nbr, radius * radius, 16, keep, overflow)
    if overflow[0]:
        raise RuntimeError("poisson_filter: cell slot overflow (more than 16 separated points in a cell)")
    return np.flatnonzero(keep)


def _cell_table(points: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Occupied cells of size h: (cell id per point, (ncells, 27) neighbour cell ids or -1)."""
    lo = points.min(axis=0) - h
    ijk = np.floor((points - lo) / h).astype(np.int64)
    dims = ijk.max(axis=0) + 2
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    uniq, inv = np.unique(key, return_inverse=True)
    ci = np.stack([uniq // (dims[1] * dims[2]), (uniq // dims[2]) % dims[1], uniq % dims[2]], axis=1)
    off = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)], dtype=np.int64)
    nb_ijk = ci[:, None, :] + off[None, :, :]
    nb_key = (nb_ijk[..., 0] * dims[1] + nb_ijk[..., 1]) * dims[2] + nb_ijk[..., 2]
    pos = np.clip(np.searchsorted(uniq, nb_key), 0, len(uniq) - 1)
    valid = (uniq[pos] == nb_key) & np.all((nb_ijk >= 0) & (nb_ijk < dims), axis=2)
    return inv.ravel().astype(np.int64), np.where(valid, pos, -1).astype(np.int64)


@nb.njit(cache=True)
def _greedy_kernel(points, cell_of, nbr, r2, cap, keep, overflow):
    """Serial greedy Poisson-disk selection: keep_i = no kept j < i with |x_i - x_j|² < r2."""
    ncell = nbr.shape[0]
    slots = np.full((ncell, cap), -1, dtype=np.int64)
    count = np.zeros(ncell, dtype=np.int64)
    for i in range(points.shape[0]):
        ok = True
        for q in range(27):
            c = nbr[cell_of[i], q]
            if c < 0:
                continue
            for s in range(count[c]):
                j = slots[c, s]
                dx = points[i, 0] - points[j, 0]
                dy = points[i, 1] - points[j, 1]
                dz = points[i, 2] - points[j, 2]
                if dx * dx + dy * dy + dz * dz < r2:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            c = cell_of[i]
            if count[c] >= cap:
                overflow[0] = 1
                return
            slots[c, count[c]] = i
            count[c] += 1
            keep[i] = True


def nearest_distance(query: np.ndarray, points: np.ndarray, cutoff: float, *, exclude_self: bool = False) -> np.ndarray:
    """Distance from each query point to its nearest point (inf when none is closer than cutoff).
    exclude_self: query is points, each point's own index is skipped (nearest-neighbour spacing)."""
    q = np.ascontiguousarray(np.asarray(query, dtype=np.float64).reshape(-1, 3))
    p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    out = np.full(len(q), np.inf)
    if len(q) == 0 or len(p) == 0:
        return out
    h = float(cutoff)
    lo = np.minimum(p.min(axis=0), q.min(axis=0)) - h
    ijk = np.floor((p - lo) / h).astype(np.int64)
    dims = np.maximum(np.floor((np.maximum(p.max(axis=0), q.max(axis=0)) - lo) / h).astype(np.int64) + 2, 1)
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(key, kind="stable")
    skey = key[order]
    _nearest_kernel(q, p[order], order, skey, lo, h, dims, exclude_self, out)
    return out


@nb.njit(parallel=True, cache=True)
def _nearest_kernel(query, sorted_pts, sorted_ids, sorted_keys, lo, h, dims, exclude_self, out):
    """out_i = min_j |q_i − p_j| over the 27 cells around q_i, when below h (else left as is)."""
    for i in nb.prange(query.shape[0]):
        ci = int(math.floor((query[i, 0] - lo[0]) / h))
        cj = int(math.floor((query[i, 1] - lo[1]) / h))
        ck = int(math.floor((query[i, 2] - lo[2]) / h))
        best = h * h
        for a in range(ci - 1, ci + 2):
            if a < 0 or a >= dims[0]:
                continue
            for b in range(cj - 1, cj + 2):
                if b < 0 or b >= dims[1]:
                    continue
                for c in range(ck - 1, ck + 2):
                    if c < 0 or c >= dims[2]:
                        continue
                    k = (a * dims[1] + b) * dims[2] + c
                    s = np.searchsorted(sorted_keys, k)
                    while s < sorted_keys.shape[0] and sorted_keys[s] == k:
                        if not (exclude_self and sorted_ids[s] == i):
                            dx = query[i, 0] - sorted_pts[s, 0]
                            dy = query[i, 1] - sorted_pts[s, 1]
                            dz = query[i, 2] - sorted_pts[s, 2]
                            dd = dx * dx + dy * dy + dz * dz
                            if dd < best:
                                best = dd
                        s += 1
        if best < h * h:
            out[i] = math.sqrt(best)
