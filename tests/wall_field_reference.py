"""Independent quadratures for tests/test_wall_field.py: the kernel written out again, the
half-space integral by nested 1D quadrature, any box's kernel mass by shells (Archimedes), a ball's
by shells about its centre, and rest-lattice sums. Nothing here comes from ipsph."""

import math

import numpy as np
from scipy import integrate


def f_kernel(q):
    """The cubic spline's shape, W = (8/(pi H^3)) f(|x|/H), written out from method.md section 1."""
    q = np.asarray(q, float)
    return np.where(q <= 0.5, 6 * q**3 - 6 * q**2 + 1, np.where(q <= 1.0, 2 * (1 - q) ** 3, 0.0))


def w_unit(r):
    return (8 / np.pi) * f_kernel(r)


_U, _UW = np.polynomial.legendre.leggauss(32)
_S, _SW = np.sin(0.5 * np.pi * _U), _UW * 0.5 * np.pi * np.cos(0.5 * np.pi * _U)


def _pieces(breaks, lo, hi):
    b = np.unique(np.clip(np.concatenate([[lo, hi], breaks]), lo, hi))
    return zip(b[:-1], b[1:])


def _nodes(lo, hi):
    """Gauss nodes in z = m + hw sin(pi u/2): square-root end behaviour becomes smooth."""
    m, hw = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return m + hw * _S, hw * _SW


def _arc(rho, x0, x1, y0, y1):
    """Angle of the circle of radius rho (array) about the origin inside [x0, x1] x [y0, y1]:
    its crossings with the four lines, sorted, and each arc between two kept if its middle is in."""
    rho = np.asarray(rho, float)[:, None]
    t = [np.zeros_like(rho), np.full_like(rho, 2 * np.pi)]
    for v in (x0, x1):
        c, ok = np.arccos(np.clip(v / rho, -1, 1)), np.abs(v) < rho
        t += [np.where(ok, c, 2 * np.pi), np.where(ok, 2 * np.pi - c, 2 * np.pi)]
    for v in (y0, y1):
        s, ok = np.arcsin(np.clip(v / rho, -1, 1)), np.abs(v) < rho
        t += [np.where(ok, np.mod(s, 2 * np.pi), 2 * np.pi), np.where(ok, np.pi - s, 2 * np.pi)]
    t = np.sort(np.concatenate(t, axis=1), axis=1)
    mid = 0.5 * (t[:, 1:] + t[:, :-1])
    x, y = rho * np.cos(mid), rho * np.sin(mid)
    inside = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    return np.sum(np.diff(t, axis=1) * inside, axis=1)


def box_mass_ref(lo, hi):
    """Kernel mass of the box lo < x < hi about a point at the origin: int w(r) r^2 Omega(r) dr over
    spheres, r^2 Omega = r int arc(sqrt(r^2 - z^2)) dz on each sphere (Archimedes), Gauss pieces
    between every radius and height where a sphere or a circle meets a face, edge or corner.
    Measured: 2e-10 against Phi, Q and O (test_reference_quadrature_is_exact)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    xs, ys, zs = [abs(x0), abs(x1)], [abs(y0), abs(y1)], [abs(z0), abs(z1)]
    e2 = [a * a + b * b for a in xs for b in ys]
    rb = xs + ys + zs + [0.5] + [math.sqrt(v) for v in e2]
    rb += [math.hypot(a, c) for a in xs + ys for c in zs] + [math.sqrt(v + c * c) for v in e2 for c in zs]
    ws, rhos = [], []
    for ra, rb_ in _pieces(np.array(rb), 0.0, 1.0):
        for r, wr in zip(*_nodes(ra, rb_)):
            zb = [z0, z1] + [
                s * math.sqrt(r * r - c2) for c2 in [a * a for a in xs + ys] + e2 if c2 < r * r for s in (-1, 1)
            ]
            for za, zb_ in _pieces(np.array(zb), max(z0, -r), min(z1, r)):
                if zb_ > za:
                    zz, zw = _nodes(za, zb_)
                    ws.append(wr * w_unit(r) * r * zw)
                    rhos.append(np.sqrt(np.maximum(r * r - zz * zz, 0.0)))
    return float(np.sum(np.concatenate(ws) * _arc(np.concatenate(rhos), x0, x1, y0, y1))) if ws else 0.0


BIG = 10.0  # a half space in box_mass_ref: beyond the support (1) by far


def marginal_ref(q):
    """A(q) = 16 int_|q|^1 f(s) s ds, the kernel's 1D marginal (scipy quad, knot at 1/2)."""
    q = abs(q)
    return 16 * sum(integrate.quad(lambda s: f_kernel(s) * s, a, b, epsabs=1e-15)[0] for a, b in _pieces([0.5], q, 1.0))


def half_ref(q):
    """Phi(q) = int_q^1 A(z) dz (nested scipy quad)."""
    if q < 0:
        return 1 - half_ref(-q)
    return sum(integrate.quad(marginal_ref, a, b, epsabs=1e-15)[0] for a, b in _pieces([0.5], q, 1.0))


def lattice(lo, hi):
    """Rest-lattice sites (k + 1/2) d, d = 1/2, inside lo <= x <= hi (given in units of d)."""
    ax = [np.arange(a, b) + 0.5 for a, b in zip(lo, hi)]
    return 0.5 * np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)


def lattice_sum(points, sites):
    """d^3 sum_j W(x_i - x_j) over the sites (the fluid's own density, units of rho0)."""
    r = np.linalg.norm(points[:, None, :] - sites[None, :, :], axis=-1)
    return (w_unit(r) * 0.125).sum(axis=1)


def ball_ref(s, radius):
    """I of a ball by shells about its centre: int_0^R rho^2 (2 pi/(s rho)) int_|s-rho|^(s+rho) w(t) t dt drho."""

    def shell(rho):
        lo, hi = abs(s - rho), min(s + rho, 1.0)
        if lo >= hi:
            return 0.0
        inner = sum(integrate.quad(lambda t: w_unit(t) * t, a, b, epsabs=1e-15)[0] for a, b in _pieces([0.5], lo, hi))
        return 2 * np.pi * rho / s * inner

    knots = [v for v in (s - 1, s - 0.5, s + 0.5, s + 1, 0.5 - s, 1 - s) if 0 < v < radius]
    return sum(integrate.quad(shell, a, b, epsabs=1e-14, epsrel=1e-12)[0] for a, b in _pieces(knots, 0.0, radius))
