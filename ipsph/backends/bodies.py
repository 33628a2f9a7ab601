"""Per-particle physics, written once: the body of every pass for one fluid particle i.

Each body is a plain function of i (and arrays and scalars): it gathers what it needs of i's
neighbours into a scratch block `buf` the launcher hands it, evaluates the kernel over that
contiguous block, and writes index i of its outputs only. Bodies allocate nothing, read no
globals and call only other bodies and the kernel formulas (`ipsph.backends.kernels`), so the CPU
launcher (`cpu_passes`: `prange` over blocks of particles) inlines them today and a CUDA
launcher compiles the same functions as device functions (`cuda_passes`: `buf` a thread-local
array). Scalar maths goes through `math`, not numpy: `np.sqrt` of a scalar does not compile for
CUDA, `math.sqrt` compiles to the same instruction on both (the CPU results were bit-identical).

Notation (method.md sections 1-3): fluid neighbours j (one mass mf, a scalar), walls b with
effective mass m_b = rho0 Psi_b; x_ij = x_i - x_j, r_ij = |x_ij|, grad W_ij = g(r_ij) x_ij.
The lists: nf, cf (fluid indices, counts), nb, cb (walls). The pair cache pair_grad[i, :, k] =
mf grad W_ij, (n, 3, K), used only when it has a row per particle.

Why two stages per particle: the second loop has no indirection, so LLVM turns it into SIMD
code (the kernel's sqrt, division and polynomial on 4 neighbours at once), faster than one
scalar loop that does both (measured: docs/performance.md, "Measured design choices").
"""

import math

from numba import njit

from .kernels import FASTMATH, grad_w_factor, w

FAST = FASTMATH  # the one fastmath set (kernels.FASTMATH)

# The warm starts and the divergence residual skip particles with fewer fluid + wall neighbours
# (too few to trust their density rate: method.md section 2).
MIN_NEIGHBOURS_WARM = 20

# The density solve's tension with field walls (method.md section 11, "Two-sided density solve"): a
# particle within TENSION_BAND of rest density (rho_i >= (1 - TENSION_BAND) rho0) also resists its
# predicted expansion, at TENSION_WEIGHT of the compression's stiffness.
TENSION_BAND, TENSION_WEIGHT = 0.05, 0.5

# buffer rows: x_ij components, then per-neighbour scalars
DX, DY, DZ, C0, C1, C2, C3, C4, C5 = 0, 1, 2, 3, 4, 5, 6, 7, 8

# rows of scratch each body needs per neighbour slot (the launcher allocates them)
DENSITY_ROWS, RATE_ROWS, STIFFNESS_ROWS, VISCOSITY_ROWS, PF_GLOBAL_ROWS, WALL_RATE_ROWS = 6, 7, 4, 9, 4, 4
VISCOUS_SETUP_ROWS, VISCOUS_APPLY_ROWS = 7, 7  # the implicit viscosity's passes (method.md section 10)


# -- gathers -------------------------------------------------------------------------------------
@njit(inline="always")
def _gather_diff(i, a, b, nbr, n, buf, row, col):
    """buf[row..row + 2, col + k] = a_i - b_j over the first n neighbours j = nbr[i, k]."""
    a0, a1, a2 = a[i, 0], a[i, 1], a[i, 2]
    for k in range(n):
        j = nbr[i, k]
        buf[row, col + k] = a0 - b[j, 0]
        buf[row + 1, col + k] = a1 - b[j, 1]
        buf[row + 2, col + k] = a2 - b[j, 2]


@njit(inline="always")
def _gather_xf(i, x, nf, cf, buf):
    """buf[DX..DZ, :n_f] = x_i - x_j over the fluid neighbours; returns n_f."""
    n_f = cf[i]
    _gather_diff(i, x, x, nf, n_f, buf, DX, 0)
    return n_f


