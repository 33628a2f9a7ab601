"""Numba passes of Projective Fluids [WKB16] (method.md section 3).

The local step (per-constraint multipliers lam_c) is `sph_passes.density_factor_lambda`.
The global step below is the closed-form solve of PF's diagonal system, written as a gather
over each particle's own neighbours, so it needs no atomics and is deterministic.
"""
from numba import njit, prange

from .sph_passes import C0, FAST, _chunk, _fluid_buffers, _gather_xf, _weighted_gradient


@njit(parallel=True, fastmath=FAST, cache=True)
def pf_global(x, s, mf, gb, nf, cf, h, rho0, lam, a, x_out, lam_sum):
    """One global step of PF with the constraint gradients of the local step:

        d_k   = sum_{c in {k} u N(k)} lam_c G_ck
              = (1/rho0) [ sum_j mf (lam_k + lam_j) grad W_kj + lam_k gb_k ]
        x_k  <- (mf s_k + a n_k (x_k + d_k)) / (mf + a n_k),        a = dt^2 k_s, n_k = |N(k)| + 1
        Lam_k <- beta_k (Lam_k + lam_k),  beta_k = a n_k / (mf + a n_k)    (pressure bookkeeping)

    gb_k = sum_b m_b grad W_kb at x comes from the local step (density_factor_lambda) just
    before, at the same positions, so the walls' neighbours are not visited again here.
    """
    bufs = _fluid_buffers(4, nf)
    for c in prange(bufs.shape[0]):
        buf = bufs[c]
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for k in range(lo, hi):
            n_f = _gather_xf(k, x, nf, cf, buf)
            lk = lam[k]
            for n in range(n_f):
                buf[C0, n] = lk + lam[nf[k, n]]
            d0, d1, d2 = _weighted_gradient(n_f, buf, C0, h)
            an = a * (cf[k] + 1)  # n_k: the lists were built at s
            inv = 1.0 / (mf + an)
            x_out[k, 0] = (mf * s[k, 0] + an * (x[k, 0] + (mf * d0 + lk * gb[k, 0]) / rho0)) * inv
            x_out[k, 1] = (mf * s[k, 1] + an * (x[k, 1] + (mf * d1 + lk * gb[k, 1]) / rho0)) * inv
            x_out[k, 2] = (mf * s[k, 2] + an * (x[k, 2] + (mf * d2 + lk * gb[k, 2]) / rho0)) * inv
            lam_sum[k] = an * inv * (lam_sum[k] + lk)
