"""The exact kernel integral of a closed triangle mesh's solid, I(x) = ∫_Ω W(x − x′) dx′, at points.

Cubic spline W (backends/kernels.py), lengths in units of the support H (so W(q) = (8/π)(1 − 6q² +
6q³) for q ≤ 1/2, (16/π)(1 − q)³ for 1/2 < q ≤ 1). With F(ρ) = ∫₀^ρ W s² ds (F(1) = F_H = 1/4π) the
field G(y) = y F(|y|)/|y|³ has ∇·G = W, so by the divergence theorem, over the triangles t (outward
unit normal n_t, h_t = (v_t − x)·n_t the signed height of x below t's plane, ρ = |y − x|):

    I(x) = Σ_t ∫_t F(ρ) h_t/ρ³ dA = w(x) − Σ_t C_t,   C_t = h_t ∫_t (F_H − F(ρ))/ρ³ dA,

w the winding number (Σ_t F_H × solid angle; 1 inside, 0 outside) and C_t zero for every
triangle farther than H. C_t in polar coordinates about x's foot p₀ on t's plane, one signed
sub-triangle (p₀, edge) per edge e at in-plane distance d_e from p₀ (positive on t's inner side),
ℓ the position along the edge from p₀'s foot on it, ρ_e² = h² + d_e² + ℓ², dθ = d_e dℓ/(d_e² + ℓ²):

    C_t = h Σ_e ∫ [N(|h|) − N(ρ_e)] d_e dℓ/(d_e² + ℓ²),   N(ρ) = ∫_ρ^1 (F_H − F)/s² ds = F_H/ρ − F_H − M(1) + M(ρ)

(N = 0 beyond the support; M(ρ) = ∫₀^ρ F/s² ds). The 1/ρ part integrates in closed form to the
solid angle (atan2 forms), the part outside the ball to a plane angle, and what is left,
Q_e = ∫_ball (M(ρ_e) − M(|h|)) d_e dℓ/(d_e² + ℓ²), has a smooth bounded integrand (M is C⁴):
Gauss–Legendre on the pieces between ρ_e = H/2 and H. No angular or volume discretisation: the
result is exact to the Gauss rule (≈1e-7 with 6 points a piece on the bunny; tests/test_mesh_field.py).

w is taken from the sign of φ (libigl's winding-number sign). On the surface the sum has no limit
(at a box corner each face's share depends on the way in: π/2 from the apex, 7π/6 along the
diagonal), so a point within ON_SURFACE of it is first moved NUDGE off it and w read from the sign
of C (0 < I < 1 there, so C = w − I > 0 exactly when w = 1).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

F_H = 1.0 / (4.0 * math.pi)  # F(1): the kernel's whole mass over 4π
M_1 = 9.0 / (20.0 * math.pi)  # M(1)
# Points closer to the surface than ON_SURFACE (in H) are moved NUDGE along NUDGE_DIR (a direction no
# mesh face of practical interest is parallel to): I changes by < 2e-8 there, far below float32.
ON_SURFACE = 1e-6
NUDGE = 1e-8
NUDGE_DIR = (0.5123167361322618, 0.6258837438407195, 0.5880485533310245)
GAUSS_POINTS = 6  # per piece of an edge: the pieces are analytic in ℓ (module doc); 1.5e-7 against 16 points


@nb.njit(inline="always")
def _m(r):
    """M(ρ) = ∫₀^ρ F(s)/s² ds for 0 ≤ ρ ≤ 1 (H = 1)."""
    if r <= 0.5:
        r2 = r * r
        return (4.0 / 3.0 * r2 - 2.4 * r2 * r2 + 1.6 * r2 * r2 * r) / math.pi
    r2 = r * r
    return (
        -8.0 / 15.0 * r2 * r2 * r + 2.4 * r2 * r2 - 4.0 * r2 * r + 8.0 / 3.0 * r2 - 0.1 + 1.0 / (60.0 * r)
    ) / math.pi


@nb.njit(inline="always")
def _q_piece(a, b, d, c2, mh, gx, gw):
    """∫_a^b (M(ρ) − M(|h|)) d/(d² + ℓ²) dℓ, ρ² = c2 + ℓ², by Gauss–Legendre (gx, gw on [−1, 1])."""
    half = 0.5 * (b - a)
    mid = 0.5 * (b + a)
    acc = 0.0
    d2 = d * d
    for k in range(gx.shape[0]):
        ell = mid + half * gx[k]
        acc += gw[k] * (_m(math.sqrt(c2 + ell * ell)) - mh) / (d2 + ell * ell)
    return acc * half * d


@nb.njit(inline="always")
def _angle(l2, l1, ad):
    """atan2(l2, ad) − atan2(l1, ad) for ad ≥ 0 in one atan2 (both lie in [−π/2, π/2])."""
    return math.atan2(ad * (l2 - l1), ad * ad + l1 * l2)


@nb.njit(inline="always")
def _triangle_c(px, py, pz, t, tri, nrm, tau, edge_in, tlen, gx, gw):
    """C_t at x = (px, py, pz) (H = 1): the triangle's share of w − I (module doc)."""
    h = (tri[t, 0, 0] - px) * nrm[t, 0] + (tri[t, 0, 1] - py) * nrm[t, 1] + (tri[t, 0, 2] - pz) * nrm[t, 2]
    ah = abs(h)
    if ah >= 1.0:
        return 0.0
    sgn = 1.0 if h >= 0.0 else -1.0  # h = 0 with p₀ off the triangle: the terms cancel
    f0 = px + h * nrm[t, 0]
    f1 = py + h * nrm[t, 1]
    f2 = pz + h * nrm[t, 2]
    mh = _m(ah)
    h_n = sgn * F_H - h * (F_H + M_1 - mh)  # h N(|h|)
    acc = 0.0
    for e in range(3):
        rx, ry, rz = f0 - tri[t, e, 0], f1 - tri[t, e, 1], f2 - tri[t, e, 2]
        d = rx * edge_in[t, e, 0] + ry * edge_in[t, e, 1] + rz * edge_in[t, e, 2]
        if d == 0.0:
            continue  # p₀ on the edge's line: a sub-triangle of zero angle
        l1 = -(rx * tau[t, e, 0] + ry * tau[t, e, 1] + rz * tau[t, e, 2])
        l2 = l1 + tlen[t, e]
        ad = abs(d)
        sd = 1.0 if d > 0.0 else -1.0
        c2 = h * h + d * d
        la = l2
        lb = l2
        if c2 < 1.0:
            big = math.sqrt(1.0 - c2)
            la = max(l1, -big)
            lb = min(l2, big)
        if la < lb:  # the edge's part inside the ball: angle, solid angle, Gauss on the rest
            ra = math.sqrt(c2 + la * la)
            rb = math.sqrt(c2 + lb * lb)
            a_in = _angle(lb, la, ad)
            s_in = math.atan2(ad * ah * (lb * ra - la * rb), ad * ad * ra * rb + la * lb * ah * ah)
            q = 0.0
            knot = math.sqrt(0.25 - c2) if c2 < 0.25 else 0.0  # split where ρ_e = 1/2 (the spline's knot)
            lo = la
            for cut in (-knot, knot, lb):
                hi = min(cut, lb)
                if hi > lo:
                    q += _q_piece(lo, hi, d, c2, mh, gx, gw)
                    lo = hi
            acc += sd * (sgn * F_H * (a_in - s_in) + h_n * (_angle(l2, l1, ad) - a_in)) - h * q
        else:
            acc += sd * h_n * _angle(l2, l1, ad)
    return acc