@njit(inline="always")
def _gather_x(i, x, xb, nf, cf, nb, cb, buf):
    """buf[DX..DZ, :n_f + n_b] = x_i - x_j (fluid first, then boundary); returns (n_f, n_b)."""
    n_f = _gather_xf(i, x, nf, cf, buf)
    n_b = cb[i]
    _gather_diff(i, x, xb, nb, n_b, buf, DX, n_f)
    return n_f, n_b


@njit(inline="always")
def _gather_rate_f(i, v, nf, n_f, buf):
    """buf[C1..C3] = v_i - v_j over the fluid neighbours: what D rho_i/Dt needs."""
    _gather_diff(i, v, v, nf, n_f, buf, C1, 0)


# -- vectorised sums over a gathered neighbourhood -------------------------------------------------
@njit(inline="always", fastmath=FAST)
def _weighted_gradient(n, buf, row, h):
    """sum_k buf[row, k] grad W(x_ik) over a gathered neighbourhood (the vectorised loop)."""
    a0 = a1 = a2 = 0.0
    for k in range(n):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        f = buf[row, k] * grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
        a0 += f * d0
        a1 += f * d1
        a2 += f * d2
    return a0, a1, a2


@njit(inline="always", fastmath=FAST)
def _density_sums(n, buf, h, rho_self, keep_f):
    """density_at's loop over fluid and walls (one loop: two were slower, docs/performance.md);
    rho starts from rho_self; with `keep_f` (a constant at each call site) f = m_k g(r_ik) is
    also left in buf[C2]."""
    rho_w = rho_self
    g0 = g1 = g2 = 0.0  # sum_k f_k x_ik
    b0 = b1 = b2 = 0.0  # its walls' part
    s2 = nn = 0.0  # sum over fluid of |f_k x_ik|^2; neighbours within H
    for k in range(n):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        r = math.sqrt(r2)
        mk = buf[C0, k]
        fluid = buf[C1, k]
        rho_w += mk * w(r, h)
        f = mk * grad_w_factor(r, h)
        g0 += f * d0
        g1 += f * d1
        g2 += f * d2
        fb = (1.0 - fluid) * f
        b0 += fb * d0
        b1 += fb * d1
        b2 += fb * d2
        s2 += fluid * f * f * r2
        nn += 1.0 if r < h else 0.0
        if keep_f:
            buf[C2, k] = f
    return rho_w, g0, g1, g2, b0, b1, b2, s2, nn


# -- the bodies ----------------------------------------------------------------------------------
@njit(inline="always", fastmath=FAST)
def density_core(i, x, mf, xb, mb, nf, cf, nb, cb, h, w0, fill, buf, pair_grad):
    """density_at's neighbour sums (and the pair cache with `fill`): rho_i, g_i, gb_i, sum_j |f_j|^2, count."""
    n_f, n_b = _gather_x(i, x, xb, nf, cf, nb, cb, buf)
    for k in range(n_f):
        buf[C0, k] = mf
        buf[C1, k] = 1.0  # fluid neighbours enter sum_j |m_j grad W_ij|^2, walls enter gb
    for k in range(n_b):
        buf[C0, n_f + k] = mb[nb[i, k]]
        buf[C1, n_f + k] = 0.0
    if fill:  # two copies of the loop (see viscosity_at), one also keeping f in buf[C2]
        rho_i, g0, g1, g2, b0, b1, b2, s2, nn = _density_sums(n_f + n_b, buf, h, mf * w0, True)
    else:
        rho_i, g0, g1, g2, b0, b1, b2, s2, nn = _density_sums(n_f + n_b, buf, h, mf * w0, False)
    if fill:
        for k in range(n_f):
            f = buf[C2, k]
            pair_grad[i, 0, k] = f * buf[DX, k]
            pair_grad[i, 1, k] = f * buf[DY, k]
            pair_grad[i, 2, k] = f * buf[DZ, k]
    return rho_i, g0, g1, g2, b0, b1, b2, s2, nn


