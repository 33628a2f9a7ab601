"""Per-particle bodies of field walls (wall model "field", method.md section 11): the walls seen as
geometry, one evaluation per fluid particle and wall object, no wall particles.

Each wall object k is a shape in its own frame (a box of half extents e_k, a ball of radius R_k)
placed by a rotation R_k and a position c_k: x_l = R_k^T (x - c_k). Its solid is the shape (an
obstacle or a body, sign +1) or the shape's complement (a container, sign -1, fluid inside).
`object_distance` gives the signed distance phi (positive in the fluid; `wall_field.box_distance`,
a ball's, a mesh grid's); the passes read the wall potential of phi (`object_potential`: a box
container per face, everything else through its one phi), and the potentials add (method.md
section 11):

    mu_i = sum_k mu_k(x_i),   rho_b,i = rho0 (1 - exp(-mu_i)),   gb_i = rho0 exp(-mu_i) sum_k grad mu_k
    gvb_i = rho0 exp(-mu_i) sum_k grad mu_k . v_k(x_i),   v_k(x) = u_k + omega_k x (x - c_k)

rho_b and gb take the place of the wall particles' sum_b m_b W_ib and sum_b m_b grad W_ib in
`bodies.density_at`, so every later pass reads the walls through gb and gvb as it does with
particles, each once (the wall term k_i gb_i is the gradient of the density it reads).

A mesh is a GRID object: its (phi, I) grid (the potential reads phi) in the body frame (`field_grid`, built by
`boundary.mesh_field`), grid number size_k[0] in the header `hdr` and the shared `pool`.

The objects travel as one tuple of arrays, `objects` (`boundary.field_walls.FieldWalls.arrays`):
(kind, sign, rot, pos, size, reach, vel, omega, qtab, otab, hdr, pool). `reach` culls: a box or
ball is skipped when x_l lies farther than reach_k outside its bounding box (obstacles), or deeper
than reach_k inside it (containers), where I_k = 0; a grid culls itself (I = 0 off the grid).
"""

import math

from numba import njit

from .bodies import density_core, density_store
from .field_grid import grid_distance
from .kernels import FASTMATH
from .wall_field import box_distance, box_potential, box_support, face_potential, face_support

FAST = FASTMATH

BOX, SPHERE, GRID = 0, 1, 2  # object kinds (boundary.field_walls.KINDS names them)
# Field walls have no neighbours to count: a wall reading of Lambda counts as FIELD_NEIGHBOURS Lambda
# (a flat face reads tau0 = 0.1497 at the first layer, the ~9 wall particles of an Akinci face grid).
FIELD_NEIGHBOURS = 60.0


@njit(inline="always", fastmath=FAST)
def _local(k, p0, p1, p2, rot, pos):
    """x_l = R_k^T (x - c_k) and the offset x - c_k."""
    d0, d1, d2 = p0 - pos[k, 0], p1 - pos[k, 1], p2 - pos[k, 2]
    l0 = rot[k, 0, 0] * d0 + rot[k, 1, 0] * d1 + rot[k, 2, 0] * d2
    l1 = rot[k, 0, 1] * d0 + rot[k, 1, 1] * d1 + rot[k, 2, 1] * d2
    l2 = rot[k, 0, 2] * d0 + rot[k, 1, 2] * d1 + rot[k, 2, 2] * d2
    return l0, l1, l2, d0, d1, d2


@njit(inline="always", fastmath=FAST)
def _culled(k, l0, l1, l2, kind, sign, size, reach):
    """True where object k cannot reach x_l (its I_k is 0 there)."""
    if kind[k] == GRID:
        return False
    if kind[k] == SPHERE:
        r = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        out = r - size[k, 0]
        return out > reach[k] if sign[k] > 0.0 else out < -reach[k]
    o0, o1, o2 = abs(l0) - size[k, 0], abs(l1) - size[k, 1], abs(l2) - size[k, 2]
    if sign[k] > 0.0:
        return o0 > reach[k] or o1 > reach[k] or o2 > reach[k]
    return o0 < -reach[k] and o1 < -reach[k] and o2 < -reach[k]


