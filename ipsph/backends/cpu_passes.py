"""The CPU launchers: `prange` over blocks of particles, each block with one scratch buffer,
calling the per-particle bodies of `bodies` for every particle in it.

Particles are processed in CHUNKS blocks rather than one buffer per thread: reading a thread id
would keep Numba from caching the compiled pass. Each particle is handled by one thread from
start to end and writes index i only, so the results do not depend on the thread count.
Arguments follow one order: positions and per-particle inputs, the lists (nf, cf: fluid
indices and counts; nb, cb: walls), scalars, outputs last.

Also here: the serial reductions (fixed order: the same bits whatever the thread count) and the
element-wise updates a step needs (one loop each instead of numpy temporaries, whose broadcast of a
(3,) vector over (n, 3) costs more than the arithmetic: docs/performance.md).
"""

import numpy as np
from numba import njit, prange

from . import bodies, kernels, viscous_bodies
from ._cache import depend_on
from .bodies import (
    DENSITY_ROWS,
    FAST,
    PF_GLOBAL_ROWS,
    RATE_ROWS,
    STIFFNESS_ROWS,
    VISCOSITY_ROWS,
    VISCOUS_APPLY_ROWS,
    VISCOUS_SETUP_ROWS,
    WALL_RATE_ROWS,
    density_at,
    density_residual_at,
    divergence_residual_at,
    pf_global_at,
    stiffness_at,
    wall_rate_at,
)
from .kernels import w
from .viscous_bodies import cg_precondition_at, viscosity_at, viscous_apply_at, viscous_setup_at

CHUNKS = 64  # blocks of particles per pass, each with its own scratch buffer

NO_DISPLACEMENT = np.zeros((0, 3))  # xsph(..., disp=NO_DISPLACEMENT): skip the PF displacement
EVERY_PARTICLE = np.zeros(0)  # warm_stiffness(..., rate=EVERY_PARTICLE): no mask

# The pair cache G[i, :, k] = mf grad W_ij (float64, the layout of the fluid lists: (n, 3, K)).
# The pressure solves run at fixed positions, so the pass that last visits the pairs at those
# positions fills it (DFSPH: the density pass; IPSPH: the viscosity pass) and returns it, and the
# solves' residual and correction passes read it instead of gathering x_j and evaluating the
# kernel. A pass given NO_PAIR_CACHE (no rows) neither fills nor reads it.
NO_PAIR_CACHE = np.zeros((0, 3, 0))


@njit(inline="always")
def _buffers(rows, nf, nb):
    """One (rows, K_f + K_b) scratch block per chunk of particles (no thread ids: cacheable)."""
    return np.empty((min(nf.shape[0], CHUNKS), rows, nf.shape[1] + nb.shape[1]))


@njit(inline="always")
def _fluid_buffers(rows, nf):
    """One (rows, K_f) scratch block per chunk, for the passes that see walls through `gb`."""
    return np.empty((min(nf.shape[0], CHUNKS), rows, nf.shape[1]))


@njit(inline="always")
def _chunk(c, n_chunks, n):
    """Particle range [lo, hi) of chunk c."""
    return c * n // n_chunks, (c + 1) * n // n_chunks