@nb.njit(parallel=True, cache=True)
def _integral_kernel(
    points, phi, tri, nrm, tau, edge_in, tlen, centre, radius, b_lo, b_dims, b_start, b_tri, gx, gw, out
):
    """out_i = I(points_i) (H = 1) over the triangles bucketed in i's cell; phi_i its signed distance."""
    nbx, nby, nbz = b_dims[0], b_dims[1], b_dims[2]
    for i in nb.prange(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        on_surface = abs(phi[i]) < ON_SURFACE
        if on_surface:  # the sum has no limit on the surface (it depends on the way in): step off it
            px += NUDGE * NUDGE_DIR[0]
            py += NUDGE * NUDGE_DIR[1]
            pz += NUDGE * NUDGE_DIR[2]
        bx = min(max(int(math.floor(px - b_lo[0])), 0), nbx - 1)
        by = min(max(int(math.floor(py - b_lo[1])), 0), nby - 1)
        bz = min(max(int(math.floor(pz - b_lo[2])), 0), nbz - 1)
        cell = bx + nbx * (by + nby * bz)
        c = 0.0
        for k in range(b_start[cell], b_start[cell + 1]):
            t = b_tri[k]
            dx, dy, dz = px - centre[t, 0], py - centre[t, 1], pz - centre[t, 2]
            reach = 1.0 + radius[t]
            if dx * dx + dy * dy + dz * dz >= reach * reach:
                continue
            c += _triangle_c(px, py, pz, t, tri, nrm, tau, edge_in, tlen, gx, gw)
        if on_surface:  # 0 < I < 1 next to the surface, so C = w − I has the sign of w
            val = (1.0 if c > 0.0 else 0.0) - c
        else:
            val = (1.0 if phi[i] < 0.0 else 0.0) - c
            if val < -1e-6:  # the sign of φ disagreed with the geometry: I is off by one
                val += 1.0
            elif val > 1.0 + 1e-6:
                val -= 1.0
        out[i] = min(max(val, 0.0), 1.0)


@nb.njit(cache=True)
def _count_buckets(lo_idx, hi_idx, dims, count):
    for t in range(lo_idx.shape[0]):
        for k in range(lo_idx[t, 2], hi_idx[t, 2] + 1):
            for j in range(lo_idx[t, 1], hi_idx[t, 1] + 1):
                for i in range(lo_idx[t, 0], hi_idx[t, 0] + 1):
                    count[i + dims[0] * (j + dims[1] * k) + 1] += 1


@nb.njit(cache=True)
def _fill_buckets(lo_idx, hi_idx, dims, start, out):
    fill = start[:-1].copy()
    for t in range(lo_idx.shape[0]):
        for k in range(lo_idx[t, 2], hi_idx[t, 2] + 1):
            for j in range(lo_idx[t, 1], hi_idx[t, 1] + 1):
                for i in range(lo_idx[t, 0], hi_idx[t, 0] + 1):
                    c = i + dims[0] * (j + dims[1] * k)
                    out[fill[c]] = t
                    fill[c] += 1


class MeshIntegral:
    """I(x) of one closed, outward-oriented triangle mesh (vertices, faces) for kernel support H.

    Triangles are bucketed on a grid of cells of size H over [lo, hi] (each triangle in every cell
    its bounding box grown by H meets), so a point costs the triangles near it only. Points outside
    [lo, hi] see the nearest cell's triangles (give lo, hi covering every point asked for).
    """

    def __init__(self, vertices, faces, support: float, lo, hi):
        self.support = float(support)
        s = 1.0 / self.support
        v = np.asarray(vertices, dtype=np.float64) * s
        f = np.asarray(faces, dtype=np.int64)
        tri = np.ascontiguousarray(v[f])  # (m, 3, 3)
        e = np.roll(tri, -1, axis=1) - tri  # edge e: corner e -> corner e+1
        tlen = np.linalg.norm(e, axis=2)
        cross = np.cross(e[:, 0], e[:, 1])
        area2 = np.linalg.norm(cross, axis=1)
        keep = (area2 > 0.0) & np.all(tlen > 0.0, axis=1)  # degenerate triangles carry no flux
        self.tri = np.ascontiguousarray(tri[keep])
        self.nrm = np.ascontiguousarray(cross[keep] / area2[keep, None])
        self.tlen = np.ascontiguousarray(tlen[keep])
        self.tau = np.ascontiguousarray(e[keep] / self.tlen[:, :, None])
        self.edge_in = np.ascontiguousarray(np.cross(self.nrm[:, None, :], self.tau))  # n × τ: into the triangle
        self.centre = np.ascontiguousarray(self.tri.mean(axis=1))
        self.radius = np.ascontiguousarray(np.linalg.norm(self.tri - self.centre[:, None], axis=2).max(axis=1))
        self.b_lo = np.asarray(lo, dtype=np.float64) * s
        dims = np.maximum(np.ceil((np.asarray(hi, dtype=np.float64) * s - self.b_lo)).astype(np.int64), 1)
        self.b_dims = dims
        grow = 1.0 + 1e-9
        t_lo = np.floor(self.tri.min(axis=1) - grow - self.b_lo).astype(np.int64)
        t_hi = np.floor(self.tri.max(axis=1) + grow - self.b_lo).astype(np.int64)
        t_lo = np.clip(t_lo, 0, dims - 1)
        t_hi = np.clip(t_hi, 0, dims - 1)
        count = np.zeros(int(np.prod(dims)) + 1, dtype=np.int64)
        _count_buckets(t_lo, t_hi, dims, count)
        self.b_start = np.cumsum(count)
        self.b_tri = np.empty(int(self.b_start[-1]), dtype=np.int64)
        _fill_buckets(t_lo, t_hi, dims, self.b_start, self.b_tri)
        self.gx, self.gw = np.polynomial.legendre.leggauss(GAUSS_POINTS)

    def __call__(self, points, phi) -> np.ndarray:
        """I at (n, 3) points (same frame and units as the vertices); phi: their signed distances."""
        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3) / self.support)
        out = np.empty(len(p), dtype=np.float64)
        if len(p):
            _integral_kernel(
                p,
                np.ascontiguousarray(np.asarray(phi, dtype=np.float64).ravel() / self.support),
                self.tri,
                self.nrm,
                self.tau,
                self.edge_in,
                self.tlen,
                self.centre,
                self.radius,
                self.b_lo,
                self.b_dims,
                self.b_start,
                self.b_tri,
                self.gx,
                self.gw,
                out,
            )
        return out
