"""Divergence-Free SPH [BK15, BK17]: the reference method (method.md section 2).

Per step (the densities and factors at x^n come from the end of the previous step):

    divergenceSolve   make D rho/Dt ~ 0 on v^n              (stiffness k^v, warm started)
    non-pressure      v* = v + dt g, XSPH
    densitySolve      make rho + dt D rho/Dt(v*) ~ rho0       (stiffness k, warm started)
    advect            x += dt v
    neighbours, rho, alpha at x^{n+1}                         (the end-of-step density error)
"""

from __future__ import annotations

from dataclasses import dataclass

from ..backends import Densities
from .base import Method, StepReport
from .solves import SolveAt, SolveScratch, density_solve, divergence_solve


@dataclass
class DFSPHData:
    """DFSPH's scratch: the densities at x^n (and the pair cache their pass filled), the solves'
    arrays, the viscosity pass's output velocities and density rate."""

    dens: Densities
    solve: SolveScratch
    v_out: object
    drho: object
    pairs: object = None  # the pair cache returned by the last density pass (at x^n)

    @classmethod
    def allocate(cls, be, n):
        return cls(Densities.allocate(be, n), SolveScratch.allocate(be, n), be.zeros(n, (3,)), be.zeros(n), be.NO_PAIRS)


class DFSPH(Method):
    name = "dfsph"
    wall_support = True  # field walls: IPSPH and PF do not take it (method.md section 11)
    phases = ("neighbourSearch", "densities", "divergenceSolve", "xsph", "viscositySolve", "densitySolve")

    def __init__(self, *args):
        super().__init__(*args)
        self.state.zeros("k_div")  # total divergence stiffness of the last step (warm start)
        self.state.zeros("k_dens")  # total density stiffness of the last step (warm start, pressure)
        self.allocate_scratch(DFSPHData)

    def prepare(self) -> None:
        """Neighbours and densities at the current positions (they stay until the next advection,
        so the next step's solves read the pair cache this pass fills)."""
        d, st, fl = self.data, self.state, self.fluid
        self.neighbour_search()
        with self.timer("densities"):
            d.pairs = self.be.densities(
                st.x, fl.mf, self.boundary, self.lists, fl.h, fl.rho0, d.dens, self.pairs.buffer(self.lists)
            )
            self.wall_rate(st.x, d.dens)

    def seed(self, p, dt: float) -> None:
        """K = 2 p / rho0^2 in the density solve's warm start (p = K rho^2, section 2; the warm start
        applies half of it); the state is already sorted and its densities current (prepare)."""
        be, st = self.be, self.state
        be.copy(st.pressure, p)
        be.copy(st.k_dens, p)
        be.scale(st.k_dens, 2.0 / (self.fluid.rho0 * self.fluid.rho0))
        self.dt_prev = dt

    def step(self, dt: float) -> StepReport:
        be, st, d, fl, cfg, nl = self.be, self.state, self.data, self.fluid, self.cfg, self.lists
        rep = self.begin(dt)
        at = SolveAt(st.x, st.v, d.dens, nl, d.pairs)  # both solves: at x^n, on v in place
        if cfg.divergence.enabled:
            with self.timer("divergenceSolve"):
                rep.divergence_iterations, rep.divergence_error, maxed = divergence_solve(
                    be, fl, at, st.k_div, d.solve, dt, self.dt_prev, cfg.divergence
                )
                rep.solver_maxed += maxed
        with self.timer("xsph"):
            be.accelerate(st.v, dt, self.g)
            self.wall_pressure(dt, st.v, d.dens)
            be.viscosity(
                st.x,
                st.v,
                fl.mf,
                d.dens,
                d.dens.lam,
                nl,
                fl.h,
                self.scene.viscosity,
                self.nu_standard * dt,
                d.v_out,
                d.drho,
                be.NO_DISPLACEMENT,
                be.NO_PAIRS,
            )
            be.copy(st.v, d.v_out)
        self.implicit_viscosity(dt, st.x, st.v, d.dens)  # viscosity_model implicit (method.md 10)
        with self.timer("densitySolve"):
            rep.density_iterations, maxed = density_solve(be, fl, at, st.k_dens, d.solve, dt, self.dt_prev, cfg.dfsph)
            rep.solver_maxed += maxed
            be.stiffness_pressure(st.pressure, st.k_dens, d.dens.rho)
        self.wall_reaction(dt, k=(st.k_div, st.k_dens) if cfg.divergence.enabled else (st.k_dens,))
        be.axpy(st.x, dt, st.v)
        self.move_walls(dt)
        self.keep_outside_walls()
        self.prepare()
        return self.end(dt, d.dens)

    def density(self):
        return self.data.dens.rho
