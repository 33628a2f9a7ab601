"""Per-particle physics, written once: the body of every pass for one fluid particle i.

Each body is a plain function of i (and arrays and scalars): it gathers what it needs of i's
neighbours into a scratch block `buf` the launcher hands it, evaluates the kernel over that
contiguous block, and writes index i of its outputs only. Bodies allocate nothing, read no
globals and call only other bodies and the kernel formulas (`ipsph.kernels`), so the CPU
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

from ..kernels import FASTMATH, grad_w_factor, w

FAST = FASTMATH  # the one fastmath set (kernels.FASTMATH)

# The warm starts and the divergence residual skip particles with fewer fluid + wall neighbours
# (too few to trust their density rate: method.md section 2).
MIN_NEIGHBOURS_WARM = 20

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


@njit(inline="always", fastmath=FAST)
def _viscosity_sums(i, n_f, buf, h, eps, mf, standard, fill, pair_grad):
    """viscosity_at's neighbour loop; with `fill` (a constant at each call site) it also
    stores pair_grad[i, :, k] = mf grad W_ij."""
    a0 = a1 = a2 = 0.0  # XSPH: sum_j (1/rho_j) v_ij W_ij
    s0 = s1 = s2 = 0.0  # Standard viscosity: sum_j (1/rho_j) (v_ij . x_ij) / (r^2 + eps) grad W_ij
    p0 = p1 = p2 = 0.0  # PF displacement: sum_j (lam_i + lam_j) grad W_ij
    dr = 0.0  # sum_j v_ij . grad W_ij
    for k in range(n_f):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        r = math.sqrt(r2)
        u0, u1, u2 = buf[C1, k], buf[C2, k], buf[C3, k]
        inv_rho = buf[C4, k]
        wij = inv_rho * w(r, h)
        a0 += wij * u0
        a1 += wij * u1
        a2 += wij * u2
        g = grad_w_factor(r, h)
        ud = u0 * d0 + u1 * d1 + u2 * d2
        dr += g * ud
        if standard:  # loop-invariant: LLVM unswitches it, so nu = 0 pays no division
            sv = inv_rho * ud * g / (r2 + eps)
            s0 += sv * d0
            s1 += sv * d1
            s2 += sv * d2
        if fill:
            gm = mf * g
            pair_grad[i, 0, k] = gm * d0
            pair_grad[i, 1, k] = gm * d1
            pair_grad[i, 2, k] = gm * d2
        gl = buf[C5, k] * g
        p0 += gl * d0
        p1 += gl * d1
        p2 += gl * d2
    return a0, a1, a2, s0, s1, s2, p0, p1, p2, dr


# -- the bodies ----------------------------------------------------------------------------------
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
    sum_sq = g0 * g0 + g1 * g1 + g2 * g2 + s2
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
def density_residual_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, rho, alpha, rho0, dt, buf, rho_err, k):
    """Density-solve residual and stiffness [BK17 Alg. 3]:
    rho*_i = max(rho_i + dt D rho_i/Dt, rho0);  rho_err_i = rho*_i - rho0;  k_i = alpha_i rho_err_i / dt^2."""
    rate = density_rate_at(i, x, v, mf, gb, gvb, nf, cf, pair_grad, cached, h, buf)
    e = max(rho[i] + dt * rate, rho0) - rho0
    rho_err[i] = e
    k[i] = alpha[i] * e / (dt * dt)


@njit(inline="always", fastmath=FAST)
def stiffness_at(i, x, mf, gb, nf, cf, pair_grad, cached, h, k, dt, buf, v, k_total):
    """v_i -= dt [sum_j mf (k_i + k_j) grad W_ij + k_i gb_i];  k_total_i += k_i.

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
    v[i, 0] -= dt * (a0 + ki * gb[i, 0])
    v[i, 1] -= dt * (a1 + ki * gb[i, 1])
    v[i, 2] -= dt * (a2 + ki * gb[i, 2])
    k_total[i] += ki


