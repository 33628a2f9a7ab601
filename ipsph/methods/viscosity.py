"""The implicit viscosity (method.md section 10): one backward-Euler step of the viscous term,

    (I - nu dt L) v* = v,    L the SPH strain-rate operator of SPlisHSPlasH's Standard model [WKBB18],

solved by conjugate gradients with a Jacobi preconditioner, matrix-free: every product A p is one
neighbour pass (`viscous_bodies.viscous_apply_at`). A is symmetric positive definite in the volume-weighted
inner product sum_i V_i a_i . b_i (V_i = mf / rho_i), which is the one CG uses; the walls enter as a
constant diagonal block and a right-hand side (no-slip, moving walls' velocities included) or not at
all (free-slip). The same solve serves the three methods: PF and IPSPH call it on the velocities
(x - x^n)/dt after the projection, DFSPH after gravity, before its density solve.

Its stop test: |b - A v|_V <= eta |b|_V (`solver.viscosity.error_pct`), at most
`solver.viscosity.max_iterations` iterations (a capped solve counts in `solver_maxed`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..backends.kernels import grad_w_factor
from ..backends.viscous_bodies import eps_of
from ..params import spacing as lattice_spacing

WALL_FACTOR = {"no-slip": 1.0, "free-slip": 0.0}  # simulation.viscosity_walls -> s_w (viscous_bodies.viscous_setup_at)


@functools.lru_cache(maxsize=None)
def full_trace(spacing: float, h: float) -> float:
    """sum_j V k(r_j) r_j^2 over a complete lattice of spacing d (V = d^3, j != 0, r_j < H): the
    trace of the viscous operator's block sum_j V_j k_ij x_ij x_ij^T of a particle with a full
    neighbourhood, what the walls complete next to a wall (viscous_bodies.viscous_setup_at)."""
    m = int(math.ceil(h / spacing))
    g = np.arange(-m, m + 1) * spacing
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    r2 = np.sum(x * x, axis=1)
    keep = (r2 > 0.0) & (r2 < h * h)
    r2 = r2[keep]
    g_r = np.array([grad_w_factor(math.sqrt(q), h) for q in r2])
    return float(np.sum(-10.0 * spacing**3 * g_r * r2 / (r2 + eps_of(h))))


@dataclass
class ViscosityScratch:
    """The solve's arrays: right-hand side b, residual r, preconditioned residual z, direction p,
    A p, the Jacobi diagonal, the walls' 3x3 blocks (6 entries), and three per-particle terms of
    the inner products."""

    b: object
    r: object
    z: object
    p: object
    ap: object
    diag: object
    wmat: object
    rz: object
    rr: object
    pap: object

    @classmethod
    def allocate(cls, be, n):
        vec = [be.zeros(n, (3,)) for _ in range(6)]
        return cls(*vec, be.zeros(n, (6,)), be.zeros(n), be.zeros(n), be.zeros(n))


def viscous_solve(
    be, fluid, x, v, dens, walls, nl, dt: float, nu: float, wall_factor: float, cfg, s: ViscosityScratch, radius: float
):
    """v <- the solution of A v* = b (in place; v is also the first guess), particle radius
    `radius`. Returns (iterations, relative residual, capped)."""
    n = x.shape[0]
    if n == 0 or nu <= 0.0:
        return 0, 0.0, False
    nu_dt = nu * dt
    mf, h = fluid.mf, fluid.h

    def total(a):
        return be.mean(a) * n

    full = full_trace(lattice_spacing(radius), h)
    be.viscous_setup(x, v, mf, dens, walls, nl, h, fluid.rho0, nu_dt, wall_factor, full, s.b, s.diag, s.wmat)
    be.cg_precondition(s.b, s.diag, dens.rho, mf, s.z, s.rz, s.rr)
    bb = total(s.rr)
    if bb <= 0.0:
        return 0, 0.0, False
    tol2 = (cfg.error_pct / 100.0) ** 2 * bb
    be.viscous_apply(x, v, mf, dens, nl, h, nu_dt, s.wmat, s.ap, s.pap)  # r = b - A v
    be.copy(s.r, s.b)
    be.axpy(s.r, -1.0, s.ap)
    be.cg_precondition(s.r, s.diag, dens.rho, mf, s.z, s.rz, s.rr)
    rz, rr = total(s.rz), total(s.rr)
    be.copy(s.p, s.z)
    it = 0
    while (rr > tol2 or it < cfg.min_iterations) and it < cfg.max_iterations:
        be.viscous_apply(x, s.p, mf, dens, nl, h, nu_dt, s.wmat, s.ap, s.pap)
        pap = total(s.pap)
        if pap <= 0.0:  # p = 0: nothing left to solve
            break
        alpha = rz / pap
        be.axpy(v, alpha, s.p)
        be.axpy(s.r, -alpha, s.ap)
        be.cg_precondition(s.r, s.diag, dens.rho, mf, s.z, s.rz, s.rr)
        rz_new, rr = total(s.rz), total(s.rr)
        it += 1
        be.scale(s.p, rz_new / rz)  # p = z + beta p
        be.axpy(s.p, 1.0, s.z)
        rz = rz_new
    return it, math.sqrt(rr / bb), rr > tol2
