"""The CUDA launchers: one work item per particle, calling the per-particle bodies of `bodies`
(compiled as device functions: `_cuda.device_function`), with the scratch block `buf` a
thread-local array.

A thin, regular mirror of `cpu_passes`: the same kernels, the same argument order (positions and
per-particle inputs, the lists, scalars, outputs last), the same tests for what a pass fills
(the pair cache, the PF displacement, the warm-start mask). Adding an argument to a pass is one
line here as there.

The scratch block must have a size known when the kernel is compiled, so the pass kernels are
built per list stride (`passes(kf, kb)`, kept for the process; the stride grows rarely). The other
kernels are cached on disk by numba-cuda (`cache=True`); the pass kernels, closures over the
stride, compile in each process's first steps (which `ipsph bench` leaves out as warm-up). Kernels loop over
particles grid-stride (`for i in range(start, n, stride)`), so a launch covers any n with a
capped grid and each thread allocates its block once.

Also here: the element-wise updates, the permutations and the reductions. Reductions run in a
fixed order: REDUCE_THREADS partial results, each a strided serial sum, then folds of FOLD partials
in index order (`Reducer`), so a run gives the same bits on every launch, whatever the GPU's size.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .. import kernels
from . import bodies
from ._cuda import SIMULATOR, cuda, device_function
from .bodies import DENSITY_ROWS, PF_GLOBAL_ROWS, RATE_ROWS, STIFFNESS_ROWS, VISCOSITY_ROWS, WALL_RATE_ROWS

THREADS = 128  # threads per block
MAX_BLOCKS = 1 if SIMULATOR else 8192  # the simulator runs each thread as a Python thread: few of them
REDUCE_THREADS = 8 if SIMULATOR else 8192  # partial results of a reduction (fixed: see the docstring)

f64 = np.float64

# the bodies as device functions (the same source as the CPU backend's passes)
density_at = device_function(bodies.density_at)
divergence_residual_at = device_function(bodies.divergence_residual_at)
density_residual_at = device_function(bodies.density_residual_at)
stiffness_at = device_function(bodies.stiffness_at)
viscosity_at = device_function(bodies.viscosity_at)
pf_global_at = device_function(bodies.pf_global_at)
wall_rate_at = device_function(bodies.wall_rate_at)
w = device_function(kernels.w)


def grid(n: int) -> tuple[int, int]:
    """(blocks, threads) of a grid-stride launch over n items."""
    if SIMULATOR:
        return 1, max(1, min(n, 8))
    return max(1, min(math.ceil(n / THREADS), MAX_BLOCKS)), THREADS


# -- per-particle passes (one set per list stride) ---------------------------------------------------
@functools.lru_cache(maxsize=None)
def passes(kf: int, kb: int):
    """The pass kernels for fluid lists of stride kf and wall lists of stride kb."""
    k_all = kf + kb

    @cuda.jit
    def density_factor_lambda(x, mf, xb, mb, nf, cf, nb, cb, h, rho0, rho, alpha, lam, err, n_nbrs, gb, pair_grad):
        fill = pair_grad.shape[0] == x.shape[0]
        w0 = w(0.0, h)
        buf = cuda.local.array((DENSITY_ROWS, k_all), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            density_at(
                i, x, mf, xb, mb, nf, cf, nb, cb, h, rho0, w0, fill, buf, rho, alpha, lam, err, n_nbrs, gb, pair_grad
            )

    @cuda.jit
    def divergence_residual(x, v, mf, gb, gvb, nf, cf, pair_grad, h, alpha, n_nbrs, dt, drho, k):
        buf = cuda.local.array((RATE_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            divergence_residual_at(
                i,
                x,
                v,
                mf,
                gb,
                gvb,
                nf,
                cf,
                pair_grad,
                pair_grad.shape[0] == x.shape[0],
                h,
                alpha,
                n_nbrs,
                dt,
                buf,
                drho,
                k,
            )

    @cuda.jit
    def density_residual(x, v, mf, gb, gvb, nf, cf, pair_grad, h, rho, alpha, rho0, dt, rho_err, k):
        buf = cuda.local.array((RATE_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            density_residual_at(
                i,
                x,
                v,
                mf,
                gb,
                gvb,
                nf,
                cf,
                pair_grad,
                pair_grad.shape[0] == x.shape[0],
                h,
                rho,
                alpha,
                rho0,
                dt,
                buf,
                rho_err,
                k,
            )

    @cuda.jit
    def apply_stiffness(x, mf, gb, nf, cf, pair_grad, h, k, dt, v, k_total):
        buf = cuda.local.array((STIFFNESS_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            stiffness_at(i, x, mf, gb, nf, cf, pair_grad, pair_grad.shape[0] == x.shape[0], h, k, dt, buf, v, k_total)

    @cuda.jit
    def xsph(x, v, mf, rho, gb, gvb, lam, nf, cf, h, zeta, nu_dt, v_out, drho, disp, pair_grad):
        with_disp = disp.shape[0] == x.shape[0]
        fill = pair_grad.shape[0] == x.shape[0]
        eps = 0.01 * h * h
        standard = nu_dt > 0.0
        buf = cuda.local.array((VISCOSITY_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            viscosity_at(
                i,
                x,
                v,
                mf,
                rho,
                gb,
                gvb,
                lam,
                nf,
                cf,
                h,
                zeta,
                nu_dt,
                eps,
                standard,
                with_disp,
                fill,
                buf,
                v_out,
                drho,
                disp,
                pair_grad,
            )

    @cuda.jit
    def pf_global(x, s, mf, gb, nf, cf, h, rho0, lam, a, x_out, lam_sum):
        buf = cuda.local.array((PF_GLOBAL_ROWS, kf), f64)
        for k in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            pf_global_at(k, x, s, mf, gb, nf, cf, h, rho0, lam, a, buf, x_out, lam_sum)

    @cuda.jit
    def wall_rate(x, xb, mb, vb, nb, cb, h, gvb):
        buf = cuda.local.array((WALL_RATE_ROWS, kb), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            wall_rate_at(i, x, xb, mb, vb, nb, cb, h, buf, gvb)

    kernels = {
        "density_factor_lambda": density_factor_lambda,
        "divergence_residual": divergence_residual,
        "density_residual": density_residual,
        "apply_stiffness": apply_stiffness,
        "xsph": xsph,
        "pf_global": pf_global,
        "wall_rate": wall_rate,
    }
    for k in kernels.values():
        k.strides = (kf, kb)  # what passes() was called with (a compile check rebuilds them)
    return kernels


def launch(kernel, n: int, *args) -> None:
    """kernel[grid(n)](*args): a grid-stride launch over n items."""
    run(kernel, *grid(n), *args)


def run(kernel, blocks: int, threads: int, *args) -> None:
    """kernel[blocks, threads](*args): every launch of this backend goes through here."""
    kernel[blocks, threads](*args)


# -- element-wise updates (the arithmetic of cpu_passes, in the same order) --------------------------
@cuda.jit(cache=True)
def advance(x, v, dt, a, x_old):
    """x_old = x;  x += dt v + dt^2 a."""
    dt2 = dt * dt
    for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
        for c in range(3):
            x_old[i, c] = x[i, c]
            x[i, c] += dt * v[i, c] + dt2 * a[c]


@cuda.jit(cache=True)
def displacement_velocity(x, x_old, dt, v):
    """v = (x - x_old) / dt."""
    for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
        for c in range(3):
            v[i, c] = (x[i, c] - x_old[i, c]) / dt


@cuda.jit(cache=True)
def accelerate(v, dt, a):
    """v += dt a."""
    for i in range(cuda.grid(1), v.shape[0], cuda.gridsize(1)):
        for c in range(3):
            v[i, c] += dt * a[c]


@cuda.jit(cache=True)
def warm_stiffness(k_total, scale, rate, n_nbrs, min_nbrs, warm):
    """cpu_passes.warm_stiffness: DFSPH's warm start, then k_total = 0."""
    masked = rate.shape[0] == k_total.shape[0]
    for i in range(cuda.grid(1), k_total.shape[0], cuda.gridsize(1)):
        on = (rate[i] > 0.0 and n_nbrs[i] >= min_nbrs) if masked else True
        warm[i] = 0.5 * min(k_total[i] * scale, 0.5) if on else 0.0
        k_total[i] = 0.0


