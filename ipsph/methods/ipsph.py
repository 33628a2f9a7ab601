"""Incompressible Projective SPH (the paper; method.md section 4): the product's default.

PF made less compressible by two DFSPH additions:

    inertial target      s = x + dt v + dt^2 g;  neighbours at s
    solvePDConstraints   PF passes until the mean density error <= eta_rho   (paper Alg. 2)
    velocities           v = (x - x^n) / dt;  XSPH
    divergenceSolve      DFSPH divergence solve at the projected positions   (paper Alg. 1)
"""
from __future__ import annotations

from .base import StepReport
from .dfsph import divergence_solve
from .pf import ProjectiveMethod, pd_solve
from .sph_passes import NO_DISPLACEMENT


class IPSPH(ProjectiveMethod):
    name = "ipsph"
    phases = ("neighbourSearch", "solvePDConstraints", "xsph", "divergenceSolve")

    def __init__(self, *args):
        super().__init__(*args)
        self.state.zeros("k_div")  # total divergence stiffness of the last step (warm start)
        self.state.zeros("pd_warm", (3,))  # the last step's final PF displacement d(Lam) (warm start)

    def step(self, dt: float) -> StepReport:
        self.report = rep = StepReport(dt=dt)
        st, cfg = self.state, self.cfg
        x_old = self.inertial_target(dt)
        with self.timer("solvePDConstraints"):
            rep.pd_passes, err = pd_solve(self, dt, cfg.ipsph_min_passes, cfg.ipsph_max_passes,
                                          cfg.ipsph_density_error_pct / 100.0, cfg.ipsph_warm_start)
            rep.solver_maxed += rep.pd_passes >= cfg.ipsph_max_passes and err > cfg.ipsph_density_error_pct / 100.0
        with self.timer("xsph"):
            # XSPH also sums this step's PF displacement for the next step's warm start (if on)
            # and fills the pair cache for the divergence solve at the same positions
            self.projected_velocities(dt, x_old, st.pd_warm if cfg.ipsph_warm_start > 0.0 else NO_DISPLACEMENT,
                                      fill_pair_cache=cfg.divergence_solve)
        if cfg.divergence_solve:
            with self.timer("divergenceSolve"):
                rep.divergence_iterations, rep.divergence_error, maxed = divergence_solve(self, dt, st.k_div, self.drho)
                rep.solver_maxed += maxed
        st.pressure[:] = self.pf_pressure(dt) + st.k_div * self.rho * self.rho
        rep.density_error_mean, rep.density_error_max = self.density_errors()
        self.dt_prev = dt
        return rep
