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

Also here: the element-wise updates and the permutations. The reductions: `cuda_reduce`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from . import bodies, kernels, viscous_bodies
from ._cuda import SIMULATOR, cuda, device_function
from .bodies import (
    DENSITY_ROWS,
    PF_GLOBAL_ROWS,
    RATE_ROWS,
    STIFFNESS_ROWS,
    VISCOSITY_ROWS,
    VISCOUS_APPLY_ROWS,
    VISCOUS_SETUP_ROWS,
    WALL_RATE_ROWS,
)

THREADS = 128  # threads per block
MAX_BLOCKS = 1 if SIMULATOR else 8192  # the simulator runs each thread as a Python thread: few of them
REDUCE_THREADS = 8 if SIMULATOR else 8192  # partial results of a reduction (fixed: see the docstring)

f64 = np.float64

# the bodies as device functions (the same source as the CPU backend's passes)
density_at = device_function(bodies.density_at)
divergence_residual_at = device_function(bodies.divergence_residual_at)
density_residual_at = device_function(bodies.density_residual_at)
stiffness_at = device_function(bodies.stiffness_at)
viscosity_at = device_function(viscous_bodies.viscosity_at)
pf_global_at = device_function(bodies.pf_global_at)
wall_rate_at = device_function(bodies.wall_rate_at)
viscous_setup_at = device_function(viscous_bodies.viscous_setup_at)
viscous_apply_at = device_function(viscous_bodies.viscous_apply_at)
cg_precondition_at = device_function(viscous_bodies.cg_precondition_at)
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
    def apply_stiffness(x, mf, gb, nf, cf, pair_grad, h, k, dt, v, k_total, mirror):
        buf = cuda.local.array((STIFFNESS_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            stiffness_at(
                i, x, mf, gb, nf, cf, pair_grad, pair_grad.shape[0] == x.shape[0], h, k, dt, buf, v, k_total, mirror
            )

    @cuda.jit
    def xsph(x, v, mf, rho, gb, gvb, lam, nf, cf, h, zeta, nu_dt, v_out, drho, disp, pair_grad, mirror):
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
                mirror,
            )

    @cuda.jit
    def pf_global(x, s, mf, gb, nf, cf, h, rho0, lam, a, x_out, lam_sum, mirror):
        buf = cuda.local.array((PF_GLOBAL_ROWS, kf), f64)
        for k in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            pf_global_at(k, x, s, mf, gb, nf, cf, h, rho0, lam, a, buf, x_out, lam_sum, mirror)

    @cuda.jit
    def wall_rate(x, xb, mb, vb, nb, cb, h, gvb):
        buf = cuda.local.array((WALL_RATE_ROWS, kb), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            wall_rate_at(i, x, xb, mb, vb, nb, cb, h, buf, gvb)

    @cuda.jit
    def viscous_setup(x, v, mf, rho, xb, mb, vb, nf, cf, nb, cb, h, rho0, nu_dt, wall_factor, full, b, diag, wmat):
        buf = cuda.local.array((VISCOUS_SETUP_ROWS, k_all), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            viscous_setup_at(
                i, x, v, mf, rho, xb, mb, vb, nf, cf, nb, cb, h, rho0, nu_dt, wall_factor, full, buf, b, diag, wmat
            )

    @cuda.jit
    def viscous_apply(x, p, mf, rho, nf, cf, h, nu_dt, wmat, out, pdot):
        buf = cuda.local.array((VISCOUS_APPLY_ROWS, kf), f64)
        for i in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
            viscous_apply_at(i, x, p, mf, rho, nf, cf, h, nu_dt, wmat, buf, out, pdot)

    kernels = {
        "density_factor_lambda": density_factor_lambda,
        "divergence_residual": divergence_residual,
        "density_residual": density_residual,
        "apply_stiffness": apply_stiffness,
        "xsph": xsph,
        "pf_global": pf_global,
        "wall_rate": wall_rate,
        "viscous_setup": viscous_setup,
        "viscous_apply": viscous_apply,
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


@cuda.jit
def cg_precondition(r, diag, rho, mf, z, rz, rr):
    """viscous_bodies.cg_precondition_at for every particle (the implicit viscosity's Jacobi step)."""
    for i in range(cuda.grid(1), r.shape[0], cuda.gridsize(1)):
        cg_precondition_at(i, r, diag, rho, mf, z, rz, rr)


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