# Flat (1D) views: the vector operations below see every array as one run of numbers.
@cuda.jit(cache=True)
def fill(a, value):
    for i in range(cuda.grid(1), a.shape[0], cuda.gridsize(1)):
        a[i] = value


@cuda.jit(cache=True)
def copy(dst, src):
    for i in range(cuda.grid(1), dst.shape[0], cuda.gridsize(1)):
        dst[i] = src[i]


@cuda.jit(cache=True)
def axpy(y, alpha, x):
    """y += alpha x."""
    for i in range(cuda.grid(1), y.shape[0], cuda.gridsize(1)):
        y[i] += alpha * x[i]


@cuda.jit(cache=True)
def scale(a, c):
    for i in range(cuda.grid(1), a.shape[0], cuda.gridsize(1)):
        a[i] *= c


@cuda.jit(cache=True)
def pf_pressure(out, lam, rho0, dt):
    """out = -rho0 lam / dt^2 (the numpy expression's order: (-rho0 lam) / (dt dt))."""
    dt2 = dt * dt
    for i in range(cuda.grid(1), out.shape[0], cuda.gridsize(1)):
        out[i] = -rho0 * lam[i] / dt2


@cuda.jit(cache=True)
def stiffness_pressure(out, k, rho, add):
    """out (+)= k rho^2 (as k * rho * rho)."""
    for i in range(cuda.grid(1), out.shape[0], cuda.gridsize(1)):
        p = k[i] * rho[i] * rho[i]
        out[i] = out[i] + p if add else p


@cuda.jit(cache=True)
def take_rows(a, perm, out):
    """out[i, :] = a[perm[i], :] for (n, m) arrays."""
    for i in range(cuda.grid(1), out.shape[0], cuda.gridsize(1)):
        j = perm[i]
        for c in range(out.shape[1]):
            out[i, c] = a[j, c]


@cuda.jit(cache=True)
def untake_rows(a, perm, out):
    """out[perm[i], :] = a[i, :] for (n, m) arrays."""
    for i in range(cuda.grid(1), a.shape[0], cuda.gridsize(1)):
        j = perm[i]
        for c in range(a.shape[1]):
            out[j, c] = a[i, c]


# -- reductions in a fixed order ---------------------------------------------------------------------
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
