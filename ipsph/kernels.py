"""Cubic spline kernel in 3D (Monaghan 1992), support radius H = 4r (method.md section 1).

    q = |x| / H,   c = 8 / (pi H^3),   c' = 48 / (pi H^3)
    W(q)  = c (6q^3 - 6q^2 + 1)          for q <= 1/2
          = 2c (1 - q)^3                 for 1/2 < q <= 1,   0 beyond
    grad W = c' q (3q - 2) x/(|x| H)     for q <= 1/2
           = -c' (1 - q)^2 x/(|x| H)     for 1/2 < q <= 1,   0 at |x| < 1e-9 or q > 1

These are plain numba functions inlined into every neighbour loop; they take H and
never read globals, so a second backend (numba.cuda) can reuse the same formulas.
"""
import math

from numba import njit

_INV_PI = 1.0 / math.pi


@njit(inline="always", fastmath={"contract", "arcp", "reassoc"})
def w(r, h):
    """W(r) for a distance r >= 0."""
    q = r / h
    c = 8.0 * _INV_PI / (h * h * h)
    if q <= 0.5:
        q2 = q * q
        return c * (6.0 * q2 * q - 6.0 * q2 + 1.0)
    if q <= 1.0:
        t = 1.0 - q
        return 2.0 * c * t * t * t
    return 0.0


@njit(inline="always", fastmath={"contract", "arcp", "reassoc"})
def grad_w_factor(r, h):
    """g(r) with grad W(x) = g(r) * x, for r = |x|; 0 outside the support and at r ~ 0."""
    q = r / h
    if r < 1e-9 or q > 1.0:
        return 0.0
    cp = 48.0 * _INV_PI / (h * h * h)
    if q <= 0.5:
        return cp * q * (3.0 * q - 2.0) / (r * h)
    t = 1.0 - q
    return -cp * t * t / (r * h)


@njit(cache=True)
def w_zero(h):
    """W(0) = 8 / (pi H^3)."""
    return 8.0 * _INV_PI / (h * h * h)
