"""Per-particle bodies of the viscosity passes, written once like `bodies`: the explicit pass (XSPH
and SPlisHSPlasH's Standard viscosity, `viscosity_at`) and the implicit viscosity (method.md
section 10). Plain functions of one particle i that gather its neighbours into `buf` and write
index i only, inlined by the CPU launchers (`cpu_passes`) and compiled as device functions by the
CUDA ones (`cuda_passes`)."""

import math

from numba import njit

from .bodies import C0, C1, C2, C3, C4, C5, DX, DY, DZ, FAST, _gather_diff, _gather_rate_f, _gather_xf
from .kernels import grad_w_factor, w


# -- the explicit pass: XSPH and Standard viscosity ---------------------------------------------
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
    mirror,
):
    """The viscosity pass for particle i: XSPH filter [SB12] and SPlisHSPlasH's "Standard"
    viscosity, explicit:

        v_i <- v_i - zeta sum_j (mf / rho_j) (v_i - v_j) W_ij
                   + 10 nu dt sum_j (mf / rho_j) (v_ij . x_ij) / (r_ij^2 + 0.01 H^2) grad W_ij

    (Monaghan 2005's SPH Laplacian with the 2 (d + 2) = 10 of 3D, as SPlisHSPlasH's
    Viscosity_Standard without its wall term; nu_dt = nu dt, eps = 0.01 H^2). Walls take no part.
    By-products of the same neighbour loop:
        drho_i = D rho_i/Dt of the input velocities (walls through gb_i and gvb_i);
        disp_i = sum_j mf (lam_i + lam_j) grad W_ij + mirror lam_i gb_i, with `with_disp`: rho0 times
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
        lw = li if mirror == 1.0 else mirror * li
        disp[i, 0] = mf * p0 + lw * gb[i, 0]
        disp[i, 1] = mf * p1 + lw * gb[i, 1]
        disp[i, 2] = mf * p2 + lw * gb[i, 2]


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
def add_moment(f00, f11, f22, f01, f02, f12, kv, d0, d1, d2):
    """F + kv d d^T in 6 entries (xx yy zz xy xz yz): one neighbour's term of F_i = sum_j V_j k_ij x_ij x_ij^T."""
    return (
        f00 + kv * d0 * d0,
        f11 + kv * d1 * d1,
        f22 + kv * d2 * d2,
        f01 + kv * d0 * d1,
        f02 + kv * d0 * d2,
        f12 + kv * d1 * d2,
    )


@njit(inline="always", fastmath=FAST)
def friction_block(full, f00, f11, f22, f01, f02, f12):
    """psd((full / 3) I - F) in 6 entries: lifted by its smallest eigenvalue when that is negative
    (a compressed neighbourhood)."""
    third = full / 3.0
    m00, m11, m22 = third - f00, third - f11, third - f22
    m01, m02, m12 = -f01, -f02, -f12
    low = _smallest_eigenvalue(m00, m11, m22, m01, m02, m12)
    if low < 0.0:
        m00 -= low
        m11 -= low
        m22 -= low
    return m00, m11, m22, m01, m02, m12


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
        f00, f11, f22, f01, f02, f12 = add_moment(f00, f11, f22, f01, f02, f12, kv, d0, d1, d2)
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
        m00, m11, m22, m01, m02, m12 = friction_block(full, f00, f11, f22, f01, f02, f12)
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
