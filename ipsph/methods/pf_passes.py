"""Numba passes of Projective Fluids [WKB16] (method.md section 3).

The local step (per-constraint multipliers lam_c) is `sph_passes.density_factor_lambda`.
The global step below is the closed-form solve of PF's diagonal system, written as a gather
over each particle's own neighbours, so it needs no atomics and is deterministic.
"""
import numpy as np
from numba import njit, prange

from ..kernels import grad_w_factor
from .sph_passes import FAST


@njit(parallel=True, fastmath=FAST, cache=True)
def pf_global(x, s, m, xb, mb, nf, cf, nb, cb, n_s, h, rho0, lam, a, x_out, lam_sum):
    """One global step of PF with the constraint gradients of the local step:

        d_k   = sum_{c in {k} u N(k)} lam_c G_ck
              = (1/rho0) [ sum_j (lam_k m_j + lam_j m_k) grad W_kj + lam_k sum_b m_b grad W_kb ]
        x_k  <- (m_k s_k + a n_k (x_k + d_k)) / (m_k + a n_k),      a = dt^2 k_s, n_k = |N(k)| + 1
        Lam_k <- beta_k (Lam_k + lam_k),  beta_k = a n_k / (m_k + a n_k)   (pressure bookkeeping)
    """
    for k in prange(x.shape[0]):
        lk = lam[k]
        mk = m[k]
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        xk0, xk1, xk2 = x[k, 0], x[k, 1], x[k, 2]
        for n in range(cf[k]):
            j = nf[k, n]
            e0 = xk0 - x[j, 0]
            e1 = xk1 - x[j, 1]
            e2 = xk2 - x[j, 2]
            f = (lk * m[j] + lam[j] * mk) * grad_w_factor(np.sqrt(e0 * e0 + e1 * e1 + e2 * e2), h)
            d0 += f * e0
            d1 += f * e1
            d2 += f * e2
        for n in range(cb[k]):
            b = nb[k, n]
            e0 = xk0 - xb[b, 0]
            e1 = xk1 - xb[b, 1]
            e2 = xk2 - xb[b, 2]
            f = lk * mb[b] * grad_w_factor(np.sqrt(e0 * e0 + e1 * e1 + e2 * e2), h)
            d0 += f * e0
            d1 += f * e1
            d2 += f * e2
        an = a * n_s[k]
        inv = 1.0 / (mk + an)
        x_out[k, 0] = (mk * s[k, 0] + an * (x[k, 0] + d0 / rho0)) * inv
        x_out[k, 1] = (mk * s[k, 1] + an * (x[k, 1] + d1 / rho0)) * inv
        x_out[k, 2] = (mk * s[k, 2] + an * (x[k, 2] + d2 / rho0)) * inv
        lam_sum[k] = an * inv * (lam_sum[k] + lk)
