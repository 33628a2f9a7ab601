"""Cubic spline kernel (method.md section 1): moments, gradient, support, symmetry."""
import math

import numpy as np
import pytest
from numba import njit

from ipsph.kernels import grad_w_factor, w, w_zero


@njit
def _w(r, h):
    return w(r, h)


@njit
def _g(r, h):
    return grad_w_factor(r, h)


def _w_reference(r, h):
    """The piecewise formula exactly as method.md writes it."""
    q = r / h
    c = 8.0 / (math.pi * h ** 3)
    if q <= 0.5:
        return c * (6 * q ** 3 - 6 * q ** 2 + 1)
    if q <= 1.0:
        return 2 * c * (1 - q) ** 3
    return 0.0


def _grad_reference(r, h):
    q = r / h
    cp = 48.0 / (math.pi * h ** 3)
    if r < 1e-9 or q > 1.0:
        return 0.0
    if q <= 0.5:
        return cp * q * (3 * q - 2) / (r * h)
    return -cp * (1 - q) ** 2 / (r * h)


H = 0.1


@pytest.mark.parametrize("r", np.linspace(0.0, 1.2 * H, 49))
def test_branch_free_form_matches_method_md(r):
    # the branch-free rewrite must be the same function to rounding (1e-12 relative)
    assert _w(r, H) == pytest.approx(_w_reference(r, H), rel=1e-12, abs=1e-9)
    assert _g(r, H) == pytest.approx(_grad_reference(r, H), rel=1e-12, abs=1e-6)


def test_w_zero_and_compact_support():
    assert _w(0.0, H) == pytest.approx(w_zero(H), rel=1e-14)
    assert _w(H, H) == 0.0 and _w(1.0001 * H, H) == 0.0
    assert _g(H, H) == 0.0 and _g(2 * H, H) == 0.0
    assert _g(0.0, H) == 0.0  # no division by zero at r = 0


def _lattice(d, n):
    g = (np.arange(-n, n + 1)) * d
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


@pytest.mark.parametrize("offset", [(0, 0, 0), (0.013, -0.021, 0.007)])
def test_partition_of_unity_and_zero_gradient_moment(offset):
    # on a lattice of spacing d = H/2 (our 2r with H = 4r), sum_j W(x - x_j) d^3 = 1 within 1 %
    # (the spline's discretisation error at 2 particles per support radius is a fraction of a
    # percent), and at a lattice site sum_j grad W d^3 vanishes (symmetry of the lattice).
    d = H / 2
    pts = _lattice(d, 4)
    x = np.asarray(offset) * d / 0.05
    rel = x - pts
    r = np.linalg.norm(rel, axis=1)
    s = sum(_w(ri, H) for ri in r) * d ** 3
    assert s == pytest.approx(1.0, abs=0.01)
    g = np.array([_g(ri, H) for ri in r])
    grad = (g[:, None] * rel).sum(axis=0) * d ** 3
    if offset == (0, 0, 0):
        assert np.linalg.norm(grad) < 1e-9


def test_gradient_matches_finite_differences():
    # central differences of W along a random direction; tolerance 1e-5 relative to max |grad W|
    rng = np.random.default_rng(1)
    gmax = max(abs(_g(r, H) * r) for r in np.linspace(1e-4, H, 200))
    eps = 1e-7
    for _ in range(200):
        x = rng.uniform(-H, H, 3)
        r = np.linalg.norm(x)
        if r < 1e-3 or abs(r - 0.5 * H) < 1e-4 or abs(r - H) < 1e-4:
            continue
        grad = _g(r, H) * x
        for a in range(3):
            e = np.zeros(3)
            e[a] = eps
            fd = (_w(np.linalg.norm(x + e), H) - _w(np.linalg.norm(x - e), H)) / (2 * eps)
            assert abs(fd - grad[a]) <= 1e-5 * gmax


def test_gradient_antisymmetric_and_points_inward():
    # grad W(x_ij) = -grad W(x_ji), and it points from i towards j (W decreases with r)
    x = np.array([0.03, -0.02, 0.01])
    r = np.linalg.norm(x)
    assert np.allclose(_g(r, H) * x, -(_g(r, H) * -x))
    assert _g(r, H) < 0
