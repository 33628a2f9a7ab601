"""Walls as geometry ("field" wall model): per-particle maths of the kernel integral of a solid.

A wall object with solid Omega gives a fluid particle at x (design brief boundary-fields.md, sections
3 and 7; H = 4r = 2d the support, q = y/H; lengths in units of H unless named) its signed distance
phi (positive in the fluid) and the exact kernel mass I(x) = int_Omega W(x - x') dx'.

Half space (the solid beyond a plane at distance y = qH), closed form for the cubic spline:

    Phi(q) = 1/2 - 7q/5 + 8q^3/3 - 24q^5/5 + 16q^6/5     0 <= q <= 1/2
           = (8/15)(1 - q)^5 (1 + 2q)                     1/2 < q <= 1,   0 beyond;   Phi(-q) = 1 - Phi(q)
    A(q)   = -dPhi/dq = (7 - 40q^2 + 120q^4 - 96q^5)/5    q <= 1/2,   (8/5)(1 - q)^4 (1 + 4q) beyond;   A(-q) = A(q)

The wall's reading (its density in units of rho0), delta the lattice calibration (delta/H =
`ipsph.boundary.field.DELTA_H`, an argument here): psi = H Phi^-1(I) and

    Lambda(I) = Phi((psi + delta)/H),   dLambda/dI = A((psi + delta)/H) / A(psi/H)

Quarter space and octant (the solid beyond two / three orthogonal planes at distances a, b, c >= 0):

    Q(a, b)    = Phi(a) Phi(b) + R(a, b)
    O(a, b, c) = Phi(a) Phi(b) Phi(c) + Phi(a) R(b, c) + Phi(b) R(a, c) + Phi(c) R(a, b) + T(a, b, c)

with R and T interpolated by the C1 bicubic / tricubic Hermite interpolants of their values and
mixed first derivatives at nodes i/n, stored per cell as polynomial coefficients (qtab[i, j, p, q],
otab[i, j, k, p, q, r], built by `ipsph.boundary.field.tables`). As Q(0, b) = Phi(b)/2 and
O(0, b, c) = Q(b, c)/2, R and T vanish with their in-face slopes on a = 0 (and b, c = 0), and so do
their interpolants: a box's terms join across its faces without a jump. Gradients are the
interpolants' own; every term is 0 from an argument of 1 on (the data are 0 on those planes).

Box (inclusion-exclusion, brief section 7): along each axis the slab |u| <= e is, within a support,
1 - chi(e - u) - chi(e + u) inside and chi(|u| - e) - chi(|u| + e) beyond, chi(t) the half space
{xi > t}; the product over the axes expands into 1, Phi, Q and O of non-negative arguments.
Ball of radius R at distance s: I(s) = [s < R] M(R - s) + int_{|R-s|}^{min(R+s,1)} 2 pi r^2 w(r)
(1 + kappa) dr, kappa = (R^2 - s^2 - r^2)/(2 s r), M(rho) the kernel mass within rho (closed form).

Like `bodies`, device functions: scalar `math`, no allocation, no globals but module constants,
tuples out; they compile with numba njit and as numba-cuda device functions, and import nothing
from ipsph. All are inline="always": numba-cuda compiles a called function that is not inlined
for the current device, which a PTX build without a GPU does not have. Numba's inliner costs grow
with the square of a callee's IR, hence the tables' Horner loops and few, small call sites.
*_field functions return (phi, dphi/dx, dphi/dy, dphi/dz, I, dI/dx, dI/dy, dI/dz) in the object's
frame and physical units.
"""

import math

from numba import njit

FAST = {"contract", "arcp", "reassoc"}  # = ipsph.kernels.FASTMATH (no nnan/ninf: NaN checks keep working)

_C = 8.0 / math.pi  # the kernel's constant in units of H: w(r) = _C f(r)


