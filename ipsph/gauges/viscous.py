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
from ..backends.viscous_bodies import _smallest_eigenvalue, eps_of
from .kernels import GRID_CELL_H, _grid, _q, add_force_torque, cell_range


@njit(cache=True)
def _friction(xs, vol, origin, dims, order, start, xa, ma, aorigin, adims, aorder, astart, i, cell, h, full, rho0, out):
    """For fluid particle i: out = (M_i's 6 entries xx yy zz xy xz yz, sum_b V_b k_ib); M = 0 without walls."""
    eps = eps_of(h)
    f00 = f11 = f22 = f01 = f02 = f12 = 0.0
    lo0, lo1, lo2, hi0, hi1, hi2 = cell_range(xs[i], origin, dims, cell, h)
    for c2 in range(lo2, hi2 + 1):
        for c1 in range(lo1, hi1 + 1):
            for c0 in range(lo0, hi0 + 1):
                c = c0 + dims[0] * (c1 + dims[1] * c2)
                for t in range(start[c], start[c + 1]):
                    j = order[t]
                    d0, d1, d2 = xs[i, 0] - xs[j, 0], xs[i, 1] - xs[j, 1], xs[i, 2] - xs[j, 2]
                    r2 = d0 * d0 + d1 * d1 + d2 * d2
                    if r2 < h * h and j != i:
                        kv = -10.0 * vol[j] * grad_w_factor(math.sqrt(r2), h) / (r2 + eps)
                        f00 += kv * d0 * d0
                        f11 += kv * d1 * d1
                        f22 += kv * d2 * d2
                        f01 += kv * d0 * d1
                        f02 += kv * d0 * d2
                        f12 += kv * d1 * d2
    kw = 0.0
    lo0, lo1, lo2, hi0, hi1, hi2 = cell_range(xs[i], aorigin, adims, cell, h)
    for c2 in range(lo2, hi2 + 1):
        for c1 in range(lo1, hi1 + 1):
            for c0 in range(lo0, hi0 + 1):
                c = c0 + adims[0] * (c1 + adims[1] * c2)
                for t in range(astart[c], astart[c + 1]):
                    b = aorder[t]
                    d0, d1, d2 = xs[i, 0] - xa[b, 0], xs[i, 1] - xa[b, 1], xs[i, 2] - xa[b, 2]
                    r2 = d0 * d0 + d1 * d1 + d2 * d2
                    if r2 < h * h:
                        kw += -10.0 * ma[b] / rho0 * grad_w_factor(math.sqrt(r2), h) / (r2 + eps)
    out[:] = 0.0
    out[6] = kw
    if kw > 0.0:
        third = full / 3.0
        m00, m11, m22, m01, m02, m12 = third - f00, third - f11, third - f22, -f01, -f02, -f12
        low = _smallest_eigenvalue(m00, m11, m22, m01, m02, m12)
        if low < 0.0:
            m00 -= low
            m11 -= low
            m22 -= low
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
    out[:] = 0.0
    for b in range(xw.shape[0]):
        f0 = f1 = f2 = 0.0
        lo0, lo1, lo2, hi0, hi1, hi2 = cell_range(xw[b], origin, dims, cell, h)
        for c2 in range(lo2, hi2 + 1):
            for c1 in range(lo1, hi1 + 1):
                for c0 in range(lo0, hi0 + 1):
                    c = c0 + dims[0] * (c1 + dims[1] * c2)
                    for t in range(start[c], start[c + 1]):
                        i = order[t]
                        d0, d1, d2 = xs[i, 0] - xw[b, 0], xs[i, 1] - xw[b, 1], xs[i, 2] - xw[b, 2]
                        r2 = d0 * d0 + d1 * d1 + d2 * d2
                        if r2 >= h * h:
                            continue
                        if math.isnan(fric[i, 6]):
                            _friction(
                                xs, vol, origin, dims, order, start, xa, ma, aorigin, adims, aorder, astart,
                                i, cell, h, full, rho0, fric[i],
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
