"""The CUDA backend's reductions, in a fixed order: REDUCE_THREADS partial results, each a strided
serial sum, then folds of FOLD partials in index order (`Reducer`), so a run gives the same bits
on every launch, whatever the GPU's size.
"""

from __future__ import annotations

import math

import numpy as np

from ._cuda import SIMULATOR, cuda
from .cuda_passes import REDUCE_THREADS, THREADS, launch, run


@cuda.jit(cache=True)
def _partial_sums(a, positive, part):
    """part[t] = sum over i = t, t + T, ... of a[i] (of max(a[i], 0) with `positive`)."""
    t = cuda.grid(1)
    if t < part.shape[0]:
        s = 0.0
        for i in range(t, a.shape[0], part.shape[0]):
            s += max(a[i], 0.0) if positive else a[i]
        part[t] = s


@cuda.jit(cache=True)
def _partial_max(a, part):
    t = cuda.grid(1)
    if t < part.shape[0]:
        m = -math.inf
        for i in range(t, a.shape[0], part.shape[0]):
            m = max(m, a[i])
        part[t] = m


@cuda.jit(cache=True)
def _partial_speed_energy(v, m, part):
    """part[0, t] = max |v_i|^2, part[1, t] = sum m_i |v_i|^2 / 2 over i = t, t + T, ..."""
    t = cuda.grid(1)
    if t < part.shape[1]:
        vmax2 = 0.0
        ke = 0.0
        for i in range(t, v.shape[0], part.shape[1]):
            s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2]
            vmax2 = max(vmax2, s2)
            ke += 0.5 * m[i] * s2
        part[0, t] = vmax2
        part[1, t] = ke


@cuda.jit(cache=True)
def _partial_unhealthy(x, v, lo0, lo1, lo2, hi0, hi1, hi2, part):
    """part[t] = the smallest unhealthy index among i = t, t + T, ... (n if none)."""
    t = cuda.grid(1)
    if t < part.shape[0]:
        n = x.shape[0]
        first = n
        for i in range(t, n, part.shape[0]):
            bad = False
            for c in range(3):
                if not (math.isfinite(x[i, c]) and math.isfinite(v[i, c])):
                    bad = True
            if x[i, 0] < lo0 or x[i, 0] > hi0 or x[i, 1] < lo1 or x[i, 1] > hi1 or x[i, 2] < lo2 or x[i, 2] > hi2:
                bad = True
            if bad:
                first = i
                break
        part[t] = first


@cuda.jit(cache=True)
def _partial_bounds(x, part):
    """part[0:3, t] = min, part[3:6, t] = max per axis over i = t, t + T, ...; part[6, t] = 1 if any
    coordinate is not finite."""
    t = cuda.grid(1)
    if t < part.shape[1]:
        lo0 = lo1 = lo2 = math.inf
        hi0 = hi1 = hi2 = -math.inf
        bad = 0.0
        for i in range(t, x.shape[0], part.shape[1]):
            a, b, c = x[i, 0], x[i, 1], x[i, 2]
            if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
                bad = 1.0
            lo0, lo1, lo2 = min(lo0, a), min(lo1, b), min(lo2, c)
            hi0, hi1, hi2 = max(hi0, a), max(hi1, b), max(hi2, c)
        part[0, t], part[1, t], part[2, t] = lo0, lo1, lo2
        part[3, t], part[4, t], part[5, t] = hi0, hi1, hi2
        part[6, t] = bad


@cuda.jit(cache=True)
def _fold(src, op, chunk, dst):
    """dst[r, t] = the sum (op 0), max (op 1) or min (op 2) of src[r, t chunk:(t + 1) chunk], in
    index order: one thread per (r, t)."""
    width = dst.shape[1]
    for k in range(cuda.grid(1), dst.shape[0] * width, cuda.gridsize(1)):
        r = k // width
        t = k % width
        lo = t * chunk
        hi = min(lo + chunk, src.shape[1])
        acc = src[r, lo]
        for j in range(lo + 1, hi):
            p = src[r, j]
            if op == 0:
                acc += p
            elif op == 1:
                acc = max(acc, p)
            else:
                acc = min(acc, p)
        dst[r, t] = acc


FOLD = 128  # partials per thread of each fold: REDUCE_THREADS -> 64 -> 1 on a GPU


class Reducer:
    """Device scratch for the reductions, allocated once (REDUCE_THREADS partials per row).

    A reduction: REDUCE_THREADS threads each reduce a strided share (stage 1), then `_fold`
    reduces runs of FOLD partials until one is left (64 threads, then one), every step in index
    order: the same bits on every launch, whatever the GPU's size, and no single thread walks
    all the partials."""

    def __init__(self):
        self.part = cuda.device_array((7, REDUCE_THREADS), dtype=np.float64)
        self.levels = []
        width = REDUCE_THREADS
        while width > 1:
            width = math.ceil(width / FOLD)
            self.levels.append(cuda.device_array((7, width), dtype=np.float64))
        if not self.levels:
            self.levels.append(cuda.device_array((7, 1), dtype=np.float64))

    def _stage1(self, kernel, *args):
        blocks = math.ceil(REDUCE_THREADS / THREADS) if not SIMULATOR else 1
        run(kernel, blocks, min(THREADS, REDUCE_THREADS), *args)

    def _fold(self, lo: int, hi: int, op: int) -> np.ndarray:
        """Rows lo:hi of the partials reduced with op, on the host."""
        src = self.part
        for dst in self.levels:
            chunk = math.ceil(src.shape[1] / dst.shape[1])
            launch(_fold, (hi - lo) * dst.shape[1], src[lo:hi], op, chunk, dst[lo:hi])
            src = dst
        return self.levels[-1][lo:hi, 0].copy_to_host()

    def _rows(self, rows: int, op: int) -> np.ndarray:
        return self._fold(0, rows, op)

    def sum(self, a, positive=False) -> float:
        self._stage1(_partial_sums, a, positive, self.part[0])
        return float(self._rows(1, 0)[0])

    def max(self, a) -> float:
        self._stage1(_partial_max, a, self.part[0])
        return float(self._rows(1, 1)[0])

    def speed_energy(self, v, m) -> tuple[float, float]:
        self._stage1(_partial_speed_energy, v, m, self.part[:2])
        vmax2 = float(self._fold(0, 1, 1)[0])
        ke = float(self._fold(1, 2, 0)[0])
        return math.sqrt(vmax2), ke

    def first_unhealthy(self, x, v, lo, hi) -> int:
        self._stage1(
            _partial_unhealthy,
            x,
            v,
            float(lo[0]),
            float(lo[1]),
            float(lo[2]),
            float(hi[0]),
            float(hi[1]),
            float(hi[2]),
            self.part[0],
        )
        first = int(self._rows(1, 2)[0])
        return -1 if first >= x.shape[0] else first

    def bounds(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the points, NaN in both if any coordinate is not finite (neighbours.cpu.bounds)."""
        self._stage1(_partial_bounds, x, self.part)
        lo = self._fold(0, 3, 2)
        hi_bad = self._fold(3, 7, 1)
        hi = hi_bad[:3]
        if hi_bad[3] > 0:
            lo[:] = np.nan
            hi[:] = np.nan
        return lo, hi
