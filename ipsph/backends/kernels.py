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

# The fastmath flags of every physics kernel (these and the bodies and passes built on them): no
# nnan/ninf, so NaN checks keep working.
FASTMATH = {"contract", "arcp", "reassoc"}


@njit(inline="always", fastmath=FASTMATH)
def w(r, h):
    """W(r) for a distance r >= 0, branch-free: W = 2c [(1-q)+^3 - 4 (1/2-q)+^3]."""
    q = r / h
    a = max(1.0 - q, 0.0)
    b = max(0.5 - q, 0.0)
    return 16.0 * _INV_PI / (h * h * h) * (a * a * a - 4.0 * b * b * b)


@njit(inline="always", fastmath=FASTMATH)
def grad_w_factor(r, h):
    """g(r) with grad W(x) = g(r) * x, for r = |x|; 0 outside the support and at r = 0.

    Branch-free form of the piecewise gradient: dW/dq = 2c [-3 (1-q)+^2 + 12 (1/2-q)+^2],
    g = dW/dq / (H r) (dW/dq vanishes at q = 0, so r is floored at 1e-9 without effect).
    """
    q = r / h
    a = max(1.0 - q, 0.0)
    b = max(0.5 - q, 0.0)
    return 48.0 * _INV_PI / (h * h * h) * (4.0 * b * b - a * a) / (h * max(r, 1e-9))


@njit(cache=True)
def w_zero(h):
    """W(0) = 8 / (pi H^3)."""
    return 8.0 * _INV_PI / (h * h * h)
