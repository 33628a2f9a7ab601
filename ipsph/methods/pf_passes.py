"""Numba passes of Projective Fluids [WKB16] (method.md section 3).

The local step (per-constraint multipliers lam_c) is `sph_passes.density_factor_lambda`.
The global step below is the closed-form solve of PF's diagonal system, written as a gather
over each particle's own neighbours, so it needs no atomics and is deterministic.
"""
from numba import njit, prange

from .sph_passes import C0, FAST, _buffers, _chunk, _gather_x, _weighted_gradient


@njit(parallel=True, fastmath=FAST, cache=True)
def pf_global(x, s, m, xb, mb, nf, cf, nb, cb, n_s, h, rho0, lam, a, x_out, lam_sum):
    """One global step of PF with the constraint gradients of the local step:

        d_k   = sum_{c in {k} u N(k)} lam_c G_ck
              = (1/rho0) [ sum_j (lam_k m_j + lam_j m_k) grad W_kj + lam_k sum_b m_b grad W_kb ]
        x_k  <- (m_k s_k + a n_k (x_k + d_k)) / (m_k + a n_k),      a = dt^2 k_s, n_k = |N(k)| + 1
        Lam_k <- beta_k (Lam_k + lam_k),  beta_k = a n_k / (m_k + a n_k)   (pressure bookkeeping)
    """
    bufs = _buffers(4, nf, nb)
    for c in prange(bufs.shape[0]):
        buf = bufs[c]
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for k in range(lo, hi):
            n_f, n_b = _gather_x(k, x, xb, nf, cf, nb, cb, buf)
            lk = lam[k]
            mk = m[k]
            for n in range(n_f):
                j = nf[k, n]
                buf[C0, n] = lk * m[j] + lam[j] * mk
            for n in range(n_b):
                buf[C0, n_f + n] = lk * mb[nb[k, n]]
            d0, d1, d2 = _weighted_gradient(n_f + n_b, buf, C0, h)
            an = a * n_s[k]
            inv = 1.0 / (mk + an)
            x_out[k, 0] = (mk * s[k, 0] + an * (x[k, 0] + d0 / rho0)) * inv
            x_out[k, 1] = (mk * s[k, 1] + an * (x[k, 1] + d1 / rho0)) * inv
            x_out[k, 2] = (mk * s[k, 2] + an * (x[k, 2] + d2 / rho0)) * inv
            lam_sum[k] = an * inv * (lam_sum[k] + lk)