# -- half space ------------------------------------------------------------------------------------
@njit(inline="always", fastmath=FAST)
def _phi_a(u):
    """(Phi(u), A(u)) for u >= 0, branch-free (numba's inliner pays for every block): the outer
    pieces minus what the inner ones differ by, a multiple of (1/2 - u)^5 and (1/2 - u)^4:
    Phi = (8/15)(1 - u)+^5 (1 + 2u) - (16/15)(1/2 - u)+^5 (1 + 4u),
    A   = (8/5)(1 - u)+^4 (1 + 4u) - (16/5)(1/2 - u)+^4 (1 + 8u)."""
    v, w = max(1.0 - u, 0.0), max(0.5 - u, 0.0)
    v4, w4 = v * v * v * v, w * w * w * w
    return (8.0 / 15.0) * v4 * v * (1.0 + 2.0 * u) - (16.0 / 15.0) * w4 * w * (1.0 + 4.0 * u), 1.6 * v4 * (
        1.0 + 4.0 * u
    ) - 3.2 * w4 * (1.0 + 8.0 * u)


@njit(inline="always", fastmath=FAST)
def half_mass(q):
    """Phi(q): the kernel mass beyond a plane at signed distance q H (q < 0: the point is inside)."""
    m = _phi_a(abs(q))[0]
    return m if q >= 0.0 else 1.0 - m


@njit(inline="always", fastmath=FAST)
def half_density(q):
    """A(q) = -dPhi/dq = H |dPhi/dy|: the kernel's 1D marginal at q (even in q)."""
    return _phi_a(abs(q))[1]


@njit(inline="always", fastmath=FAST)
def half_mass_inv(m):
    """q = Phi^-1(m) in [-1, 1] (psi = H q): Newton on G(u) = Phi(u)^(1/5) - t^(1/5), t = min(m, 1 - m),
    inside a bisection bracket. The fifth root keeps the root simple as u -> 1, where
    Phi ~ (8/5)(1 - u)^5; from the guess below Newton reaches 1e-15 in 3 steps (30 allowed)."""
    if m <= 0.0:
        return 1.0
    if m >= 1.0:
        return -1.0
    t = m if m <= 0.5 else 1.0 - m
    tau = t**0.2
    lo, hi = 0.0, 1.0  # G(lo) >= 0 >= G(hi)
    # u ~ 1 - tau P(tau), P a least-squares fit (3e-3 in u): at most 3 Newton steps (measured)
    u = min(max(1.0 - tau * (0.86549957 + tau * (0.55517878 + tau * (-1.12221606 + 0.98002063 * tau))), 0.0), 1.0)
    for _ in range(30):
        p = half_mass(u)
        p5 = p**0.2
        lo, hi = (u, hi) if p5 > tau else (lo, u)
        a = half_density(u)
        un = u + (p5 - tau) * 5.0 * p / (a * p5) if a > 0.0 and p > 0.0 else -1.0  # G' = -A Phi^(1/5) / (5 Phi)
        un = un if lo <= un <= hi else 0.5 * (lo + hi)
        if abs(un - u) <= 1e-9:  # quadratic convergence: this step leaves < 1e-15
            return un if m <= 0.5 else -un
        u = un
    return u if m <= 0.5 else -u


@njit(inline="always", fastmath=FAST)
def wall_reading(mass, delta_h):
    """The calibrated reading of a wall of kernel mass I = `mass`, delta_h = delta/H:
    returns (Lambda, dLambda/dI, psi/H). dLambda/dI = A(q + delta_h)/A(q) grows without bound as
    I -> 1 (deep inside a solid), where dI/dx -> 0: the denominator is floored at 1e-30 only."""
    q = half_mass_inv(mass)
    qd = q + delta_h
    lam = half_mass(qd)
    ad = half_density(qd)
    dlam = ad / max(half_density(q), 1e-30) if ad > 0.0 else 0.0
    return lam, dlam, q