@njit(inline="always", fastmath=FAST)
def viscosity_at(
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
):
    """The viscosity pass for particle i: XSPH filter [SB12] and SPlisHSPlasH's "Standard"
    viscosity, explicit:

        v_i <- v_i - zeta sum_j (mf / rho_j) (v_i - v_j) W_ij
                   + 10 nu dt sum_j (mf / rho_j) (v_ij . x_ij) / (r_ij^2 + 0.01 H^2) grad W_ij

    (Monaghan 2005's SPH Laplacian with the 2 (d + 2) = 10 of 3D, as SPlisHSPlasH's
    Viscosity_Standard without its wall term; nu_dt = nu dt, eps = 0.01 H^2). Walls take no part.
    By-products of the same neighbour loop:
        drho_i = D rho_i/Dt of the input velocities (walls through gb_i and gvb_i);
        disp_i = sum_j mf (lam_i + lam_j) grad W_ij + lam_i gb_i, with `with_disp`: rho0 times
                 the PF displacement of the multipliers lam (IPSPH's next warm start);
        pair_grad[i, :, k] = mf grad W_ij, with `fill`.
    """
    n_f = _gather_xf(i, x, nf, cf, buf)
    _gather_rate_f(i, v, nf, n_f, buf)
    li = lam[i] if with_disp else 0.0
    for k in range(n_f):
        j = nf[i, k]
        buf[C4, k] = 1.0 / rho[j]
        buf[C5, k] = li + lam[j] if with_disp else 0.0
    vi0, vi1, vi2 = v[i, 0], v[i, 1], v[i, 2]
    if fill:  # two copies of the loop, one with the cache's stores (a runtime test inside
        #       the loop stops LLVM vectorising it)
        a0, a1, a2, s0, s1, s2, p0, p1, p2, dr = _viscosity_sums(i, n_f, buf, h, eps, mf, standard, True, pair_grad)
    else:
        a0, a1, a2, s0, s1, s2, p0, p1, p2, dr = _viscosity_sums(i, n_f, buf, h, eps, mf, standard, False, pair_grad)
    drho[i] = mf * dr + vi0 * gb[i, 0] + vi1 * gb[i, 1] + vi2 * gb[i, 2] - gvb[i]
    zm = zeta * mf
    nm = 10.0 * nu_dt * mf
    v_out[i, 0] = vi0 - zm * a0 + nm * s0
    v_out[i, 1] = vi1 - zm * a1 + nm * s1
    v_out[i, 2] = vi2 - zm * a2 + nm * s2
    if with_disp:
        disp[i, 0] = mf * p0 + li * gb[i, 0]
        disp[i, 1] = mf * p1 + li * gb[i, 1]
        disp[i, 2] = mf * p2 + li * gb[i, 2]


