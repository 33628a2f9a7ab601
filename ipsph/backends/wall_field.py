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

with R (qtab[i, j, s, t] = d^s_a d^t_b R at (i, j)/n) and T (otab, three flags) cubic Hermite data
on [0, 1]^2 and [0, 1]^3 (`ipsph.boundary.field.tables`). As Q(0, b) = Phi(b)/2 and O(0, b, c) =
Q(b, c)/2, R and T vanish with their in-face slopes on a = 0 (and b, c = 0), and so do their
interpolants: a box's terms join across its faces without a jump. Gradients are the interpolants'
own; every term is 0 from an argument of 1 on (the data are 0 on those planes).

Box (inclusion-exclusion, brief section 7): along each axis the slab |u| <= e is, within a support,
1 - chi(e - u) - chi(e + u) inside and chi(|u| - e) - chi(|u| + e) beyond, chi(t) the half space
{xi > t}; the product over the axes expands into 1, Phi, Q and O of non-negative arguments.
Ball of radius R at distance s: I(s) = [s < R] M(R - s) + int_{|R-s|}^{min(R+s,1)} 2 pi r^2 w(r)
(1 + kappa) dr, kappa = (R^2 - s^2 - r^2)/(2 s r), M(rho) the kernel mass within rho (closed form).

Like `bodies`, device functions: scalar `math`, no allocation, no globals but module constants,
tuples out; they compile with numba njit and as numba-cuda device functions, and import nothing
from ipsph. inline="always" on the closed forms and on what carries the tables (arrays passed to
a compiled call cost reference counting on the CPU: 70 ns per call measured); the interpolation
and per-axis helpers are plain njit, left to LLVM (IR-inlining them too took the box 24 s to compile).
*_field functions return (phi, dphi/dx, dphi/dy, dphi/dz, I, dI/dx, dI/dy, dI/dz) in the object's
frame and physical units.
"""

import math

from numba import njit

FAST = {"contract", "arcp", "reassoc"}  # = ipsph.kernels.FASTMATH (no nnan/ninf: NaN checks keep working)

_C = 8.0 / math.pi  # the kernel's constant in units of H: w(r) = _C f(r)


# -- half space ------------------------------------------------------------------------------------
@njit(inline="always", fastmath=FAST)
def half_mass(q):
    """Phi(q): the kernel mass beyond a plane at signed distance q H (q < 0: the point is inside)."""
    u = abs(q)
    if u >= 1.0:
        m = 0.0
    elif u > 0.5:
        v = 1.0 - u
        v2 = v * v
        m = (8.0 / 15.0) * v2 * v2 * v * (1.0 + 2.0 * u)
    else:
        u2 = u * u
        m = 0.5 - u * (1.4 - u2 * (8.0 / 3.0 - u2 * (4.8 - 3.2 * u)))
    return m if q >= 0.0 else 1.0 - m


@njit(inline="always", fastmath=FAST)
def half_density(q):
    """A(q) = -dPhi/dq = H |dPhi/dy|: the kernel's 1D marginal at q (even in q)."""
    u = abs(q)
    if u >= 1.0:
        return 0.0
    if u > 0.5:
        v = 1.0 - u
        v2 = v * v
        return 1.6 * v2 * v2 * (1.0 + 4.0 * u)
    u2 = u * u
    return 1.4 - u2 * (8.0 - u2 * (24.0 - 19.2 * u))


@njit(inline="always", fastmath=FAST)
def half_mass_inv(m):
    """q = Phi^-1(m) in [-1, 1] (psi = H q): Newton on G(u) = Phi(u)^(1/5) - t^(1/5), t = min(m, 1 - m),
    inside a bisection bracket. The fifth root keeps the root simple as u -> 1, where
    Phi ~ (8/5)(1 - u)^5; from the guess below Newton takes 3-5 steps to 1e-15 (max 30)."""
    if m <= 0.0:
        return 1.0
    if m >= 1.0:
        return -1.0
    t = m if m <= 0.5 else 1.0 - m
    tau = t**0.2
    lo, hi = 0.0, 1.0  # G(lo) >= 0 >= G(hi)
    # G is near linear: slope -1.6^(1/5) at u = 1, G(0) = 0.5^(1/5)
    u = min(max(1.0 - tau * (0.9102392266268373 + 0.2739177 * tau), 0.0), 1.0)
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