@njit(inline="always", fastmath=FAST)
def density_store(i, rho0, rho_i, sum_sq, nn, b0, b1, b2, rho, alpha, lam, err, n_nbrs, gb):
    rho[i] = rho_i
    alpha[i] = 1.0 / max(sum_sq, 1e-5)
    c = max(rho_i / rho0 - 1.0, 0.0)
    err[i] = c
    lam[i] = -c / (sum_sq / (rho0 * rho0) + 1e-6)
    n_nbrs[i] = int(nn)
    gb[i, 0] = b0
    gb[i, 1] = b1
    gb[i, 2] = b2


@njit(inline="always", fastmath=FAST)
def density_at(i, x, mf, xb, mb, nf, cf, nb, cb, h, rho0, w0, fill, buf, rho, alpha, lam, err, n_nbrs, gb, pair_grad):
    """Density, DFSPH factor, PF multiplier, density error and wall gradient of particle i:

    rho_i   = mf W(0) + sum_j mf W_ij + sum_b m_b W_ib           (w0 = W(0))
    gb_i    = sum_b m_b grad W_ib     (the walls' part: fixed while positions are, so the
                                       pressure solves and the viscosity pass reuse it)
    g_i     = sum_j mf grad W_ij + gb_i
    alpha_i = 1 / max(|g_i|^2 + sum_j |mf grad W_ij|^2, 1e-5)           [BK17 eq. 9]
    C_i     = max(rho_i / rho0 - 1, 0)                                  [WKB16, unilateral]
    lam_i   = -C_i / (sum_k |G_ik|^2 + 1e-6),  sum_k |G_ik|^2 = (|g_i|^2 + sum_j |mf grad W_ij|^2) / rho0^2
    err_i   = C_i;  n_nbrs_i = |{j : r_ij < H}| + |{b : r_ib < H}|
    pair_grad[i, :, k] = mf grad W_ij   (only with `fill`)
    """
    rho_i, g0, g1, g2, b0, b1, b2, s2, nn = density_core(i, x, mf, xb, mb, nf, cf, nb, cb, h, w0, fill, buf, pair_grad)
    sum_sq = g0 * g0 + g1 * g1 + g2 * g2 + s2
    density_store(i, rho0, rho_i, sum_sq, nn, b0, b1, b2, rho, alpha, lam, err, n_nbrs, gb)


@njit(inline="always", fastmath=FAST)
def density_rate_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, buf):
    """D rho_i / Dt = sum_j mf (v_i - v_j) . grad W_ij + sum_b m_b (v_i - v_b) . grad W_ib
                    = sum_j mf (v_i - v_j) . grad W_ij + v_i . gb_i - gvb_i
    [BK17 eq. 4; gb: density_at; gvb_i = sum_b m_b v_b . grad W_ib: wall_rate_at, 0 for static walls].

    From the pair cache when `cached`, else from the positions."""
    n_f = cf[i]
    _gather_rate_f(i, v, nf, n_f, buf)
    walls = v[i, 0] * gb[i, 0] + v[i, 1] * gb[i, 1] + v[i, 2] * gb[i, 2] - gvb[i]
    rate = 0.0
    if cached:
        g = pair_grad[i]
        for k in range(n_f):
            rate += buf[C1, k] * g[0, k] + buf[C2, k] * g[1, k] + buf[C3, k] * g[2, k]
        return rate + walls
    _gather_xf(i, x, nf, cf, buf)
    for k in range(n_f):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        f = grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
        rate += f * (buf[C1, k] * d0 + buf[C2, k] * d1 + buf[C3, k] * d2)
    return mf * rate + walls


@njit(inline="always", fastmath=FAST)
def divergence_residual_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, alpha, n_nbrs, dt, buf, drho, k):
    """Divergence-solve residual and stiffness [BK17 Alg. 2]:
    drho_i = max(D rho_i/Dt, 0), zero for particles with < MIN_NEIGHBOURS_WARM neighbours; k_i = alpha_i drho_i / dt."""
    d = 0.0
    if n_nbrs[i] >= MIN_NEIGHBOURS_WARM:
        d = max(density_rate_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, buf), 0.0)
    drho[i] = d
    k[i] = alpha[i] * d / dt


