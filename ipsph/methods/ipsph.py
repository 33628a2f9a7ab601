"""Incompressible Projective SPH (the paper; method.md section 4): the product's default.

PF made less compressible by two DFSPH additions:

    inertial target      s = x + dt v + dt^2 g;  neighbours at s
    solvePDConstraints   PF passes until the mean density error <= eta_rho   (paper Alg. 2)
    velocities           v = (x - x^n) / dt;  XSPH
    divergenceSolve      DFSPH divergence solve at the projected positions   (paper Alg. 1)
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import StepReport
from .pf import PFData, ProjectiveMethod
from .solves import SolveAt, SolveScratch, divergence_solve


@dataclass
class IPSPHData(PFData):
    """PF's scratch plus the divergence solve's."""

    solve: SolveScratch = None

    @classmethod
    def allocate(cls, be, n):
        base = PFData.allocate(be, n)
        return cls(**vars(base), solve=SolveScratch.allocate(be, n))


class IPSPH(ProjectiveMethod):
    name = "ipsph"
    phases = ("neighbourSearch", "solvePDConstraints", "xsph", "viscositySolve", "divergenceSolve")
    Data = IPSPHData

    def __init__(self, *args):
        super().__init__(*args)
        self.state.zeros("k_div")  # total divergence stiffness of the last step (warm start)
        self.state.zeros("pd_warm", (3,))  # the last step's final PF displacement d(Lam) (warm start)

    def seed(self, p, dt: float) -> None:
        """Lam = -p dt^2 / (rho0 w) (section 3: p = -rho0 Lam / dt^2, over the warm-start fraction w,
        which the first step applies) and its PF displacement d(Lam) in pd_warm, at the sorted
        positions; the pressure output starts at p."""
        w = self.cfg.ipsph.warm_start
        if w <= 0.0:
            return
        be, st, d, fl = self.be, self.state, self.data, self.fluid
        (p,) = self.neighbour_search(p)
        be.densities(st.x, fl.mf, self.boundary, self.lists, fl.h, fl.rho0, d.dens, be.NO_PAIRS)
        be.copy(st.pressure, p)
        be.copy(st.pd_lambda, p)
        be.scale(st.pd_lambda, -dt * dt / (fl.rho0 * w))
        be.viscosity(
            st.x,
            st.v,
            fl.mf,
            d.dens,
            st.pd_lambda,
            self.lists,
            fl.h,
            0.0,
            0.0,
            d.v_out,
            d.drho,
            st.pd_warm,
            be.NO_PAIRS,
        )
        self.dt_prev = dt

    def step(self, dt: float) -> StepReport:
        be, st, d, cfg, div = self.be, self.state, self.data, self.cfg.ipsph, self.cfg.divergence
        rep = self.begin(dt)
        tol = cfg.density_error_pct / 100.0
        x_old = self.inertial_target(dt)
        with self.timer("solvePDConstraints"):
            rep.pd_passes, err = self.project(dt, cfg.min_passes, cfg.max_passes, tol, cfg.warm_start)
            rep.solver_maxed += rep.pd_passes >= cfg.max_passes and err > tol
        with self.timer("xsph"):
            # also sums this step's PF displacement for the next warm start (if on) and fills the
            # pair cache for the divergence solve at the same positions
            pairs = self.velocities(dt, x_old, st.pd_warm if cfg.warm_start > 0.0 else None, fill_pairs=div.enabled)
        self.implicit_viscosity(dt, st.x, st.v, d.dens)  # viscosity_model implicit (method.md 10)
        if div.enabled:
            with self.timer("divergenceSolve"):
                rep.divergence_iterations, rep.divergence_error, maxed = divergence_solve(
                    be,
                    self.fluid,
                    SolveAt(st.x, st.v, d.dens, self.lists, pairs),
                    st.k_div,
                    d.solve,
                    dt,
                    self.dt_prev,
                    div,
                    rate=d.drho,
                )
                rep.solver_maxed += maxed
        be.pf_pressure(st.pressure, st.pd_lambda, self.fluid.rho0, dt)
        be.stiffness_pressure(st.pressure, st.k_div, d.dens.rho, add=True)
        self.wall_reaction(dt, lam=st.pd_lambda, k=(st.k_div,) if div.enabled else (), after_move=True)
        return self.end(dt, d.dens)
