"""The shared solves, on explicit arrays: DFSPH's divergence and density solves [BK17 Alg. 2, 3]
and Projective Fluids' local/global iteration [WKB16; the paper's Alg. 2].

Each takes the backend, the fluid constants, the arrays it reads and writes, the neighbour lists
and the pair cache the caller got from the pass that filled it at these positions
(`be.NO_PAIRS`: evaluate the kernel instead), and a `SolveScratch` for its per-iteration arrays.
They hold no state between calls; warm starts arrive as arguments.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..backends import Backend, Densities
from ..backends.bodies import MIN_NEIGHBOURS_WARM
from ..config import DFSPHConfig, DivergenceConfig
from .base import Fluid


@dataclass
class SolveScratch:
    """A pressure solve's per-iteration arrays: stiffness k, residual, warm-start stiffness."""

    k: object
    residual: object
    warm: object

    @classmethod
    def allocate(cls, be: Backend, n: int) -> "SolveScratch":
        return cls(be.zeros(n), be.zeros(n), be.zeros(n))


def divergence_solve(
    be: Backend,
    fl: Fluid,
    x,
    v,
    dens: Densities,
    nl,
    pairs,
    k_total,
    sc: SolveScratch,
    dt: float,
    dt_prev: float | None,
    cfg: DivergenceConfig,
    rate=None,
) -> tuple[int, float, bool]:
    """Make D rho/Dt ~ 0 on `v` at the positions `x` (in place on v) [BK17 Alg. 2].

    Iterates k_i = alpha_i max(D rho_i/Dt, 0) / dt and the velocity correction until
    dt * mean(D rho/Dt) <= eta_v rho0, between the configured min and max iterations.
    Warm start: half the previous step's total stiffness `k_total`, rescaled by dt_prev/dt and
    capped, where D rho_i/Dt > 0 (and the particle has >= MIN_NEIGHBOURS_WARM neighbours). `rate`, when given, is
    a D rho_i/Dt already at hand for that test (IPSPH: the viscosity pass's by-product), which
    saves one residual pass. `k_total` receives everything applied (the next warm start).
    `dens`: the density pass at x. Returns (iterations, error, hit_cap).
    """
    eta = cfg.error_pct / 100.0
    drho, k = sc.residual, sc.k
    if dt_prev is not None:
        if rate is None:
            be.divergence_residual(x, v, fl.mf, dens, nl, pairs, fl.h, dt, drho, k)
            rate = drho  # already 0 below MIN_NEIGHBOURS_WARM neighbours
        be.warm_stiffness(k_total, dt_prev / dt, rate, dens.n_nbrs, MIN_NEIGHBOURS_WARM, sc.warm)
        be.apply_stiffness(x, fl.mf, dens, nl, pairs, fl.h, sc.warm, dt, v, k_total)
    else:
        be.fill(k_total, 0.0)
    be.divergence_residual(x, v, fl.mf, dens, nl, pairs, fl.h, dt, drho, k)
    err = dt * be.mean(drho) / fl.rho0
    it = 0
    while it < cfg.max_iterations and (it < cfg.min_iterations or err > eta):
        be.apply_stiffness(x, fl.mf, dens, nl, pairs, fl.h, k, dt, v, k_total)
        be.divergence_residual(x, v, fl.mf, dens, nl, pairs, fl.h, dt, drho, k)
        err = dt * be.mean(drho) / fl.rho0
        it += 1
    return it, err, bool(err > eta)


def density_solve(
    be: Backend,
    fl: Fluid,
    x,
    v,
    dens: Densities,
    nl,
    pairs,
    k_total,
    sc: SolveScratch,
    dt: float,
    dt_prev: float | None,
    cfg: DFSPHConfig,
) -> tuple[int, bool]:
    """Make rho + dt D rho/Dt(v) ~ rho0 (in place on v) [BK17 Alg. 3]: k_i = alpha_i (rho*_i - rho0)
    / dt^2 until mean(rho* - rho0) <= eta rho0. Warm start: half of `k_total` rescaled by
    (dt_prev/dt)^2, capped, everywhere. Returns (iterations, hit_cap)."""
    eta = cfg.density_error_pct / 100.0
    res, k = sc.residual, sc.k
    be.density_residual(x, v, fl.mf, dens, nl, pairs, fl.h, fl.rho0, dt, res, k)
    if dt_prev is not None:
        be.warm_stiffness(k_total, (dt_prev / dt) ** 2, None, dens.n_nbrs, 0, sc.warm)
        be.apply_stiffness(x, fl.mf, dens, nl, pairs, fl.h, sc.warm, dt, v, k_total)
        be.density_residual(x, v, fl.mf, dens, nl, pairs, fl.h, fl.rho0, dt, res, k)
    else:
        be.fill(k_total, 0.0)
    err = be.mean(res) / fl.rho0
    it = 0
    while it < cfg.density_max_iterations and (it < cfg.density_min_iterations or err > eta):
        be.apply_stiffness(x, fl.mf, dens, nl, pairs, fl.h, k, dt, v, k_total)
        be.density_residual(x, v, fl.mf, dens, nl, pairs, fl.h, fl.rho0, dt, res, k)
        err = be.mean(res) / fl.rho0
        it += 1
    return it, bool(err > eta)


def pd_solve(
    be: Backend,
    fl: Fluid,
    *,
    x,
    x_spare,
    s,
    lam_sum,
    dens: Densities,
    walls,
    nl,
    dt: float,
    stiffness: float,
    min_passes: int,
    max_passes: int,
    tol: float,
    warm=None,
    warm_scale: float = 0.0,
):
    """Local/global passes from x = s until the mean density error <= tol [WKB16 sec. 4; paper Alg. 2].

    Each pass: local step (`be.densities` at x) -> stop test -> global step (closed form,
    Jacobi, into `x_spare`; the two swap). The final local step leaves `dens` valid at the
    projected positions. Accumulates the pressure multiplier in `lam_sum`. `s` receives the
    inertial target (a copy of x on entry).

    Warm start (IPSPH only, a [choice] of ours), when `warm_scale` > 0: before the first pass,
    displace x by `warm_scale` times the previous step's final PF displacement d(Lam) (`warm`,
    summed by the previous step's viscosity pass at its projected positions), already rescaled to
    this step (Lam ~ p dt^2) by the caller; Lam starts from the same scaled multipliers. The stop
    test is unchanged, so the result meets the same tolerance in fewer passes.

    Returns (passes, mean error, x, x_spare): the arrays holding the result and the spare.
    """
    be.copy(s, x)  # the inertial target
    a = dt * dt * stiffness
    if warm_scale > 0.0:
        be.axpy(x, warm_scale / fl.rho0, warm)  # pf_global's pure displacement (a -> infinity) by c Lam
        be.scale(lam_sum, warm_scale)
    else:
        be.fill(lam_sum, 0.0)
    passes = 0
    while True:
        be.densities(x, fl.mf, walls, nl, fl.h, fl.rho0, dens, be.NO_PAIRS)
        err = be.mean(dens.err)
        if passes >= max_passes or (passes >= min_passes and err <= tol):
            break
        be.pf_global(x, s, fl.mf, dens, nl, fl.h, fl.rho0, a, x_spare, lam_sum)
        x, x_spare = x_spare, x
        passes += 1
    return passes, err, x, x_spare