# -- cubic Hermite tables: quarter space and octant --------------------------------------------------
@njit(fastmath=FAST)
def _hermite(x, n):
    """Cell of x in [0, 1] on n cells and the 1D cubic Hermite weights there: (i, weights of node i's
    value and slope, node i+1's value and slope, then the same four differentiated in x)."""
    p = min(max(x, 0.0), 1.0) * n
    i = min(int(p), n - 1)
    t = p - i
    s = 1.0 / n
    v0 = t * t * (2.0 * t - 3.0) + 1.0
    m0, m1 = t * (t - 1.0) * (t - 1.0) * s, t * t * (t - 1.0) * s
    d0, e0, e1 = 6.0 * n * t * (t - 1.0), (3.0 * t - 1.0) * (t - 1.0), t * (3.0 * t - 2.0)
    return i, v0, m0, 1.0 - v0, m1, d0, e0, -d0, e1


@njit
def _w(c, k, w):
    """(weight, its derivative) of node c (0, 1), datum k (0 value, 1 slope) from a _hermite tuple."""
    if c == 0:
        return (w[1], w[5]) if k == 0 else (w[2], w[6])
    return (w[3], w[7]) if k == 0 else (w[4], w[8])


@njit(inline="always", fastmath=FAST)
def _table2(a, b, tab):
    """Bicubic Hermite interpolant of tab[i, j, s, t] = d^s_a d^t_b f(i/n, j/n): (f, df/da, df/db)."""
    n = tab.shape[0] - 1
    wa = _hermite(a, n)
    wb = _hermite(b, n)
    i, j = wa[0], wb[0]
    v = ga = gb = 0.0
    for ci in range(2):
        for ka in range(2):
            sv = sd = 0.0
            for cj in range(2):
                for kb in range(2):
                    f = tab[i + ci, j + cj, ka, kb]
                    xb, db = _w(cj, kb, wb)
                    sv += f * xb
                    sd += f * db
            xa, da = _w(ci, ka, wa)
            v += xa * sv
            ga += da * sv
            gb += xa * sd
    return v, ga, gb


@njit(inline="always", fastmath=FAST)
def _table3(a, b, c, tab):
    """Tricubic Hermite interpolant of tab[i, j, k, s, t, u] (all mixed first derivatives): (f, grad f)."""
    n = tab.shape[0] - 1
    wa = _hermite(a, n)
    wb = _hermite(b, n)
    wc = _hermite(c, n)
    i, j, k = wa[0], wb[0], wc[0]
    v = ga = gb = gc = 0.0
    for ci in range(2):
        for ka in range(2):
            xa, da = _w(ci, ka, wa)
            for cj in range(2):
                for kb in range(2):
                    xb, db = _w(cj, kb, wb)
                    sv = sd = 0.0
                    for ck in range(2):
                        for kc in range(2):
                            f = tab[i + ci, j + cj, k + ck, ka, kb, kc]
                            xc, dc = _w(ck, kc, wc)
                            sv += f * xc
                            sd += f * dc
                    v += xa * xb * sv
                    ga += da * xb * sv
                    gb += xa * db * sv
                    gc += xa * xb * sd
    return v, ga, gb, gc


@njit(fastmath=FAST)
def quarter_mass(a, b, qtab):
    """(Q, dQ/da, dQ/db) for a, b >= 0 (units of H): Q = Phi(a) Phi(b) + R~(a, b), R~ from qtab."""
    if a >= 1.0 or b >= 1.0:
        return 0.0, 0.0, 0.0
    pa, pb = half_mass(a), half_mass(b)
    r, ra, rb = _table2(a, b, qtab)
    return pa * pb + r, ra - half_density(a) * pb, rb - pa * half_density(b)