# -- tables: quarter space and octant ------------------------------------------------------------------
@njit(inline="always", fastmath=FAST)
def _table2(a, b, tab):
    """The bicubic of the cell holding (a, b) in [0, 1]^2 on n cells: tab[i, j, p, q] multiplies
    ta^p tb^q, ta = n a - i; returns (f, df/da, df/db) (Horner, derivatives alongside)."""
    n = tab.shape[0]
    pa, pb = min(max(a, 0.0), 1.0) * n, min(max(b, 0.0), 1.0) * n
    i, j = min(int(pa), n - 1), min(int(pb), n - 1)
    ta, tb = pa - i, pb - j
    v = ga = gb = 0.0
    for p in range(3, -1, -1):
        vb = db = 0.0
        for q in range(3, -1, -1):
            db = db * tb + vb
            vb = vb * tb + tab[i, j, p, q]
        ga = ga * ta + v
        v = v * ta + vb
        gb = gb * ta + db
    return v, ga * n, gb * n


@njit(inline="always", fastmath=FAST)
def _table3(a, b, c, tab):
    """The tricubic of the cell holding (a, b, c): tab[i, j, k, p, q, r] multiplies ta^p tb^q tc^r;
    returns (f, grad f)."""
    n = tab.shape[0]
    pa, pb, pc = min(max(a, 0.0), 1.0) * n, min(max(b, 0.0), 1.0) * n, min(max(c, 0.0), 1.0) * n
    i, j, k = min(int(pa), n - 1), min(int(pb), n - 1), min(int(pc), n - 1)
    ta, tb, tc = pa - i, pb - j, pc - k
    v = ga = gb = gc = 0.0
    for p in range(3, -1, -1):
        vb = db = dcb = 0.0
        for q in range(3, -1, -1):
            vc = dc = 0.0
            for r in range(3, -1, -1):
                dc = dc * tc + vc
                vc = vc * tc + tab[i, j, k, p, q, r]
            db = db * tb + vb
            vb = vb * tb + vc
            dcb = dcb * tb + dc
        ga = ga * ta + v
        v = v * ta + vb
        gb = gb * ta + db
        gc = gc * ta + dcb
    return v, ga * n, gb * n, gc * n


@njit(inline="always", fastmath=FAST)
def _half(t):
    """(Phi(t), dPhi/dt) for an argument present (t >= 0); (1, 0) for one left out (t < 0)."""
    f = 0.5 + math.copysign(0.5, t)  # 1 present, 0 left out (arithmetic: no blocks for the inliner)
    p, a = _phi_a(max(t, 0.0))
    return f * p + (1.0 - f), -f * a


@njit(inline="always", fastmath=FAST)
def orthant_mass(a, b, c, qtab, otab):
    """Kernel mass of {xi > a, eta > b, zeta > c} (units of H) with (M, dM/da, dM/db, dM/dc); an
    argument < 0 leaves its half space out (Phi = 1, its R and T terms 0), so one code path gives
    1, Phi, Q (two arguments) and O: M = prod Phi + sum_m Phi_m R~(other two) + T~."""
    if max(a, b, c) >= 1.0:
        return 0.0, 0.0, 0.0, 0.0
    p0, d0 = _half(a)
    p1, d1 = _half(b)
    p2, d2 = _half(c)
    fa, fb, fc = a >= 0.0, b >= 0.0, c >= 0.0  # `&`, not `and`: no short-circuit blocks
    v, g0, g1, g2 = p0 * p1 * p2, d0 * p1 * p2, p0 * d1 * p2, p0 * p1 * d2
    if fb & fc:
        r, rb, rc = _table2(b, c, qtab)
        v, g0, g1, g2 = v + p0 * r, g0 + d0 * r, g1 + p0 * rb, g2 + p0 * rc
    if fa & fc:
        r, ra, rc = _table2(a, c, qtab)
        v, g0, g1, g2 = v + p1 * r, g0 + p1 * ra, g1 + d1 * r, g2 + p1 * rc
    if fa & fb:
        r, ra, rb = _table2(a, b, qtab)
        v, g0, g1, g2 = v + p2 * r, g0 + p2 * ra, g1 + p2 * rb, g2 + d2 * r
    if fa & fb & fc:
        t, ta, tb, tc = _table3(a, b, c, otab)
        v, g0, g1, g2 = v + t, g0 + ta, g1 + tb, g2 + tc
    return v, g0, g1, g2


