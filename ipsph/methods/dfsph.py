"""Divergence-Free SPH [BK15, BK17]: the reference method (method.md section 2).

Per step (the densities and factors at x^n come from the end of the previous step):

    divergenceSolve   make D rho/Dt ~ 0 on v^n              (stiffness k^v, warm started)
    non-pressure      v* = v + dt g, XSPH
    densitySolve      make rho + dt D rho/Dt(v*) ~ rho0       (stiffness k, warm started)
    advect            x += dt v
    neighbours, rho, alpha at x^{n+1}                         (the end-of-step density error)

`divergence_solve` is shared with IPSPH (the paper's Algorithm 1).
"""
from __future__ import annotations

import numpy as np

from .base import Method, StepReport
from .sph_passes import (NO_DISPLACEMENT, NO_PAIR_CACHE, accelerate, apply_stiffness, density_factor_lambda,
                         density_residual, divergence_residual, mean, warm_stiffness, xsph)

EVERY_PARTICLE = np.zeros(0)  # warm_stiffness(..., rate=EVERY_PARTICLE): no mask


def divergence_solve(method: Method, dt: float, k_total: np.ndarray,
                     rate: np.ndarray | None = None) -> tuple[int, float, bool]:
    """DFSPH divergence solve on `method.state.v` at the current positions [BK17 Alg. 2].

    Iterates k_i = alpha_i max(D rho_i/Dt, 0) / dt and the velocity correction until
    dt * mean(D rho/Dt) <= eta_v rho0, between the configured min and max iterations.
    Warm start: half the previous step's total stiffness, rescaled by dt_prev/dt and capped,
    where D rho_i/Dt > 0 (and the particle has >= 20 neighbours). `rate`, when given, is a
    D rho_i/Dt already at hand for that test (IPSPH: XSPH's by-product, from the velocities just
    before the filter), which saves one residual pass; otherwise it is computed here.
    `k_total` receives everything applied (the next warm start).
    Needs method.alpha, method.n_nbrs and method.gb at the current positions, and reads the pair
    cache method.pair_grad when the last pass at these positions filled it.
    Returns (iterations, error, hit_cap).
    """
    st, cfg = method.state, method.cfg
    _, _, nf, cf, _, _ = method.lists()
    x, v, m, h = st.x, st.v, method.mf, method.h
    k, drho, gb, pg = method.k, method.drho, method.gb, method.pair_grad
    eta = cfg.divergence_error_pct / 100.0
    if method.dt_prev is not None:
        if rate is None:
            divergence_residual(x, v, m, gb, nf, cf, pg, h, method.alpha, method.n_nbrs, dt, drho, k)
            rate = drho  # already 0 below 20 neighbours
        warm = np.empty_like(k_total)
        warm_stiffness(k_total, method.dt_prev / dt, rate, method.n_nbrs, 20, warm)
        apply_stiffness(x, m, gb, nf, cf, pg, h, warm, dt, v, k_total)
    else:
        k_total[:] = 0.0
    divergence_residual(x, v, m, gb, nf, cf, pg, h, method.alpha, method.n_nbrs, dt, drho, k)
    err = dt * mean(drho) / method.rho0
    it = 0
    while it < cfg.divergence_max_iterations and (it < cfg.divergence_min_iterations or err > eta):
        apply_stiffness(x, m, gb, nf, cf, pg, h, k, dt, v, k_total)
        divergence_residual(x, v, m, gb, nf, cf, pg, h, method.alpha, method.n_nbrs, dt, drho, k)
        err = dt * mean(drho) / method.rho0
        it += 1
    return it, err, bool(err > eta)


class DFSPH(Method):
    name = "dfsph"
    phases = ("neighbourSearch", "densities", "divergenceSolve", "xsph", "densitySolve")

    def __init__(self, *args):
        super().__init__(*args)
        self.state.zeros("k_div")   # total divergence stiffness of the last step (warm start)
        self.state.zeros("k_dens")  # total density stiffness of the last step (warm start, pressure)

    def prepare(self) -> None:
        self.neighbour_search()
        self._densities()

    def _densities(self) -> None:
        st = self.state
        xb, mb, nf, cf, nb, cb = self.lists()
        with self.timer("densities"):
            # the positions stay until the next step's advection: its solves read the pair cache
            density_factor_lambda(st.x, self.mf, xb, mb, nf, cf, nb, cb, self.h, self.rho0, self.rho,
                                  self.alpha, self.lam, self.err, self.n_nbrs, self.gb,
                                  self.pair_cache_to_fill())

    def step(self, dt: float) -> StepReport:
        self.report = rep = StepReport(dt=dt)
        st, cfg = self.state, self.cfg
        _, _, nf, cf, _, _ = self.lists()
        if cfg.divergence_solve:
            with self.timer("divergenceSolve"):
                rep.divergence_iterations, rep.divergence_error, maxed = divergence_solve(self, dt, st.k_div)
                rep.solver_maxed += maxed
        with self.timer("xsph"):
            accelerate(st.v, dt, self.g)
            # (lam is not read without a displacement)
            xsph(st.x, st.v, self.mf, self.rho, self.gb, self.lam, nf, cf, self.h, self.scene.viscosity,
                 self.scene.standard_viscosity * dt, self.scratch_v, self.drho, NO_DISPLACEMENT, NO_PAIR_CACHE)
            st.v[:] = self.scratch_v
        with self.timer("densitySolve"):
            rep.density_iterations, maxed = self.density_solve(dt)
            rep.solver_maxed += maxed
            st.pressure[:] = st.k_dens * self.rho * self.rho
        st.x += dt * st.v
        self.prepare()
        rep.density_error_mean, rep.density_error_max = self.density_errors()
        self.dt_prev = dt
        return rep

    def density_solve(self, dt: float) -> tuple[int, bool]:
        """[BK17 Alg. 3]: k_i = alpha_i (rho*_i - rho0) / dt^2 until mean(rho* - rho0) <= eta rho0."""
        st, cfg = self.state, self.cfg
        _, _, nf, cf, _, _ = self.lists()
        x, v, m, h, k, gb = st.x, st.v, self.mf, self.h, self.k, self.gb  # gb, alpha: from prepare()
        pg = self.pair_grad
        eta = cfg.density_error_pct / 100.0
        k_total = st.k_dens
        density_residual(x, v, m, gb, nf, cf, pg, h, self.rho, self.alpha, self.rho0, dt, self.err, k)
        if self.dt_prev is not None:
            warm = np.empty_like(k_total)
            warm_stiffness(k_total, (self.dt_prev / dt) ** 2, EVERY_PARTICLE, self.n_nbrs, 0, warm)
            apply_stiffness(x, m, gb, nf, cf, pg, h, warm, dt, v, k_total)
            density_residual(x, v, m, gb, nf, cf, pg, h, self.rho, self.alpha, self.rho0, dt, self.err, k)
        else:
            k_total[:] = 0.0
        err = mean(self.err) / self.rho0
        it = 0
        while it < cfg.density_max_iterations and (it < cfg.density_min_iterations or err > eta):
            apply_stiffness(x, m, gb, nf, cf, pg, h, k, dt, v, k_total)
            density_residual(x, v, m, gb, nf, cf, pg, h, self.rho, self.alpha, self.rho0, dt, self.err, k)
            err = mean(self.err) / self.rho0
            it += 1
        return it, bool(err > eta)