# -- per-particle passes ---------------------------------------------------------------------------
@njit(parallel=True, fastmath=FAST, cache=True)
def density_factor_lambda(x, mf, xb, mb, nf, cf, nb, cb, h, rho0, rho, alpha, lam, err, n_nbrs, gb, pair_grad):
    """bodies.density_at for every particle; fills the pair cache if it has a row per particle."""
    fill = pair_grad.shape[0] == x.shape[0]
    w0 = w(0.0, h)
    bufs = _buffers(DENSITY_ROWS, nf, nb)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            density_at(
                i,
                x,
                mf,
                xb,
                mb,
                nf,
                cf,
                nb,
                cb,
                h,
                rho0,
                w0,
                fill,
                bufs[c],
                rho,
                alpha,
                lam,
                err,
                n_nbrs,
                gb,
                pair_grad,
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def divergence_residual(x, v, mf, gb, gvb, nf, cf, pair_grad, h, alpha, n_nbrs, dt, drho, k):
    """bodies.divergence_residual_at for every particle."""
    bufs = _fluid_buffers(RATE_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
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
                bufs[c],
                drho,
                k,
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def density_residual(x, v, mf, gb, gvb, nf, cf, pair_grad, h, rho, alpha, rho0, dt, rho_err, k):
    """bodies.density_residual_at for every particle."""
    bufs = _fluid_buffers(RATE_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
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
                bufs[c],
                rho_err,
                k,
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def apply_stiffness(x, mf, gb, nf, cf, pair_grad, h, k, dt, v, k_total, mirror):
    """bodies.stiffness_at for every particle (in place on v, k_total)."""
    bufs = _fluid_buffers(STIFFNESS_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            stiffness_at(
                i, x, mf, gb, nf, cf, pair_grad, pair_grad.shape[0] == x.shape[0], h, k, dt, bufs[c], v, k_total, mirror
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def xsph(x, v, mf, rho, gb, gvb, lam, nf, cf, h, zeta, nu_dt, v_out, drho, disp, pair_grad, mirror):
    """bodies.viscosity_at for every particle; the PF displacement only if `disp` has a row per
    particle, the pair cache only if `pair_grad` has."""
    with_disp = disp.shape[0] == x.shape[0]
    fill = pair_grad.shape[0] == x.shape[0]
    eps = 0.01 * h * h
    standard = nu_dt > 0.0
    bufs = _fluid_buffers(VISCOSITY_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
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
                bufs[c],
                v_out,
                drho,
                disp,
                pair_grad,
                mirror,
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def pf_global(x, s, mf, gb, nf, cf, h, rho0, lam, a, x_out, lam_sum, mirror):
    """bodies.pf_global_at for every particle."""
    bufs = _fluid_buffers(PF_GLOBAL_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for k in range(lo, hi):
            pf_global_at(k, x, s, mf, gb, nf, cf, h, rho0, lam, a, bufs[c], x_out, lam_sum, mirror)


@njit(parallel=True, fastmath=FAST, cache=True)
def wall_rate(x, xb, mb, vb, nb, cb, h, gvb):
    """bodies.wall_rate_at for every particle (moving walls only)."""
    bufs = _fluid_buffers(WALL_RATE_ROWS, nb)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            wall_rate_at(i, x, xb, mb, vb, nb, cb, h, bufs[c], gvb)


@njit(parallel=True, fastmath=FAST, cache=True)
def viscous_setup(x, v, mf, rho, xb, mb, vb, nf, cf, nb, cb, h, rho0, nu_dt, wall_factor, full, b, diag, wmat):
    """viscous_bodies.viscous_setup_at for every particle: the implicit viscosity's right-hand side,
    Jacobi diagonal and wall blocks."""
    bufs = _buffers(VISCOUS_SETUP_ROWS, nf, nb)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            viscous_setup_at(
                i, x, v, mf, rho, xb, mb, vb, nf, cf, nb, cb, h, rho0, nu_dt, wall_factor, full, bufs[c], b, diag, wmat
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def viscous_apply(x, p, mf, rho, nf, cf, h, nu_dt, wmat, out, pdot):
    """viscous_bodies.viscous_apply_at for every particle: out = A p, pdot_i = V_i p_i . out_i."""
    bufs = _fluid_buffers(VISCOUS_APPLY_ROWS, nf)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            viscous_apply_at(i, x, p, mf, rho, nf, cf, h, nu_dt, wmat, bufs[c], out, pdot)


@njit(cache=True)
def cg_precondition(r, diag, rho, mf, z, rz, rr):
    """viscous_bodies.cg_precondition_at for every particle (element-wise)."""
    for i in range(r.shape[0]):
        cg_precondition_at(i, r, diag, rho, mf, z, rz, rr)


# -- serial reductions ------------------------------------------------------------------------------
@njit(cache=True)
def mean(a):
    """Serial sum / n: the same bits whatever the thread count (loop criteria depend on it)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i]
    return s / max(a.shape[0], 1)


@njit(cache=True)
def mean_positive(a):
    """Serial sum of max(a_i, 0) / n (the same bits as mean(np.maximum(a, 0)))."""
    s = 0.0
    for i in range(a.shape[0]):
        s += max(a[i], 0.0)
    return s / max(a.shape[0], 1)


@njit(cache=True)
def speed_energy(v, m):
    """(max_i |v_i|, sum_i m_i |v_i|^2 / 2), serially for thread-count independent bits."""
    vmax2 = 0.0
    ke = 0.0
    for i in range(v.shape[0]):
        s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2]
        vmax2 = max(vmax2, s2)
        ke += 0.5 * m[i] * s2
    return np.sqrt(vmax2), ke


@njit(cache=True)
def first_unhealthy(x, v, lo, hi):
    """Index of the first particle with a non-finite position/velocity or outside [lo, hi], else -1."""
    for i in range(x.shape[0]):
        for c in range(3):
            if not (np.isfinite(x[i, c]) and np.isfinite(v[i, c])):
                return i
            if x[i, c] < lo[c] or x[i, c] > hi[c]:
                return i
    return -1


# -- element-wise updates (the same arithmetic, in the same order, as the numpy expressions) --------
@njit(cache=True)
def advance(x, v, dt, a, x_old):
    """x_old = x;  x += dt v + dt^2 a   (the inertial target, a = g)."""
    dt2 = dt * dt
    for i in range(x.shape[0]):
        for c in range(3):
            x_old[i, c] = x[i, c]
            x[i, c] += dt * v[i, c] + dt2 * a[c]


@njit(cache=True)
def displacement_velocity(x, x_old, dt, v):
    """v = (x - x_old) / dt."""
    for i in range(x.shape[0]):
        for c in range(3):
            v[i, c] = (x[i, c] - x_old[i, c]) / dt


@njit(cache=True)
def accelerate(v, dt, a):
    """v += dt a (one acceleration for all particles)."""
    for i in range(v.shape[0]):
        for c in range(3):
            v[i, c] += dt * a[c]


@njit(cache=True)
def warm_stiffness(k_total, scale, rate, n_nbrs, min_nbrs, warm):
    """DFSPH's warm start (method.md section 2): warm_i = 0.5 min(k_total_i scale, 0.5) where
    rate_i > 0 and n_nbrs_i >= min_nbrs (every particle if `rate` is empty), else 0; then
    k_total = 0, ready to sum what the solve applies."""
    masked = rate.shape[0] == k_total.shape[0]
    for i in range(k_total.shape[0]):
        on = (rate[i] > 0.0 and n_nbrs[i] >= min_nbrs) if masked else True
        warm[i] = 0.5 * min(k_total[i] * scale, 0.5) if on else 0.0
        k_total[i] = 0.0


# -- cache=True keys a pass's cache on this file only: it also depends on the bodies it inlines
_PASSES = (density_factor_lambda, divergence_residual, density_residual, apply_stiffness, xsph, pf_global, wall_rate)
_INLINED = (bodies, viscous_bodies, kernels)
depend_on((*_PASSES, viscous_setup, viscous_apply, cg_precondition), (__file__, *(m.__file__ for m in _INLINED)))