@njit(inline="always", fastmath=FAST)
def quarter_mass(a, b, qtab, otab):
    """(Q, dQ/da, dQ/db) for a, b >= 0: Q = Phi(a) Phi(b) + R~(a, b)."""
    m, da, db, _ = orthant_mass(a, b, -1.0, qtab, otab)
    return m, da, db


@njit(inline="always", fastmath=FAST)
def octant_mass(a, b, c, qtab, otab):
    """(O, dO/da, dO/db, dO/dc) for a, b, c >= 0."""
    return orthant_mass(a, b, c, qtab, otab)


# -- box: inclusion-exclusion over faces, edges and corners ------------------------------------------
@njit(inline="always", fastmath=FAST)
def _slab(u, e):
    """A box's slab |u| <= e along one axis (units of H) as three terms coefficient x chi(argument):
    1 - chi(e - u) - chi(e + u) within it, chi(|u| - e) - chi(|u| + e) beyond; returns coefficients,
    arguments and d argument / du as 3-tuples (argument < 0: no half space, the factor 1; a term
    out of reach, argument >= 1, gets coefficient 0). Arithmetic, not branches (see _table2)."""
    t = abs(u)
    f = 0.5 + math.copysign(0.5, e - t)  # 1 within the slab, 0 beyond
    g = math.copysign(1.0 - f, u)
    a1, a2 = f * (e - u) + (1.0 - f) * (t + e), f * (e + u + 1.0) - 1.0
    c1, c2 = -0.5 - math.copysign(0.5, 1.0 - a1), -f * (0.5 + math.copysign(0.5, 1.0 - a2))
    return (1.0, c1, c2), (f * (e - t - 1.0) + t - e, a1, a2), (g, g - f, f)


@njit(inline="always", fastmath=FAST)
def box_distance(x, y, z, ex, ey, ez):
    """(phi, grad phi) of the solid box: positive outside; inside, minus the distance to the
    nearest face (its normal as the gradient; ties go to the first axis)."""
    qx, qy, qz = abs(x) - ex, abs(y) - ey, abs(z) - ez
    sx, sy, sz = math.copysign(1.0, x), math.copysign(1.0, y), math.copysign(1.0, z)
    ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
    out = math.sqrt(ox * ox + oy * oy + oz * oz)
    if out > 0.0:
        return out, sx * ox / out, sy * oy / out, sz * oz / out
    if qx >= qy and qx >= qz:
        return qx, sx, 0.0, 0.0
    if qy >= qz:
        return qy, 0.0, sy, 0.0
    return qz, 0.0, 0.0, sz


@njit(inline="always", fastmath=FAST)
def box_field(x, y, z, ex, ey, ez, h, container, qtab, otab):
    """(phi, grad phi, I, grad I) of the box of half extents (ex, ey, ez) about its frame's origin; with
    `container` its complement (fluid inside: I = 1 - I_box, phi and both gradients change sign).
    I is the product of the three slabs' terms: 27 orthant masses (those with an argument >= 1 are 0)."""
    d, d0, d1, d2 = box_distance(x, y, z, ex, ey, ez)
    u, v, w = x / h, y / h, z / h
    m = gx = gy = gz = 0.0
    if max(abs(u) - ex / h, abs(v) - ey / h, abs(w) - ez / h) < 1.0:
        cx, ax, sx = _slab(u, ex / h)
        cy, ay, sy = _slab(v, ey / h)
        cz, az, sz = _slab(w, ez / h)
        for i in range(3):  # zero terms skipped at each level: a point well inside has one
            if cx[i] == 0.0:
                continue
            for j in range(3):
                if cy[j] == 0.0:
                    continue
                for k in range(3):
                    c = cx[i] * cy[j] * cz[k]
                    if c != 0.0:
                        val, dx, dy, dz = orthant_mass(ax[i], ay[j], az[k], qtab, otab)
                        m += c * val
                        gx += c * dx * sx[i]
                        gy += c * dy * sy[j]
                        gz += c * dz * sz[k]
    sg = -1.0 if container else 1.0
    return sg * d, sg * d0, sg * d1, sg * d2, (1.0 - m if container else m), sg * gx / h, sg * gy / h, sg * gz / h