@njit(inline="always", fastmath=FAST)
def density_residual_at(
    i, x, v, mf, gb, gvb, wb, nf, cf, pair_grad, cached, h, rho, alpha, rho0, dt, two_sided, buf, rho_err, k
):
    """Density-solve residual and stiffness [BK17 Alg. 3]:
    rho*_i = rho_i + dt D rho_i/Dt;  rho_err_i = max(rho*_i, rho0) - rho0;  k_i = alpha_i rho_err_i / dt^2.

    `two_sided` (field walls: their density wb has rows): where rho_i >= (1 - TENSION_BAND) rho0, rho_err_i += TENSION_WEIGHT
    min(rho*_i - rho0, 0), so a particle at rest density also resists being pulled apart."""
    rate = density_rate_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, buf)
    pred = rho[i] + dt * rate
    e = max(pred, rho0) - rho0
    if two_sided and rho[i] >= (1.0 - TENSION_BAND) * rho0:
        e += TENSION_WEIGHT * min(pred - rho0, 0.0)
    rho_err[i] = e
    k[i] = alpha[i] * e / (dt * dt)


@njit(inline="always", fastmath=FAST)
def _support_sum(i, n_f, nf, wm, pair_grad, cached, mf, h, buf, a0, a1, a2):
    """sum_j s_ij (M_i + M_j)/2 mf grad W_ij, s_ij = buf[C0, j] and (a0, a1, a2) = sum_j s_ij mf grad W_ij:
    (M_i a + sum_j s_ij M_j mf grad W_ij) / 2 (M the walls' support, wm: xx, yy, zz, xy, xz, yz).
    Neighbours without support (trace 0) are skipped; with the positions, buf holds x_ij (`_gather_xf`)."""
    m = wm[i]
    b0 = m[0] * a0 + m[3] * a1 + m[4] * a2
    b1 = m[3] * a0 + m[1] * a1 + m[5] * a2
    b2 = m[4] * a0 + m[5] * a1 + m[2] * a2
    for n in range(n_f):
        j = nf[i, n]
        if wm[j, 0] + wm[j, 1] + wm[j, 2] <= 0.0:
            continue
        if cached:
            q0, q1, q2 = pair_grad[i, 0, n], pair_grad[i, 1, n], pair_grad[i, 2, n]
        else:
            d0, d1, d2 = buf[DX, n], buf[DY, n], buf[DZ, n]
            f = mf * grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
            q0, q1, q2 = f * d0, f * d1, f * d2
        s = buf[C0, n]
        b0 += s * (wm[j, 0] * q0 + wm[j, 3] * q1 + wm[j, 4] * q2)
        b1 += s * (wm[j, 3] * q0 + wm[j, 1] * q1 + wm[j, 5] * q2)
        b2 += s * (wm[j, 4] * q0 + wm[j, 5] * q1 + wm[j, 2] * q2)
    return 0.5 * b0, 0.5 * b1, 0.5 * b2


