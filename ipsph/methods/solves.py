"""The shared solves: DFSPH's divergence and density solves [BK17 Alg. 2, 3] and Projective
Fluids' local/global iteration [WKB16; the paper's Alg. 2].

Each takes the backend, the fluid constants, the arrays it reads and writes (DFSPH's: one
`SolveAt`), the neighbour lists and the pair cache the caller got from the pass that filled it at
these positions (`be.NO_PAIRS`: evaluate the kernel instead), and a `SolveScratch` for its
per-iteration arrays.
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


@dataclass(frozen=True)
class SolveAt:
    """What a DFSPH solve iterates on: the positions x (fixed), the velocities v (corrected in
    place), the density pass at x (`dens`), the neighbour lists and the pair cache that pass filled."""

    x: object
    v: object
    dens: Densities
    nl: object
    pairs: object

    def apply(self, be: Backend, fl: Fluid, k, dt: float, k_total) -> None:
        """v -= dt sum_j m (k_i + k_j) grad W_ij (+ the walls' terms); k_total += k."""
        be.apply_stiffness(self.x, fl.mf, self.dens, self.nl, self.pairs, fl.h, k, dt, self.v, k_total)


def _iterate(be: Backend, fl: Fluid, at: SolveAt, sc: SolveScratch, k_total, dt: float, residual, error, stop):
    """The Jacobi loop both solves share: apply k, recompute the residual (and k), until
    error() <= eta after at least lo and at most hi iterations, stop = (eta, lo, hi).
    Returns (iterations, error)."""
    eta, lo, hi = stop
    err = error()
    it = 0
    while it < hi and (it < lo or err > eta):
        at.apply(be, fl, sc.k, dt, k_total)
        residual()
        err = error()
        it += 1
    return it, err


def divergence_solve(
    be: Backend,
    fl: Fluid,
    at: SolveAt,
    k_total,
    sc: SolveScratch,
    dt: float,
    dt_prev: float | None,
    cfg: DivergenceConfig,
    rate=None,
) -> tuple[int, float, bool]:
    """Make D rho/Dt ~ 0 on `at.v` at the positions `at.x` [BK17 Alg. 2].

    Iterates k_i = alpha_i max(D rho_i/Dt, 0) / dt and the velocity correction until
    dt * mean(D rho/Dt) <= eta_v rho0, between the configured min and max iterations.
    Warm start: half the previous step's total stiffness `k_total`, rescaled by dt_prev/dt and
    capped, where D rho_i/Dt > 0 (and the particle has >= MIN_NEIGHBOURS_WARM neighbours). `rate`, when given, is
    a D rho_i/Dt already at hand for that test (IPSPH: the viscosity pass's by-product), which
    saves one residual pass. `k_total` receives everything applied (the next warm start).
    Returns (iterations, error, hit_cap).
    """
    drho = sc.residual

    def residual():
        be.divergence_residual(at.x, at.v, fl.mf, at.dens, at.nl, at.pairs, fl.h, dt, drho, sc.k)

    def error():
        return dt * be.mean(drho) / fl.rho0

    if dt_prev is not None:
        if rate is None:
            residual()
            rate = drho  # already 0 below MIN_NEIGHBOURS_WARM neighbours
        be.warm_stiffness(k_total, dt_prev / dt, rate, at.dens.n_nbrs, MIN_NEIGHBOURS_WARM, sc.warm)
        at.apply(be, fl, sc.warm, dt, k_total)
    else:
        be.fill(k_total, 0.0)
    residual()
    eta = cfg.error_pct / 100.0
    it, err = _iterate(be, fl, at, sc, k_total, dt, residual, error, (eta, cfg.min_iterations, cfg.max_iterations))
    return it, err, bool(err > eta)


def density_solve(
    be: Backend,
    fl: Fluid,
    at: SolveAt,
    k_total,
    sc: SolveScratch,
    dt: float,
    dt_prev: float | None,
    cfg: DFSPHConfig,
) -> tuple[int, bool]:
    """Make rho + dt D rho/Dt(v) ~ rho0 (in place on `at.v`) [BK17 Alg. 3]: k_i = alpha_i (rho*_i - rho0)
    / dt^2 until mean(rho* - rho0) <= eta rho0. Warm start: half of `k_total` rescaled by
    (dt_prev/dt)^2, capped, everywhere. Returns (iterations, hit_cap)."""
    res = sc.residual

    def residual():
        be.density_residual(at.x, at.v, fl.mf, at.dens, at.nl, at.pairs, fl.h, fl.rho0, dt, res, sc.k)

    def error():
        return be.mean(res) / fl.rho0

    residual()
    if dt_prev is not None:
        be.warm_stiffness(k_total, (dt_prev / dt) ** 2, None, at.dens.n_nbrs, 0, sc.warm)
        at.apply(be, fl, sc.warm, dt, k_total)
        residual()
    else:
        be.fill(k_total, 0.0)
    eta = cfg.density_error_pct / 100.0
    stop = (eta, cfg.density_min_iterations, cfg.density_max_iterations)
    it, err = _iterate(be, fl, at, sc, k_total, dt, residual, error, stop)
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