@njit(fastmath=FAST)
def octant_mass(a, b, c, qtab, otab):
    """(O, dO/da, dO/db, dO/dc) for a, b, c >= 0:
    O = Phi_a Phi_b Phi_c + Phi_a R~(b, c) + Phi_b R~(a, c) + Phi_c R~(a, b) + T~(a, b, c)."""
    if a >= 1.0 or b >= 1.0 or c >= 1.0:
        return 0.0, 0.0, 0.0, 0.0
    p0, p1, p2 = half_mass(a), half_mass(b), half_mass(c)
    d0, d1, d2 = -half_density(a), -half_density(b), -half_density(c)
    v, g0, g1, g2 = _table3(a, b, c, otab)
    v += p0 * p1 * p2
    g0 += d0 * p1 * p2
    g1 += p0 * d1 * p2
    g2 += p0 * p1 * d2
    for m in range(3):  # the pair without axis m, times Phi of axis m
        x, y = (b, c) if m == 0 else ((a, c) if m == 1 else (a, b))
        r, rx, ry = _table2(x, y, qtab)
        if m == 0:
            v, g0, g1, g2 = v + p0 * r, g0 + d0 * r, g1 + p0 * rx, g2 + p0 * ry
        elif m == 1:
            v, g0, g1, g2 = v + p1 * r, g0 + p1 * rx, g1 + d1 * r, g2 + p1 * ry
        else:
            v, g0, g1, g2 = v + p2 * r, g0 + p2 * rx, g1 + p2 * ry, g2 + d2 * r
    return v, g0, g1, g2


# -- box: inclusion-exclusion over faces, edges and corners ------------------------------------------
@njit(fastmath=FAST)
def _term(k, u, e):
    """Term k (0, 1, 2) of a box's slab |u| <= e along one axis (units of H), as (coefficient,
    argument, d argument / du): within the slab 1 - chi(e - u) - chi(e + u), beyond it
    chi(|u| - e) - chi(|u| + e); argument < 0 is "no half space", coefficient 0 "no term"."""
    t = abs(u)
    sg = 1.0 if u >= 0.0 else -1.0
    if t <= e:
        if k == 0:
            return 1.0, -1.0, 0.0
        a = e - u if k == 1 else e + u
        return (-1.0 if a < 1.0 else 0.0), a, (-1.0 if k == 1 else 1.0)
    if k == 0:
        return 1.0, t - e, sg
    return (-1.0 if k == 1 and t + e < 1.0 else 0.0), t + e, sg


@njit(inline="always", fastmath=FAST)
def _mass_of(ax, ay, az, qtab, otab):
    """Kernel mass of the intersection of the half spaces with arguments >= 0 (negative = absent):
    1, Phi, Q or O; returns (mass, d/dax, d/day, d/daz)."""
    px, py, pz = ax >= 0.0, ay >= 0.0, az >= 0.0
    n = int(px) + int(py) + int(pz)
    if n == 0:
        return 1.0, 0.0, 0.0, 0.0
    if n == 3:
        return octant_mass(ax, ay, az, qtab, otab)
    if n == 1:
        t = ax if px else (ay if py else az)
        d = -half_density(t)
        return half_mass(t), d if px else 0.0, d if py else 0.0, d if pz else 0.0
    p, r = (ay, az) if not px else ((ax, az) if not py else (ax, ay))
    m, dp, dr = quarter_mass(p, r, qtab)
    return m, (dp if px else 0.0), ((dr if py else 0.0) if px else dp), (dr if pz else 0.0)


