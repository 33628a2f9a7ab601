"""The viscous part of a force gauge: the reaction of the implicit viscosity's wall friction
(simulation.viscosity_model = "implicit" with no-slip walls; method.md section 10).

That model drags a fluid particle i next to walls towards the walls' velocity: its velocity
changes by -nu dt M_i (v_i - vw_i) in a step, with

    M_i  = psd((full / 3) I - F_i),   F_i = sum_j V_j k_ij x_ij x_ij^T   (what the fluid around i lacks)
    vw_i = sum_b V_b k_ib v_b / sum_b V_b k_ib,   k_ib = -10 g(r_ib) / (r_ib^2 + 0.01 H^2)

(`backends.viscous_bodies.viscous_setup_at`, V_b = m_b / rho0). The force on the walls is the
opposite, m_i nu M_i (v_i - vw_i), and wall particle b takes the share V_b k_ib / sum_b' V_b' k_ib'
of it. Evaluated, like every gauge, on the fluid as a frame stores it (`kernels._q`): the
end-of-step velocities, where the solve used its own iterate; the wall's particles in the order
given, each over its fluid neighbours.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..backends.kernels import grad_w_factor
from ..backends.viscous_bodies import add_moment, eps_of, friction_block
from .kernels import GRID_CELL_H, _grid, _q, add_force_torque, cell_range


@njit(inline="always")
def _near(p, pts, origin, dims, order, start, cell, h, found, offsets):
    """The points of pts (on their grid `_grid`: origin, dims, order, start) closer than h to p, in the
    grid's order: their indices into found[:n], (p - pts[j], |p - pts[j]|^2) into offsets[:n]. Returns n."""
    n = 0
    lo0, lo1, lo2, hi0, hi1, hi2 = cell_range(p, origin, dims, cell, h)
    for c2 in range(lo2, hi2 + 1):
        for c1 in range(lo1, hi1 + 1):
            for c0 in range(lo0, hi0 + 1):
                c = c0 + dims[0] * (c1 + dims[1] * c2)
                for t in range(start[c], start[c + 1]):
                    j = order[t]
                    d0, d1, d2 = p[0] - pts[j, 0], p[1] - pts[j, 1], p[2] - pts[j, 2]
                    r2 = d0 * d0 + d1 * d1 + d2 * d2
                    if r2 < h * h:
                        found[n] = j
                        offsets[n, 0], offsets[n, 1], offsets[n, 2], offsets[n, 3] = d0, d1, d2, r2
                        n += 1
    return n


@njit(cache=True)
def _friction(
    xs,
    vol,
    origin,
    dims,
    order,
    start,
    xa,
    ma,
    aorigin,
    adims,
    aorder,
    astart,
    i,
    cell,
    h,
    full,
    rho0,
    found,
    offsets,
    out,
):
    """For fluid particle i: out = (M_i's 6 entries xx yy zz xy xz yz, sum_b V_b k_ib); M = 0 without walls.
    found, offsets: `_near`'s scratch, as long as the fluid and the walls."""
    eps = eps_of(h)
    f00 = f11 = f22 = f01 = f02 = f12 = 0.0
    for t in range(_near(xs[i], xs, origin, dims, order, start, cell, h, found, offsets)):
        j = found[t]
        if j != i:
            d0, d1, d2, r2 = offsets[t, 0], offsets[t, 1], offsets[t, 2], offsets[t, 3]
            kv = -10.0 * vol[j] * grad_w_factor(math.sqrt(r2), h) / (r2 + eps)
            f00, f11, f22, f01, f02, f12 = add_moment(f00, f11, f22, f01, f02, f12, kv, d0, d1, d2)
    kw = 0.0
    for t in range(_near(xs[i], xa, aorigin, adims, aorder, astart, cell, h, found, offsets)):
        r2 = offsets[t, 3]
        kw += -10.0 * ma[found[t]] / rho0 * grad_w_factor(math.sqrt(r2), h) / (r2 + eps)
    out[:] = 0.0
    out[6] = kw
    if kw > 0.0:
        m00, m11, m22, m01, m02, m12 = friction_block(full, f00, f11, f22, f01, f02, f12)
        out[0], out[1], out[2], out[3], out[4], out[5] = m00, m11, m22, m01, m02, m12


@njit(cache=True)
def wall_viscous_force(x, v, rho, m, idx, xw, mw, vw, xa, ma, h, nu, full, rho0, centre, out):
    """out = (F, T about centre) of the implicit viscosity's wall friction on the wall particles
    (xw, mw, vw); idx: the fluid within 2H of them (complete neighbourhoods for those within H);
    (xa, ma): every wall particle near them (vw_i and sum_b V_b k_ib run over all walls)."""
    nc = idx.shape[0]
    xs = np.empty((nc, 3))
    vs = np.empty((nc, 3))
    vol = np.empty(nc)
    mass = np.empty(nc)
    for k in range(nc):
        j = idx[k]
        for a in range(3):
            xs[k, a] = _q(x[j, a])
            vs[k, a] = _q(v[j, a])
        mass[k] = _q(m[j])
        vol[k] = mass[k] / _q(rho[j])
    cell = GRID_CELL_H * h
    origin, dims, order, start = _grid(xs, cell)
    aorigin, adims, aorder, astart = _grid(xa, cell)
    fric = np.full((nc, 7), np.nan)  # per fluid particle, computed when a wall particle first needs it
    eps = eps_of(h)
    found, offsets = np.empty(nc, np.int64), np.empty((nc, 4))  # wall particle b's fluid neighbours
    inner, inner_offsets = np.empty(max(nc, xa.shape[0]), np.int64), np.empty((max(nc, xa.shape[0]), 4))
    out[:] = 0.0
    for b in range(xw.shape[0]):
        f0 = f1 = f2 = 0.0
        for t in range(_near(xw[b], xs, origin, dims, order, start, cell, h, found, offsets)):
            i, r2 = found[t], offsets[t, 3]
            if math.isnan(fric[i, 6]):
                _friction(
                    xs, vol, origin, dims, order, start, xa, ma, aorigin, adims, aorder, astart,
                    i, cell, h, full, rho0, inner, inner_offsets, fric[i],
                )  # fmt: skip
            kw = fric[i, 6]
            if not kw > 0.0:
                continue
            share = -10.0 * mw[b] / rho0 * grad_w_factor(math.sqrt(r2), h) / (r2 + eps) / kw
            u0, u1, u2 = vs[i, 0] - vw[b, 0], vs[i, 1] - vw[b, 1], vs[i, 2] - vw[b, 2]
            s = mass[i] * nu * share
            mi = fric[i]
            f0 += s * (mi[0] * u0 + mi[3] * u1 + mi[4] * u2)
            f1 += s * (mi[3] * u0 + mi[1] * u1 + mi[5] * u2)
            f2 += s * (mi[4] * u0 + mi[5] * u1 + mi[2] * u2)
        add_force_torque(out, xw[b], centre, f0, f1, f2)