@njit(inline="always", fastmath=FAST)
def pf_global_at(k, x, s, mf, gb, nf, cf, h, rho0, lam, a, buf, x_out, lam_sum):
    """One global step of Projective Fluids [WKB16] for particle k, with the constraint
    gradients of the local step (density_at, just before, at the same positions):

        d_k   = sum_{c in {k} u N(k)} lam_c G_ck
              = (1/rho0) [ sum_j mf (lam_k + lam_j) grad W_kj + lam_k gb_k ]
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
    x_out[k, 0] = (mf * s[k, 0] + an * (x[k, 0] + (mf * d0 + lk * gb[k, 0]) / rho0)) * inv
    x_out[k, 1] = (mf * s[k, 1] + an * (x[k, 1] + (mf * d1 + lk * gb[k, 1]) / rho0)) * inv
    x_out[k, 2] = (mf * s[k, 2] + an * (x[k, 2] + (mf * d2 + lk * gb[k, 2]) / rho0)) * inv
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


# -- the implicit viscosity (method.md section 10) -------------------------------------------------
@njit(inline="always")
def eps_of(h):
    """The Standard operator's regulariser 0.01 H^2 (SPlisHSPlasH's)."""
    return 0.01 * h * h


@njit(inline="always")
def _smallest_eigenvalue(a00, a11, a22, a01, a02, a12):
    """The smallest eigenvalue of a symmetric 3x3 matrix, in closed form (Smith 1961)."""
    q = (a00 + a11 + a22) / 3.0
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    p2 = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2 + 2.0 * p1
    if p2 <= 1e-300:
        return q
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    det = b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02)
    r = min(max(det / 2.0, -1.0), 1.0)
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0 + 2.0 * math.pi / 3.0)


@njit(inline="always", fastmath=FAST)
def viscous_setup_at(
    i, x, v, mf, rho, xb, mb, vb, nf, cf, nb, cb, h, rho0, nu_dt, wall_factor, full, buf, b, diag, wmat
):
    """The constant parts of the implicit viscosity system A v = b of particle i [WKBB18]:

        (A v)_i = v_i + nu dt sum_j V_j k_ij (x_ij . v_ij) x_ij + Wm_i (v_i - 0)
        b_i     = v_i + Wm_i vw_i
        diag_i  = the diagonal of A's 3x3 block of i             (the Jacobi preconditioner)

    k_ij = -10 g(r_ij) / (r_ij^2 + 0.01 H^2) >= 0 (grad W_ij = g(r_ij) x_ij: SPlisHSPlasH's Standard
    operator, 2 (d + 2) = 10 in 3D), V_j = mf / rho_j. `v` is the velocity before the solve.

    The walls [choice, method.md section 10] fill the part of i's neighbourhood the fluid leaves
    empty, moving with the walls' velocity: with F_i = sum_j V_j k_ij x_ij x_ij^T and the complete
    lattice's block (full / 3) I (`full`: its trace),

        Wm_i  = s_w nu dt psd((full / 3) I - F_i)          (6 entries: xx yy zz xy xz yz)
        vw_i  = sum_b V_b k_ib v_b / sum_b V_b k_ib         (V_b = m_b / rho0, the walls' velocity)

    for particles with wall neighbours (0 otherwise: a free surface takes no friction), s_w =
    wall_factor (1 no-slip, 0 free-slip); psd() lifts the block by its smallest eigenvalue when that
    is negative. Next to a flat box wall it reproduces a linear shear to 1 %; next to
    curved walls, where the lattice leaves gaps of 1-2 d, the gap counts as wall."""
    n_f = _gather_xf(i, x, nf, cf, buf)
    n_b = cb[i]
    _gather_diff(i, x, xb, nb, n_b, buf, DX, n_f)
    for k in range(n_f):
        buf[C0, k] = mf / rho[nf[i, k]]
    for k in range(n_b):
        bj = nb[i, k]
        buf[C0, n_f + k] = mb[bj] / rho0
        buf[C1, n_f + k] = vb[bj, 0]
        buf[C2, n_f + k] = vb[bj, 1]
        buf[C3, n_f + k] = vb[bj, 2]
    f00 = f11 = f22 = f01 = f02 = f12 = 0.0  # F_i = sum_j V_j k_ij x_ij x_ij^T
    for k in range(n_f):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        kv = -10.0 * buf[C0, k] * grad_w_factor(math.sqrt(r2), h) / (r2 + eps_of(h))
        f00 += kv * d0 * d0
        f11 += kv * d1 * d1
        f22 += kv * d2 * d2
        f01 += kv * d0 * d1
        f02 += kv * d0 * d2
        f12 += kv * d1 * d2
    kw = q0 = q1 = q2 = 0.0  # sum_b V_b k_ib (v_b)
    for k in range(n_f, n_f + n_b):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        kv = -10.0 * buf[C0, k] * grad_w_factor(math.sqrt(r2), h) / (r2 + eps_of(h))
        kw += kv
        q0 += kv * buf[C1, k]
        q1 += kv * buf[C2, k]
        q2 += kv * buf[C3, k]
    m00 = m11 = m22 = m01 = m02 = m12 = 0.0
    vw0 = vw1 = vw2 = 0.0
    if kw > 0.0 and wall_factor > 0.0:
        third = full / 3.0
        m00, m11, m22 = third - f00, third - f11, third - f22
        m01, m02, m12 = -f01, -f02, -f12
        low = _smallest_eigenvalue(m00, m11, m22, m01, m02, m12)
        if low < 0.0:  # lift the block to positive semi-definite (a compressed neighbourhood)
            m00 -= low
            m11 -= low
            m22 -= low
        sw = wall_factor * nu_dt
        m00, m11, m22, m01, m02, m12 = sw * m00, sw * m11, sw * m22, sw * m01, sw * m02, sw * m12
        vw0, vw1, vw2 = q0 / kw, q1 / kw, q2 / kw
    b[i, 0] = v[i, 0] + m00 * vw0 + m01 * vw1 + m02 * vw2
    b[i, 1] = v[i, 1] + m01 * vw0 + m11 * vw1 + m12 * vw2
    b[i, 2] = v[i, 2] + m02 * vw0 + m12 * vw1 + m22 * vw2
    diag[i, 0] = 1.0 + nu_dt * f00 + m00
    diag[i, 1] = 1.0 + nu_dt * f11 + m11
    diag[i, 2] = 1.0 + nu_dt * f22 + m22
    wmat[i, 0] = m00
    wmat[i, 1] = m11
    wmat[i, 2] = m22
    wmat[i, 3] = m01
    wmat[i, 4] = m02
    wmat[i, 5] = m12


@njit(inline="always", fastmath=FAST)
def viscous_apply_at(i, x, p, mf, rho, nf, cf, h, nu_dt, wmat, buf, out, pdot):
    """out_i = (A p)_i = p_i + nu dt sum_j V_j k_ij (x_ij . p_ij) x_ij + Wm_i p_i   (viscous_setup_at)
    and pdot_i = V_i p_i . out_i, the mass-weighted inner product's term (A is symmetric in it:
    conjugate gradients on sum_i V_i a_i . b_i, method.md section 10)."""
    eps = eps_of(h)
    n_f = _gather_xf(i, x, nf, cf, buf)
    _gather_diff(i, p, p, nf, n_f, buf, C1, 0)
    for k in range(n_f):
        buf[C0, k] = mf / rho[nf[i, k]]
    s0 = s1 = s2 = 0.0
    for k in range(n_f):
        d0, d1, d2 = buf[DX, k], buf[DY, k], buf[DZ, k]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        kv = -10.0 * buf[C0, k] * grad_w_factor(math.sqrt(r2), h) / (r2 + eps)
        xp = kv * (d0 * buf[C1, k] + d1 * buf[C2, k] + d2 * buf[C3, k])
        s0 += xp * d0
        s1 += xp * d1
        s2 += xp * d2
    p0, p1, p2 = p[i, 0], p[i, 1], p[i, 2]
    o0 = p0 + nu_dt * s0 + wmat[i, 0] * p0 + wmat[i, 3] * p1 + wmat[i, 4] * p2
    o1 = p1 + nu_dt * s1 + wmat[i, 3] * p0 + wmat[i, 1] * p1 + wmat[i, 5] * p2
    o2 = p2 + nu_dt * s2 + wmat[i, 4] * p0 + wmat[i, 5] * p1 + wmat[i, 2] * p2
    out[i, 0] = o0
    out[i, 1] = o1
    out[i, 2] = o2
    pdot[i] = mf / rho[i] * (p0 * o0 + p1 * o1 + p2 * o2)


@njit(inline="always")
def cg_precondition_at(i, r, diag, rho, mf, z, rz, rr):
    """Jacobi: z_i = r_i / diag_i (per component); rz_i = V_i r_i . z_i, rr_i = V_i r_i . r_i."""
    vi = mf / rho[i]
    a = b = 0.0
    for c in range(3):
        zc = r[i, c] / diag[i, c]
        z[i, c] = zc
        a += r[i, c] * zc
        b += r[i, c] * r[i, c]
    rz[i] = vi * a
    rr[i] = vi * b
