"""The CUDA launchers: built from the pass table (`passes.PASSES`), one work item per particle,
calling the pass's body (compiled as a device function: `_cuda.device_function`), with the scratch
block `buf` a thread-local array.

The scratch block must have a size known when the kernel is compiled, so the kernels of the passes
with one are built per list stride (`passes(kf, kb)`, kept for the process; the stride grows
rarely); those without one are built once and bound here by name. The other kernels are cached on
disk by numba-cuda (`cache=True`); the pass kernels compile in each process's first steps (which
`ipsph bench` leaves out as warm-up). Kernels loop over particles grid-stride (`for i in
range(start, n, stride)`), so a launch covers any n with a capped grid and each thread allocates
its block once.

Also here: the element-wise updates and the permutations. The reductions: `cuda_reduce`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from . import kernels
from ._cuda import SIMULATOR, cuda, device_function
from .passes import PASSES, source

THREADS = 128  # threads per block
MAX_BLOCKS = 1 if SIMULATOR else 8192  # the simulator runs each thread as a Python thread: few of them
REDUCE_THREADS = 8 if SIMULATOR else 8192  # partial results of a reduction (fixed: see the docstring)

f64 = np.float64

w = device_function(kernels.w)


def grid(n: int) -> tuple[int, int]:
    """(blocks, threads) of a grid-stride launch over n items."""
    if SIMULATOR:
        return 1, max(1, min(n, 8))
    return max(1, min(math.ceil(n / THREADS), MAX_BLOCKS)), THREADS


# -- per-particle passes: generated from the pass table ------------------------------------------------
_STRIDE = {"fluid": "kf", "walls": "kb", "all": "kf + kb"}
_LOOP = ["for i in range(cuda.grid(1), {n}, cuda.gridsize(1)):"]


def _kernel(p, kf: int = 0, kb: int = 0):
    """The kernel of pass `p` (its body a device function), its scratch block (if any) `buf` a
    thread-local array of the lists' strides kf, kb."""
    scratch = f"buf = cuda.local.array(({p.rows}, {_STRIDE[p.stride]}), f64)" if p.rows else ""
    namespace = {"__name__": __name__, "cuda": cuda, "f64": f64, "w": w, "kf": kf, "kb": kb}
    namespace["body"] = device_function(p.body)
    exec(compile(source(p, scratch, _LOOP), __file__, "exec"), namespace)
    kernel = cuda.jit(namespace[p.name])
    if p.rows:
        kernel.strides = (kf, kb)  # what passes() was called with (a compile check rebuilds them)
    return kernel


@functools.lru_cache(maxsize=None)
def passes(kf: int, kb: int) -> dict:
    """The kernels of the passes with a scratch block, for fluid lists of stride kf and wall lists of
    stride kb (the block's size is a constant of the compiled kernel)."""
    return {p.name: _kernel(p, kf, kb) for p in PASSES.values() if p.rows}


# the passes without a scratch block: one kernel each, bound here by name
globals().update({p.name: _kernel(p) for p in PASSES.values() if not p.rows})


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
        warm[i] = 0.5 * max(min(k_total[i] * scale, 0.5), -0.5) if on else 0.0
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