@njit(inline="always", fastmath=FAST)
def _to_world(k, rot, g0, g1, g2):
    """A vector of object k's frame in world axes: R_k g."""
    return (
        rot[k, 0, 0] * g0 + rot[k, 0, 1] * g1 + rot[k, 0, 2] * g2,
        rot[k, 1, 0] * g0 + rot[k, 1, 1] * g1 + rot[k, 1, 2] * g2,
        rot[k, 2, 0] * g0 + rot[k, 2, 1] * g1 + rot[k, 2, 2] * g2,
    )


@njit(inline="always", fastmath=FAST)
def _local_distance(k, l0, l1, l2, kind, sign, size, hdr, pool):
    """(phi, grad phi) of object k at the point l of its own frame, in its axes, positive in the fluid."""
    if kind[k] == GRID:
        f, f0, f1, f2 = grid_distance(hdr, int(size[k, 0]), pool, l0, l1, l2)
    elif kind[k] == SPHERE:
        s = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        n0, n1, n2 = (l0 / s, l1 / s, l2 / s) if s > 0.0 else (0.0, 0.0, 1.0)
        f, f0, f1, f2 = s - size[k, 0], n0, n1, n2
    else:
        f, f0, f1, f2 = box_distance(l0, l1, l2, size[k, 0], size[k, 1], size[k, 2])
    if sign[k] < 0.0:  # a container: the fluid inside the shape
        f, f0, f1, f2 = -f, -f0, -f1, -f2
    return f, f0, f1, f2


@njit(inline="always", fastmath=FAST)
def object_distance(k, p0, p1, p2, objects):
    """(phi, grad phi) of object k at the world point p, in world axes, phi positive in the fluid (the
    projection and the host's distance queries; the passes read the potential, object_potential)."""
    kind, sign, rot, pos, size, _, _, _, _, _, hdr, pool = objects
    l0, l1, l2, _, _, _ = _local(k, p0, p1, p2, rot, pos)
    f, f0, f1, f2 = _local_distance(k, l0, l1, l2, kind, sign, size, hdr, pool)
    w0, w1, w2 = _to_world(k, rot, f0, f1, f2)
    return f, w0, w1, w2


@njit(inline="always", fastmath=FAST)
def object_velocity(k, d0, d1, d2, vel, omega):
    """v_k(x) = u_k + omega_k x (x - c_k), given d = x - c_k."""
    a0, a1, a2 = omega[k, 0], omega[k, 1], omega[k, 2]
    return vel[k, 0] + a1 * d2 - a2 * d1, vel[k, 1] + a2 * d0 - a0 * d2, vel[k, 2] + a0 * d1 - a1 * d0


@njit(inline="always", fastmath=FAST)
def object_potential(k, p0, p1, p2, h, b, reach, objects):
    """(mu, grad mu) of object k at the world point p, in world axes (the wall potential of
    `wall_field.box_potential`; a ball and a grid read their signed distance)."""
    kind, sign, rot, pos, size, _, _, _, _, _, hdr, pool = objects
    l0, l1, l2, _, _, _ = _local(k, p0, p1, p2, rot, pos)
    container = sign[k] < 0.0
    if kind[k] == BOX:
        m, m0, m1, m2 = box_potential(l0, l1, l2, size[k, 0], size[k, 1], size[k, 2], h, container, b, reach)
    else:  # a ball and a grid read their signed distance
        f, f0, f1, f2 = _local_distance(k, l0, l1, l2, kind, sign, size, hdr, pool)
        m, dm = face_potential(f / h, b, reach)
        m0, m1, m2 = dm * f0 / h, dm * f1 / h, dm * f2 / h
    w0, w1, w2 = _to_world(k, rot, m0, m1, m2)
    return m, w0, w1, w2