# -- ball --------------------------------------------------------------------------------------------
@njit(inline="always", fastmath=FAST)
def _cubed_moments(a, m):
    """int_0^m t^k (a - t)^3 dt for k = 1, 2, 3."""
    m2 = m * m
    m4 = m2 * m2
    a2 = a * a
    j1 = m2 * (a2 * a / 2.0 - a2 * m + 0.75 * a * m2 - m2 * m / 5.0)
    j2 = m2 * m * (a2 * a / 3.0 - 0.75 * a2 * m + 0.6 * a * m2 - m2 * m / 6.0)
    j3 = m4 * (a2 * a / 4.0 - 0.6 * a2 * m + 0.5 * a * m2 - m2 * m / 7.0)
    return j1, j2, j3


@njit(inline="always", fastmath=FAST)
def _moments(r):
    """(P1, P2, P3)(r), P_k(r) = int_0^r t^k w(t) dt in units of H, from the kernel's branch-free
    form w = (16/pi) [(1 - t)+^3 - 4 (1/2 - t)+^3]: P_k = (16/pi) [J_k(1, min(r, 1)) - 4 J_k(1/2, min(r, 1/2))]."""
    o1, o2, o3 = _cubed_moments(1.0, min(r, 1.0))
    i1, i2, i3 = _cubed_moments(0.5, min(r, 0.5))
    return 2.0 * _C * (o1 - 4.0 * i1), 2.0 * _C * (o2 - 4.0 * i2), 2.0 * _C * (o3 - 4.0 * i3)


@njit(inline="always", fastmath=FAST)
def ball_mass(s, radius, h):
    """(I, dI/ds) of a solid ball of `radius` at distance s from its centre (physical units):
    I = [s < R] 4 pi P2(R - s) + 2 pi dP2 + (pi/s)((R^2 - s^2) dP1 - dP3),
    dI/ds = -(pi/s^2)((R^2 + s^2) dP1 - dP3),  dP_k = P_k(min(R + s, 1)) - P_k(|R - s|)  (units of H).
    Below s = 1e-4 H (where 1/s^2 would cancel digits) s is held there, the slope scaled to 0 at s = 0."""
    sh = s / h
    rr = radius / h
    sc = max(sh, 1e-4)
    if rr - sc >= 1.0:
        return 1.0, 0.0
    lo = abs(rr - sc)
    if lo >= 1.0:
        return 0.0, 0.0
    m = 4.0 * math.pi * _moments(max(rr - sc, 0.0))[1]
    a1, a2, a3 = _moments(lo)
    b1, b2, b3 = _moments(rr + sc)
    d1, d2, d3 = b1 - a1, b2 - a2, b3 - a3
    m += 2.0 * math.pi * d2 + (math.pi / sc) * ((rr * rr - sc * sc) * d1 - d3)
    dm = -(math.pi / (sc * sc)) * ((rr * rr + sc * sc) * d1 - d3)
    if sh < sc:
        dm *= sh / sc
    return m, dm / h