@njit(inline="always", fastmath=FAST)
def stiffness_at(i, x, mf, gb, wm, nf, cf, pair_grad, cached, support, h, k, dt, buf, v, k_total, mirror):
    """v_i -= dt [sum_j mf (k_i + k_j) (I + (M_i + M_j)/2) grad W_ij + mirror k_i gb_i];  k_total_i += k_i.

    mirror: the walls' stiffness k_b = (mirror - 1) k_i (1: carried once, Akinci's; 2: mirrored).
    M: the field walls' support along their faces (wm; `support` when it has rows, else M = 0),
    symmetric in the pair, so the fluid's momentum stays conserved (method.md section 11).

    In place: reads k of the neighbours and writes v_i, k_total_i only. mf grad W_ij comes from
    the pair cache when `cached`, else from the positions."""
    ki = k[i]
    n_f = cf[i]
    for n in range(n_f):
        buf[C0, n] = ki + k[nf[i, n]]
    if cached:
        g = pair_grad[i]
        a0 = a1 = a2 = 0.0
        for n in range(n_f):
            s = buf[C0, n]
            a0 += s * g[0, n]
            a1 += s * g[1, n]
            a2 += s * g[2, n]
    else:
        _gather_xf(i, x, nf, cf, buf)
        a0, a1, a2 = _weighted_gradient(n_f, buf, C0, h)
        a0 *= mf
        a1 *= mf
        a2 *= mf
    if support:
        s0, s1, s2 = _support_sum(i, n_f, nf, wm, pair_grad, cached, mf, h, buf, a0, a1, a2)
        a0 += s0
        a1 += s1
        a2 += s2
    kw = ki if mirror == 1.0 else mirror * ki  # once: exactly the particle models' arithmetic
    v[i, 0] -= dt * (a0 + kw * gb[i, 0])
    v[i, 1] -= dt * (a1 + kw * gb[i, 1])
    v[i, 2] -= dt * (a2 + kw * gb[i, 2])
    k_total[i] += ki


@njit(inline="always", fastmath=FAST)
def pf_global_at(k, x, s, mf, gb, nf, cf, h, rho0, lam, a, buf, x_out, lam_sum, mirror):
    """One global step of Projective Fluids [WKB16] for particle k, with the constraint
    gradients of the local step (density_at, just before, at the same positions):

        d_k   = sum_{c in {k} u N(k)} lam_c G_ck
              = (1/rho0) [ sum_j mf (lam_k + lam_j) grad W_kj + mirror lam_k gb_k ]
        x_k  <- (mf s_k + a n_k (x_k + d_k)) / (mf + a n_k),        a = dt^2 k_s, n_k = |N(k)| + 1
        Lam_k <- beta_k (Lam_k + lam_k),  beta_k = a n_k / (mf + a n_k)    (pressure bookkeeping)

    The closed-form solve of PF's diagonal system as a gather: no atomics, deterministic.
    """
    n_f = _gather_xf(k, x, nf, cf, buf)
    lk = lam[k]
    for n in range(n_f):
        buf[C0, n] = lk + lam[nf[k, n]]
    d0, d1, d2 = _weighted_gradient(n_f, buf, C0, h)
    an = a * (cf[k] + 1)  # n_k: the lists were built at s
    inv = 1.0 / (mf + an)
    lw = lk if mirror == 1.0 else mirror * lk
    x_out[k, 0] = (mf * s[k, 0] + an * (x[k, 0] + (mf * d0 + lw * gb[k, 0]) / rho0)) * inv
    x_out[k, 1] = (mf * s[k, 1] + an * (x[k, 1] + (mf * d1 + lw * gb[k, 1]) / rho0)) * inv
    x_out[k, 2] = (mf * s[k, 2] + an * (x[k, 2] + (mf * d2 + lw * gb[k, 2]) / rho0)) * inv
    lam_sum[k] = an * inv * (lam_sum[k] + lk)


@njit(inline="always", fastmath=FAST)
def wall_rate_at(i, x, xb, mb, vb, nb, cb, h, buf, gvb):
    """The moving walls' part of D rho_i/Dt: gvb_i = sum_b m_b v_b . grad W_ib (v_b the wall
    particles' velocities; density_rate_at subtracts it). Only run when walls move: static walls
    leave gvb = 0, so their scenes compute exactly what they did before walls could move."""
    n_b = cb[i]
    _gather_diff(i, x, xb, nb, n_b, buf, DX, 0)
    for k in range(n_b):
        b = nb[i, k]
        buf[C0, k] = mb[b] * (vb[b, 0] * buf[DX, k] + vb[b, 1] * buf[DY, k] + vb[b, 2] * buf[DZ, k])
    s = 0.0
    for k in range(n_b):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        s += buf[C0, k] * grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
    gvb[i] = s