@njit(inline="always", fastmath=FAST)
def _object_support(k, l0, l1, l2, mk, n0, n1, n2, h, b, u_reach, kind, sign, rot, size):
    """Object k's support M_k = sum_f c_f (I - n_f n_f) in world axes, as (xx, yy, zz, xy, xz, yz): a box
    container per face (`wall_field.box_support`, turned by R_k: R diag R^T), anything else through its
    one potential mk and its gradient n (c(mk) (I - n n), n = grad mu / |grad mu|)."""
    if kind[k] == BOX and sign[k] < 0.0:
        a0, a1, a2 = box_support(l0, l1, l2, size[k, 0], size[k, 1], size[k, 2], h, b, u_reach)
        r = rot
        m00 = r[k, 0, 0] * r[k, 0, 0] * a0 + r[k, 0, 1] * r[k, 0, 1] * a1 + r[k, 0, 2] * r[k, 0, 2] * a2
        m11 = r[k, 1, 0] * r[k, 1, 0] * a0 + r[k, 1, 1] * r[k, 1, 1] * a1 + r[k, 1, 2] * r[k, 1, 2] * a2
        m22 = r[k, 2, 0] * r[k, 2, 0] * a0 + r[k, 2, 1] * r[k, 2, 1] * a1 + r[k, 2, 2] * r[k, 2, 2] * a2
        m01 = r[k, 0, 0] * r[k, 1, 0] * a0 + r[k, 0, 1] * r[k, 1, 1] * a1 + r[k, 0, 2] * r[k, 1, 2] * a2
        m02 = r[k, 0, 0] * r[k, 2, 0] * a0 + r[k, 0, 1] * r[k, 2, 1] * a1 + r[k, 0, 2] * r[k, 2, 2] * a2
        m12 = r[k, 1, 0] * r[k, 2, 0] * a0 + r[k, 1, 1] * r[k, 2, 1] * a1 + r[k, 1, 2] * r[k, 2, 2] * a2
        return m00, m11, m22, m01, m02, m12
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if nn <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    c = face_support(mk)
    q = c / nn
    return c - q * n0 * n0, c - q * n1 * n1, c - q * n2 * n2, -q * n0 * n1, -q * n0 * n2, -q * n1 * n2


@njit(inline="always", fastmath=FAST)
def wall_field_at(i, x, h, rho0, wall, objects, wb, gw, gvb, ws, wm, support):
    """The walls' density wb_i = rho0 Lambda_i, Lambda_i = 1 - exp(-sum_k mu_k(x_i)), its gradient
    gw_i = rho0 exp(-mu) sum_k grad mu_k, the moving walls' rate term gvb_i = sum_k gw_i,k . v_k(x_i)
    and the support along the faces wm_i = sum_k M_k(x_i) (`_object_support`, where wm has rows:
    `support`; method.md section 11;
    wall = (b, U) of `wall_field.face_potential`). ws_i = 0: the potential carries the wall pressure
    once, with no hydrostatic increment."""
    kind, sign, rot, pos, size, reach, vel, omega, qtab, otab, hdr, pool = objects
    b, u_reach, s_wall = wall
    p0, p1, p2 = x[i, 0], x[i, 1], x[i, 2]
    m = g0 = g1 = g2 = gv = 0.0
    s00 = s11 = s22 = s01 = s02 = s12 = 0.0
    for k in range(kind.shape[0]):
        l0, l1, l2, d0, d1, d2 = _local(k, p0, p1, p2, rot, pos)
        if _culled(k, l0, l1, l2, kind, sign, size, reach):
            continue
        mk, n0, n1, n2 = object_potential(k, p0, p1, p2, h, b, u_reach, objects)
        m += mk
        g0 += n0
        g1 += n1
        g2 += n2
        u0, u1, u2 = object_velocity(k, d0, d1, d2, vel, omega)
        gv += n0 * u0 + n1 * u1 + n2 * u2
        if support and mk > 0.0:
            t00, t11, t22, t01, t02, t12 = _object_support(
                k, l0, l1, l2, mk, n0, n1, n2, h, b, u_reach, kind, sign, rot, size
            )
            s00 += t00
            s11 += t11
            s22 += t22
            s01 += t01
            s02 += t02
            s12 += t12
    if support:
        wm[i, 0], wm[i, 1], wm[i, 2], wm[i, 3], wm[i, 4], wm[i, 5] = s00, s11, s22, s01, s02, s12
    if m <= 0.0:
        wb[i] = 0.0
        gw[i, 0] = gw[i, 1] = gw[i, 2] = 0.0
        gvb[i] = 0.0
        ws[i] = 0.0
        return
    ws[i] = s_wall * h
    e = math.exp(-m)
    s = rho0 * e
    wb[i] = rho0 * (1.0 - e)
    gw[i, 0] = s * g0
    gw[i, 1] = s * g1
    gw[i, 2] = s * g2
    gvb[i] = s * gv