@njit(inline="always", fastmath=FAST)
def sphere_field(x, y, z, radius, h, container):
    """(phi, grad phi, I, grad I) of a ball centred at the origin of its frame (with `container`,
    the fluid fills the ball: the complement). At the centre grad phi is taken as (0, 0, 1)."""
    s = math.sqrt(x * x + y * y + z * z)
    m, dm = ball_mass(s, radius, h)
    n0, n1, n2 = (x / s, y / s, z / s) if s > 0.0 else (0.0, 0.0, 1.0)
    if container:
        return radius - s, -n0, -n1, -n2, 1.0 - m, -dm * n0, -dm * n1, -dm * n2
    return s - radius, n0, n1, n2, m, dm * n0, dm * n1, dm * n2


@njit(inline="always", fastmath=FAST)
def plane_field(x, y, z, nx, ny, nz, offset, h):
    """(phi, grad phi, I, grad I) of the half space n . x < offset (n unit, pointing into the fluid):
    phi = n . x - offset, I = Phi(phi/H), grad I = -A(phi/H) n / H."""
    d = nx * x + ny * y + nz * z - offset
    q = d / h
    g = -half_density(q) / h
    return d, nx, ny, nz, half_mass(q), g * nx, g * ny, g * nz


# -- the wall potential (the reading the passes use) -------------------------------------------------
@njit(inline="always", fastmath=FAST)
def face_potential(u, b, reach):
    """(mu, dmu/du) of one face at signed distance u (units of H, positive in the fluid):
    mu = b (1 - u/U)^3 below U = `reach`, 0 beyond (C2 at U; it keeps growing inside the solid)."""
    t = max(1.0 - u / reach, 0.0)
    return b * t * t * t, -3.0 * b * t * t / reach


@njit(inline="always", fastmath=FAST)
def box_potential(x, y, z, ex, ey, ez, h, container, b, reach):
    """(mu, grad mu) of a box in its frame (physical units). A container's faces add: each face f
    at distance y_f from the point (inside the box) gives face_potential(y_f/H), so an edge or
    corner reads 1 - prod_f (1 - lambda_f) through the reading 1 - exp(-mu). An obstacle reads its
    one signed distance: mu = face_potential(phi/H)."""
    if not container:
        d, n0, n1, n2 = box_distance(x, y, z, ex, ey, ez)
        m, dm = face_potential(d / h, b, reach)
        return m, dm * n0 / h, dm * n1 / h, dm * n2 / h
    m0, a0 = face_potential((ex - x) / h, b, reach)
    m1, a1 = face_potential((ex + x) / h, b, reach)
    m2, a2 = face_potential((ey - y) / h, b, reach)
    m3, a3 = face_potential((ey + y) / h, b, reach)
    m4, a4 = face_potential((ez - z) / h, b, reach)
    m5, a5 = face_potential((ez + z) / h, b, reach)
    return m0 + m1 + m2 + m3 + m4 + m5, (a1 - a0) / h, (a3 - a2) / h, (a5 - a4) / h


# -- the walls' support along their faces (method.md section 11, "Support") ---------------------------
@njit(inline="always", fastmath=FAST)
def face_support(m):
    """c(mu) = min(e^mu - 1, 1) of one face's potential mu: the reading's ratio Lambda / (1 - Lambda),
    the share of the particle's missing fluid the wall stands in for, capped at a full face."""
    return min(math.exp(m) - 1.0, 1.0)


@njit(inline="always", fastmath=FAST)
def _face_c(u, b, reach):
    """c of one face at signed distance u (units of H)."""
    return face_support(face_potential(u, b, reach)[0])


@njit(inline="always", fastmath=FAST)
def box_support(x, y, z, ex, ey, ez, h, b, reach):
    """A container's support in its frame, diagonal: (M_xx, M_yy, M_zz) = sum_f c_f (I - n_f n_f) over
    its six faces (a face of normal x supports y and z)."""
    cx = _face_c((ex - x) / h, b, reach) + _face_c((ex + x) / h, b, reach)
    cy = _face_c((ey - y) / h, b, reach) + _face_c((ey + y) / h, b, reach)
    cz = _face_c((ez - z) / h, b, reach) + _face_c((ez + z) / h, b, reach)
    return cy + cz, cx + cz, cx + cy