@njit(inline="always", fastmath=FAST)
def box_mass(x, y, z, ex, ey, ez, h, qtab, otab):
    """(I, dI/dx, dI/dy, dI/dz) of the solid box |x| <= ex, |y| <= ey, |z| <= ez (its own frame)."""
    u, v, w = x / h, y / h, z / h
    eu, ev, ew = ex / h, ey / h, ez / h
    if abs(u) - eu >= 1.0 or abs(v) - ev >= 1.0 or abs(w) - ew >= 1.0:
        return 0.0, 0.0, 0.0, 0.0
    m = gx = gy = gz = 0.0
    for i in range(3):
        cx, ax, sx = _term(i, u, eu)
        if cx == 0.0:
            continue
        for j in range(3):
            cy, ay, sy = _term(j, v, ev)
            if cy == 0.0:
                continue
            for k in range(3):
                cz, az, sz = _term(k, w, ew)
                if cz == 0.0:
                    continue
                c = cx * cy * cz
                val, dx, dy, dz = _mass_of(ax, ay, az, qtab, otab)
                m += c * val
                gx += c * dx * sx
                gy += c * dy * sy
                gz += c * dz * sz
    return m, gx / h, gy / h, gz / h


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
    `container` its complement (fluid inside: I = 1 - I_box, phi and both gradients change sign)."""
    d, d0, d1, d2 = box_distance(x, y, z, ex, ey, ez)
    m, g0, g1, g2 = box_mass(x, y, z, ex, ey, ez, h, qtab, otab)
    if container:
        return -d, -d0, -d1, -d2, 1.0 - m, -g0, -g1, -g2
    return d, d0, d1, d2, m, g0, g1, g2


# -- ball --------------------------------------------------------------------------------------------
def _moment_knot(k):
    """int_0^(1/2) t^k f dt minus the outer antiderivative 2 int t^k (1 - t)^3 dt at 1/2 (host only)."""
    inner = 6.0 * 0.5 ** (k + 4) / (k + 4) - 6.0 * 0.5 ** (k + 3) / (k + 3) + 0.5 ** (k + 1) / (k + 1)
    return inner - 2.0 * sum(c * 0.5 ** (k + j) / (k + j) for j, c in ((1, 1.0), (2, -3.0), (3, 3.0), (4, -1.0)))


_K1, _K2, _K3 = _moment_knot(1), _moment_knot(2), _moment_knot(3)  # the outer pieces' constants


@njit(inline="always", fastmath=FAST)
def _moments(r):
    """(P1, P2, P3)(r), P_k(r) = int_0^min(r,1) t^k w(t) dt in units of H (w = (8/pi) f)."""
    r = min(r, 1.0)
    r2, r3, r4 = r * r, r * r * r, r * r * r * r
    if r <= 0.5:
        p1 = r2 * (0.5 + r2 * (-1.5 + 1.2 * r))
        p2 = r3 * (1.0 / 3.0 + r2 * (-1.2 + r))
        p3 = r4 * (0.25 + r2 * (-1.0 + r * (6.0 / 7.0)))
    else:
        p1 = _K1 + 2.0 * r2 * (0.5 + r * (-1.0 + r * (0.75 - 0.2 * r)))
        p2 = _K2 + 2.0 * r3 * (1.0 / 3.0 + r * (-0.75 + r * (0.6 - r / 6.0)))
        p3 = _K3 + 2.0 * r4 * (0.25 + r * (-0.6 + r * (0.5 - r / 7.0)))
    return _C * p1, _C * p2, _C * p3


@njit(fastmath=FAST)
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
    m = 4.0 * math.pi * _moments(rr - sc)[1] if sc < rr else 0.0
    a1, a2, a3 = _moments(lo)
    b1, b2, b3 = _moments(rr + sc)
    d1, d2, d3 = b1 - a1, b2 - a2, b3 - a3
    m += 2.0 * math.pi * d2 + (math.pi / sc) * ((rr * rr - sc * sc) * d1 - d3)
    dm = -(math.pi / (sc * sc)) * ((rr * rr + sc * sc) * d1 - d3)
    if sh < sc:
        dm *= sh / sc
    return m, dm / h


@njit(fastmath=FAST)
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