@njit(inline="always", fastmath=FAST)
def wall_pressure_at(i, gw, ws, g0, g1, g2, rho0, dt, v):
    """The hydrostatic part of the mirrored wall pressure (brief section 4): the wall's pressure is
    the particle's plus rho0 |g.n| s below it, n = -gw/|gw| out of the wall, so i gains

        v_i += dt (g . n) (s_i / rho0) gw_i = -dt (g . gw_i) / |gw_i| (s_i / rho0) gw_i

    once per step (static walls; a moving wall's acceleration is not included)."""
    n2 = gw[i, 0] * gw[i, 0] + gw[i, 1] * gw[i, 1] + gw[i, 2] * gw[i, 2]
    if n2 <= 0.0:
        return
    c = -dt * (g0 * gw[i, 0] + g1 * gw[i, 1] + g2 * gw[i, 2]) / math.sqrt(n2) * ws[i] / rho0
    v[i, 0] += c * gw[i, 0]
    v[i, 1] += c * gw[i, 1]
    v[i, 2] += c * gw[i, 2]


@njit(inline="always", fastmath=FAST)
def wall_project_at(i, x, v, h, phi_min, objects, moved):
    """Keep particle i at least phi_min outside every wall surface: where phi_k(x_i) < phi_min, move
    it out along grad phi_k by the difference and remove its velocity towards the wall relative to
    the wall's (brief section 8, pitfall 3). moved_i = how many objects pushed it (0, 1, ...)."""
    kind, sign, rot, pos, size, reach, vel, omega, qtab, otab, hdr, pool = objects
    count = 0
    for k in range(kind.shape[0]):
        p0, p1, p2 = x[i, 0], x[i, 1], x[i, 2]
        l0, l1, l2, d0, d1, d2 = _local(k, p0, p1, p2, rot, pos)
        if _culled(k, l0, l1, l2, kind, sign, size, reach):
            continue
        f, g0, g1, g2 = _local_distance(k, l0, l1, l2, kind, sign, size, hdr, pool)
        if f >= phi_min:
            continue
        n0, n1, n2 = _to_world(k, rot, g0, g1, g2)
        norm = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if norm < 1e-12:
            continue
        n0, n1, n2 = n0 / norm, n1 / norm, n2 / norm
        push = phi_min - f
        x[i, 0] = p0 + push * n0
        x[i, 1] = p1 + push * n1
        x[i, 2] = p2 + push * n2
        u0, u1, u2 = object_velocity(k, d0, d1, d2, vel, omega)
        vn = (v[i, 0] - u0) * n0 + (v[i, 1] - u1) * n1 + (v[i, 2] - u2) * n2
        if vn < 0.0:
            v[i, 0] -= vn * n0
            v[i, 1] -= vn * n1
            v[i, 2] -= vn * n2
        count += 1
    moved[i] = count


@njit(inline="always", fastmath=FAST)
def field_density_at(
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
    buf,
    rho,
    alpha,
    lam,
    err,
    n_nbrs,
    gb,
    pair_grad,
    wb,
    gw,
    mirror,
):
    """density_at with field walls (field_bodies.wall_field_at: their density wb_i and its gradient
    gw_i) added to the sums, and the walls' pressure share `mirror` in the factor:

    rho_i  += wb_i;  gb_i += gw_i;  g_i += gw_i;  n_nbrs_i += FIELD_NEIGHBOURS wb_i / rho0
    alpha_i = 1 / max(|g_i|^2 + (mirror - 1) gb_i . g_i + sum_j |mf grad W_ij|^2, 1e-5)
              (the pressure passes apply mirror k_i gb_i at the walls: 1 once, 2 mirrored)
    """
    rho_i, g0, g1, g2, b0, b1, b2, s2, nn = density_core(i, x, mf, xb, mb, nf, cf, nb, cb, h, w0, fill, buf, pair_grad)
    rho_i += wb[i]
    b0 += gw[i, 0]
    b1 += gw[i, 1]
    b2 += gw[i, 2]
    g0 += gw[i, 0]
    g1 += gw[i, 1]
    g2 += gw[i, 2]
    nn += FIELD_NEIGHBOURS * wb[i] / rho0
    sum_sq = g0 * g0 + g1 * g1 + g2 * g2 + (mirror - 1.0) * (b0 * g0 + b1 * g1 + b2 * g2) + s2
    density_store(i, rho0, rho_i, sum_sq, nn, b0, b1, b2, rho, alpha, lam, err, n_nbrs, gb)
