"""Host side of the "field" wall model: the Q and O tables, the lattice calibration, evaluators.

The device maths is `ipsph.backends.wall_field` (its docstring states the formulas). Here, in
units of H with w(r) = (8/pi) f(r) the kernel (f = 6r^3 - 6r^2 + 1 below r = 1/2, 2(1 - r)^3 to 1):

Tables. The octant mass O(a, b, c) = int_{xi > a, eta > b, zeta > c} W is integrated over
spheres about the point (Archimedes: on the unit sphere dA = dz dt):

    O(a, b, c) = int_{r0}^1 w(r) r^2 Omega(a/r, b/r, c/r) dr,      r0 = |(a, b, c)|
    Omega(al, be, ga) = int_ga^zm theta(z) dz,  theta = pi/2 - asin(al/rho) - asin(be/rho),
                        rho = sqrt(1 - z^2), zm = sqrt(1 - al^2 - be^2)
                      = (pi/2)(zm - ga) - [F_al + F_be]_ga^zm,
    F_al(z) = z asin(al/rho) + al asin(z/sqrt(1 - al^2)) - atan(al z / sqrt(1 - al^2 - z^2))

(dF_al/dz = asin(al/rho)). Its Hermite data: dO/da = -S(a; b, c), S(h; p, q) = the kernel on the
plane xi = h over {eta > p, zeta > q} = int w(r) r theta(sqrt(r^2 - h^2); p, q) dr;
d2O/dadb = L(a^2 + b^2, c) = int_c w(sqrt(rho^2 + z^2)) dz in closed form (antiderivatives of r^k
in z, asinh for the odd k); d3O/dadbdc = -w(|(a, b, c)|); the rest by O's symmetry under
permutations. Q(a, b) = 2 O(a, b, 0) and its data likewise. The radial integrals are
Gauss-Legendre in s = sqrt(r - r0) (O and S behave like powers of sqrt(r - r0) at r0), split at
the kernel's knot r = 1/2. The tables hold the remainders R = Q - Phi Phi and T = O - Phi Phi Phi
- sum Phi R (wall_field's docstring), their data by the product rule, and are handed to the
device as each cell's polynomial coefficients of the cubic Hermite interpolant (`_cells`). At
16 cells per H: 32 kB and 2.1 MB, built in 0.2 s once per process (too little for a disk cache to
pay); interpolation error 2e-7 (value) and 5e-6 (H |gradient|), measured by tests/test_wall_field.py.

Calibration (brief section 3): on the simple cubic lattice of spacing d (volume d^3, H = 2d) the
first layer of a half lattice, d/2 from a flat face, reads S_half = d^3 sum_{fluid j} W_ij;
TAU0 = 1 - S_half is what the wall must add for it to read rho0, and DELTA_H = delta/H solves
Phi(1/4 + DELTA_H) = TAU0 (TAU0 = 0.149712, DELTA_H = 0.0416176, delta = 0.08324 d).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit

from ..backends import wall_field as wf

CELLS = 16  # table cells per H on [0, 1] (errors ~ CELLS^-4 in value, ^-3 in gradient)
GAUSS = 48  # Gauss-Legendre points per radial piece (24 leaves 1e-12 at the nodes, 48 rounding)


def _w(r):
    r = np.asarray(r, float)
    return (8.0 / np.pi) * np.where(r <= 0.5, 6 * r**3 - 6 * r**2 + 1, np.where(r < 1.0, 2 * (1 - r) ** 3, 0.0))


def _F(al, z, D):
    """F_al(z) (module docstring) with D = sqrt(1 - al^2 - z^2) given, so that no asin meets an
    argument rounded near 1 (where asin would turn 1e-16 into 1e-8)."""
    return z * np.arctan2(al, D) + al * np.arctan2(z, D) - np.arctan2(al * z, D)


def _omega(a, b, c, r, e):
    """Omega(a/r, b/r, c/r) given e = r^2 - a^2 - b^2 - c^2 >= 0 computed without cancellation."""
    al, be, ga = a / r, b / r, c / r
    zm = np.sqrt(e + c * c) / r
    dag = np.sqrt(e + b * b) / r  # sqrt(1 - al^2 - ga^2)
    dbg = np.sqrt(e + a * a) / r
    om = 0.5 * np.pi * (zm - ga) - (_F(al, zm, be) - _F(al, ga, dag)) - (_F(be, zm, al) - _F(be, ga, dbg))
    return np.maximum(om, 0.0)


def solid_angle(al, be, ga):
    """Omega(al, be, ga): area of {x > al, y > be, z > ga} on the unit sphere (al, be, ga >= 0)."""
    al, be, ga = np.broadcast_arrays(*(np.asarray(v, float) for v in (al, be, ga)))
    e = 1.0 - al * al - be * be - ga * ga
    return np.where(e > 0, _omega(al, be, ga, 1.0, np.maximum(e, 0.0)), 0.0)


def _radial(r0, integrand, n=GAUSS):
    """int_{r0}^1 integrand(r, e) dr with e = r^2 - r0^2, vectorised over r0 (1D): Gauss-Legendre
    in s = sqrt(r - r0) (so e = s^2 (2 r0 + s^2) keeps its digits), split at r = 1/2."""
    x, wts = np.polynomial.legendre.leggauss(n)
    r0 = np.asarray(r0, float)
    total = np.zeros_like(r0)
    for lo, hi in ((r0, np.clip(0.5, r0, 1.0)), (np.clip(0.5, r0, 1.0), np.ones_like(r0))):
        s0, s1 = np.sqrt(np.maximum(lo - r0, 0.0)), np.sqrt(np.maximum(hi - r0, 0.0))
        s = 0.5 * (s0 + s1)[:, None] + 0.5 * (s1 - s0)[:, None] * x[None, :]
        r = r0[:, None] + s * s
        e = s * s * (2.0 * r0[:, None] + s * s)
        total += 0.5 * (s1 - s0) * np.sum(wts[None, :] * integrand(r, e) * 2.0 * s, axis=1)
    return total


def _prep(*args):
    return tuple(np.ravel(np.asarray(v, float)) for v in np.broadcast_arrays(*args))


def octant_exact(a, b, c, n=GAUSS):
    """O(a, b, c) by the radial quadrature (a, b, c >= 0; flattened)."""
    a, b, c = _prep(a, b, c)
    r0 = np.sqrt(a * a + b * b + c * c)
    k = r0 < 1.0
    a, b, c = a[k, None], b[k, None], c[k, None]
    out = np.zeros(k.shape)
    out[k] = _radial(r0[k], lambda r, e: _w(r) * r * r * _omega(a, b, c, r, e), n)
    return out


def slice_exact(hh, p, q, n=GAUSS):
    """S(h; p, q) = int_{eta > p, zeta > q} W(h, eta, zeta) = -dO/da at (h, p, q); flattened.
    theta = acos(p/rho) - asin(q/rho) with rho^2 - p^2 = e + q^2, rho^2 - q^2 = e + p^2."""
    hh, p, q = _prep(hh, p, q)
    r0 = np.sqrt(hh * hh + p * p + q * q)
    k = r0 < 1.0
    p, q = p[k, None], q[k, None]

    def f(r, e):
        return _w(r) * r * (np.arctan2(np.sqrt(e + q * q), p) - np.arctan2(q, np.sqrt(e + p * p)))

    out = np.zeros(k.shape)
    out[k] = _radial(r0[k], f, n)
    return out


def line_exact(rho2, c):
    """L(rho^2, c) = int_c^inf w(sqrt(rho^2 + z^2)) dz in closed form (c >= 0)."""
    rho2, c = (np.asarray(v, float) for v in np.broadcast_arrays(rho2, c))
    rho = np.sqrt(rho2)

    def J(z):  # antiderivatives of r^0..r^3 in z, r = sqrt(rho^2 + z^2)
        r = np.sqrt(rho2 + z * z)
        with np.errstate(divide="ignore", invalid="ignore"):
            ash = np.where(rho > 0, rho2 * np.arcsinh(np.where(rho > 0, z / rho, 0.0)), 0.0)
        return z, 0.5 * (z * r + ash), rho2 * z + z**3 / 3, z * (2 * z * z + 5 * rho2) * r / 8 + 0.375 * rho2 * ash

    def inner(z):
        j0, _, j2, j3 = J(z)
        return 6 * j3 - 6 * j2 + j0

    def outer(z):
        j0, j1, j2, j3 = J(z)
        return 2 * j0 - 6 * j1 + 6 * j2 - 2 * j3

    zk = np.sqrt(np.maximum(0.25 - rho2, 0.0))
    ze = np.sqrt(np.maximum(1.0 - rho2, 0.0))
    lo = np.minimum(c, ze)
    mid = np.clip(zk, lo, ze)
    val = inner(mid) - inner(lo) + outer(ze) - outer(mid)
    return (8.0 / np.pi) * np.where(c < ze, val, 0.0)


def _phi_jet(v):
    """(Phi(v), dPhi/dv) on an array, stacked on a last axis of 2."""
    v = np.asarray(v, float)
    return np.stack([np.vectorize(wf.half_mass)(v), -np.vectorize(wf.half_density)(v)], axis=-1)


def _quarter_jet(a, b):
    """Q and its Hermite data [Q, Q_b; Q_a, Q_ab] on a grid, shape a.shape + (2, 2)."""
    sh, z = a.shape, np.zeros_like(a)
    q = np.empty(sh + (2, 2))
    q[..., 0, 0] = 2 * octant_exact(a, b, z).reshape(sh)
    q[..., 1, 0] = -2 * slice_exact(a, b, z).reshape(sh)
    q[..., 0, 1] = -2 * slice_exact(b, a, z).reshape(sh)
    q[..., 1, 1] = 2 * line_exact(a * a + b * b, z)
    return q


def _build(n):
    """The Hermite tables on n cells per H (one grid for both, so that the octant's faces are the
    quarter's edges to rounding), as node data: R = Q - Phi(a) Phi(b), (n+1, n+1, 2, 2), and
    T = O - Phi Phi Phi - sum Phi R, (n+1,)*3 + (2, 2, 2), each with its mixed derivatives.
    R vanishes on a = 0 and b = 0 (Q(0, b) = Phi(b)/2) and T on the three faces, with their data,
    so the interpolants do too: the box's terms join across its faces without a jump."""
    t = np.linspace(0.0, 1.0, n + 1)
    A, B = np.meshgrid(t, t, indexing="ij")
    ph = _phi_jet(t)  # (n+1, 2)
    R = _quarter_jet(A, B) - ph[:, None, :, None] * ph[None, :, None, :]
    A, B, C = np.meshgrid(t, t, t, indexing="ij")
    sh = A.shape
    oj = np.empty(sh + (2, 2, 2))
    oj[..., 0, 0, 0] = octant_exact(A, B, C).reshape(sh)
    oj[..., 1, 0, 0] = -slice_exact(A, B, C).reshape(sh)
    oj[..., 0, 1, 0] = -slice_exact(B, A, C).reshape(sh)
    oj[..., 0, 0, 1] = -slice_exact(C, A, B).reshape(sh)
    oj[..., 1, 1, 0] = line_exact(A * A + B * B, C)
    oj[..., 1, 0, 1] = line_exact(A * A + C * C, B)
    oj[..., 0, 1, 1] = line_exact(B * B + C * C, A)
    oj[..., 1, 1, 1] = -_w(np.sqrt(A * A + B * B + C * C))
    pa = ph[:, None, None, :, None, None]
    pb = ph[None, :, None, None, :, None]
    pc = ph[None, None, :, None, None, :]
    T = oj - pa * pb * pc
    T -= pa * R[None, :, :, None, :, :]  # Phi(a) R(b, c)
    T -= pb * R[:, None, :, :, None, :]  # Phi(b) R(a, c)
    T -= pc * R[:, :, None, :, :, None]  # Phi(c) R(a, b)
    # zero on the coordinate faces (value and in-face slopes), as they are analytically
    R[0, :, 0, :] = R[:, 0, :, 0] = 0.0
    T[0, :, :, 0, :, :] = T[:, 0, :, :, 0, :] = T[:, :, 0, :, :, 0] = 0.0
    return R, T


# rows: a cell's node 0 value, node 0 slope x width, node 1 value, node 1 slope x width; columns: the
# coefficients of t^0..t^3 of the cubic Hermite basis functions
_HERMITE = np.array([[1.0, 0.0, -3.0, 2.0], [0.0, 1.0, -2.0, 1.0], [0.0, 0.0, 3.0, -2.0], [0.0, 0.0, -1.0, 1.0]])


def _cells(nodes):
    """Per-cell polynomial coefficients of the Hermite interpolant of node data `nodes` (shape
    (n+1,)*dim + (2,)*dim, value and mixed first derivatives): (n,)*dim + (4,)*dim."""
    dim = nodes.ndim // 2
    n = nodes.shape[0] - 1
    data = np.empty((n,) * dim + (4,) * dim)
    for corner in np.ndindex(*(2,) * dim):  # node offsets within the cell
        for flags in np.ndindex(*(2,) * dim):  # which derivatives
            src = nodes[tuple(slice(c, c + n) for c in corner) + flags]
            data[(Ellipsis,) + tuple(2 * c + f for c, f in zip(corner, flags))] = src * (1.0 / n) ** sum(flags)
    for axis in range(dim):  # the basis change along each local axis in turn
        data = np.moveaxis(np.tensordot(data, _HERMITE, axes=([dim + axis], [0])), -1, dim + axis)
    return np.ascontiguousarray(data)


@lru_cache(maxsize=4)
def tables(n: int = CELLS) -> tuple[np.ndarray, np.ndarray]:
    """(qtab, otab) for `wall_field`'s orthant_mass, box_field, ...: (n, n, 4, 4) and (n, n, n, 4, 4, 4)
    cell coefficients (C-contiguous float64, read-only)."""
    qtab, otab = (_cells(t) for t in _build(n))
    for t in (qtab, otab):
        t.flags.writeable = False
    return qtab, otab


# -- calibration -------------------------------------------------------------------------------------
def lattice_first_layer() -> tuple[float, float, float]:
    """(full-lattice sum, missing sum, TAU0) of the simple cubic lattice, spacing d, V = d^3, H = 2d:
    the kernel sum at a site, the part of it from the sites beyond a face d/2 below the site, and
    1 - (full - missing), what a wall must add for the first layer to read rho0."""
    k = np.arange(-3, 4, dtype=float)
    X, Y, Z = np.meshgrid(k, k, k, indexing="ij")
    wv = _w(np.sqrt(X * X + Y * Y + Z * Z) / 2.0) / 8.0  # d^3 W with d = 1, H = 2: W = w(r/H)/H^3
    full = float(wv.sum())
    missing = float(wv[Z < 0].sum())
    return full, missing, 1.0 - (full - missing)


def calibration() -> tuple[float, float]:
    """(TAU0, DELTA_H): Phi(1/4 + DELTA_H) = TAU0, the first layer at d/2 = H/4 from the face."""
    tau0 = lattice_first_layer()[2]
    return tau0, wf.half_mass_inv.py_func(tau0) - 0.25  # (py_func: no compile at import)


TAU0, DELTA_H = calibration()


def lattice_first_layer_slope() -> float:
    """g_f (units rho0/d): d/dy of the first layer's fluid kernel sum, the layer moved alone away
    from the face (towards the fluid) on the lattice of `lattice_first_layer`."""
    k = np.arange(-3, 4, dtype=float)
    X, Y, Z = np.meshgrid(k, k, k, indexing="ij")
    x, y, z = X[Z >= 0], Y[Z >= 0], Z[Z >= 0]
    r = np.sqrt(x * x + y * y + z * z)
    q = r / 2.0  # H = 2d
    dw = (8.0 / np.pi) * np.where(q <= 0.5, 18 * q * q - 12 * q, np.where(q < 1.0, -6 * (1 - q) ** 2, 0.0)) / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        return float(np.sum(np.where(r > 0, -dw * z / r, 0.0)) / 8.0)


G_F = lattice_first_layer_slope()
# The potential's slope at the rest distance d/2, a multiple of g_f: 2 balances a uniform pressure
# carried once (method.md section 11: p (|gb| - 2 g_f) = 0 on the first layer).
SLOPE_G_F = 2.0
# The hydrostatic increment of the wall pressure, s = WALL_INCREMENT d / (4 g_f) (1 would give the
# first layer the g/2 its one-sided pressure gradient lacks). Off: on the r = 0.02 tank at rest it
# lowered DFSPH's first-layer excess from 6.3 % to 5.0 % but raised its peak speed from 0.22 to
# 0.71 m/s, and moved IPSPH's slope from +4 % to -7.5 % (docs/validation.md, "Tank at rest").
WALL_INCREMENT = 0.0


def wall_profile(slope_g_f: float = SLOPE_G_F, increment: float = WALL_INCREMENT) -> tuple[float, float, float]:
    """(b, U, s/H) of `wall_field.face_potential`, mu(u) = b (1 - u/U)^3 (u in H), such that the
    reading 1 - exp(-mu) of one flat face is TAU0 at d/2 (u = 1/4) with slope slope_g_f * G_F
    (rho0/d); s/H the hydrostatic increment's depth (`WALL_INCREMENT`) in units of H = 2d."""
    mu0 = -np.log1p(-TAU0)
    dmu = 2.0 * slope_g_f * G_F / (1.0 - TAU0)  # per H: dLambda/du = H dLambda/dy = 2 d dLambda/dy
    reach = 0.25 + 3.0 * mu0 / dmu
    s_h = increment / (8.0 * G_F)  # s = increment d / (4 g_f), H = 2d
    return float(mu0 / (1.0 - 0.25 / reach) ** 3), float(reach), s_h


# -- host evaluators (loops over the device functions) ---------------------------------------------
@njit
def _box_loop(p, ex, ey, ez, h, container, qtab, otab, out):
    for i in range(p.shape[0]):
        r = wf.box_field(p[i, 0], p[i, 1], p[i, 2], ex, ey, ez, h, container, qtab, otab)
        for k in range(8):
            out[i, k] = r[k]


@njit
def _sphere_loop(p, radius, h, container, out):
    for i in range(p.shape[0]):
        r = wf.sphere_field(p[i, 0], p[i, 1], p[i, 2], radius, h, container)
        for k in range(8):
            out[i, k] = r[k]


@njit
def _plane_loop(p, nx, ny, nz, offset, h, out):
    for i in range(p.shape[0]):
        r = wf.plane_field(p[i, 0], p[i, 1], p[i, 2], nx, ny, nz, offset, h)
        for k in range(8):
            out[i, k] = r[k]


@njit
def _reading_loop(m, delta_h, out):
    for i in range(m.shape[0]):
        r = wf.wall_reading(m[i], delta_h)
        for k in range(3):
            out[i, k] = r[k]


@njit
def _quarter_loop(a, b, qtab, otab, out):
    for i in range(a.shape[0]):
        r = wf.quarter_mass(a[i], b[i], qtab, otab)
        for k in range(3):
            out[i, k] = r[k]


@njit
def _octant_loop(a, b, c, qtab, otab, out):
    for i in range(a.shape[0]):
        r = wf.octant_mass(a[i], b[i], c[i], qtab, otab)
        for k in range(4):
            out[i, k] = r[k]


def _points(points):
    return np.ascontiguousarray(np.asarray(points, float).reshape(-1, 3))


def _split(out):
    """(phi, grad phi, I, grad I) from the (n, 8) rows of a *_field loop."""
    return out[:, 0], out[:, 1:4], out[:, 4], out[:, 5:8]


def box(points, half_extents, h, container=False, tabs=None):
    """phi (n,), grad phi (n, 3), I (n,), grad I (n, 3) of a box centred at the origin, axis-aligned."""
    p = _points(points)
    qtab, otab = tabs if tabs is not None else tables()
    out = np.empty((len(p), 8))
    ex, ey, ez = (float(v) for v in half_extents)
    _box_loop(p, ex, ey, ez, float(h), bool(container), qtab, otab, out)
    return _split(out)


def sphere(points, radius, h, container=False):
    """As `box`, for a ball of `radius` centred at the origin."""
    p = _points(points)
    out = np.empty((len(p), 8))
    _sphere_loop(p, float(radius), float(h), bool(container), out)
    return _split(out)


def plane(points, normal, offset, h):
    """As `box`, for the solid n . x < offset (n is normalised here)."""
    p = _points(points)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    out = np.empty((len(p), 8))
    _plane_loop(p, n[0], n[1], n[2], float(offset), float(h), out)
    return _split(out)


def reading(mass, delta_h=DELTA_H):
    """Lambda, dLambda/dI, psi/H for kernel masses I (any shape; flattened)."""
    m = np.ascontiguousarray(np.ravel(np.asarray(mass, float)))
    out = np.empty((len(m), 3))
    _reading_loop(m, float(delta_h), out)
    return out[:, 0], out[:, 1], out[:, 2]


def quarter(a, b, tabs=None):
    """The interpolated Q(a, b) and its gradient, (n, 3), for a, b >= 0 (units of H)."""
    a, b = (np.ascontiguousarray(v) for v in _prep(a, b))
    out = np.empty((len(a), 3))
    _quarter_loop(a, b, *(tabs or tables()), out)
    return out


def octant(a, b, c, tabs=None):
    """The interpolated O(a, b, c) and its gradient, (n, 4), for a, b, c >= 0 (units of H)."""
    a, b, c = (np.ascontiguousarray(v) for v in _prep(a, b, c))
    out = np.empty((len(a), 4))
    _octant_loop(a, b, c, *(tabs or tables()), out)
    return out
