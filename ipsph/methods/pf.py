"""Projective Fluids [WKB16]: the reference method (method.md section 3).

Per step:

    inertial target     s = x + dt v + dt^2 g;  x := s;  neighbours at s (fixed for the step)
    solvePDConstraints  L local/global passes on C_i = max(rho_i/rho0 - 1, 0)
    velocities          v = (x - x^n) / dt;  XSPH

`ProjectiveMethod` holds what PF and IPSPH share; IPSPH wraps the paper's average-density loop
around the same solve (`solves.pd_solve`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..backends import Densities
from .base import Method, StepReport
from .solves import pd_solve


@dataclass
class PFData:
    """PF's scratch: the densities at the projected positions, the inertial target s, x^n, the
    spare position buffer of the local/global ping-pong, the viscosity pass's outputs."""

    dens: Densities
    s: object
    x_old: object
    x_spare: object
    v_out: object
    drho: object

    @classmethod
    def allocate(cls, be, n):
        return cls(
            Densities.allocate(be, n),
            be.zeros(n, (3,)),
            be.zeros(n, (3,)),
            be.zeros(n, (3,)),
            be.zeros(n, (3,)),
            be.zeros(n),
        )


class ProjectiveMethod(Method):
    """Shared by PF and IPSPH: the inertial target, the constraint projection, the velocities."""

    Data = PFData

    def __init__(self, *args):
        super().__init__(*args)
        self.state.zeros("pd_lambda")  # Lam: the step's accumulated multipliers (pressure, warm start)
        self.allocate_scratch(self.Data)

    def prepare(self) -> None:
        """Densities at the current positions, so frame 0 carries them.

        The particle order is left alone (a resumed run must continue exactly as an
        uninterrupted one): the densities are computed on a sorted copy and scattered back.
        """
        be, st, d, fl = self.be, self.state, self.data, self.fluid
        perm = self.search.update(st.x)
        be.densities(be.take(st.x, perm), fl.mf, self.boundary, self.lists, fl.h, fl.rho0, d.dens, be.NO_PAIRS)
        for a in d.dens.arrays():
            if a.shape[0] == perm.shape[0]:  # the field walls' arrays have no rows without field walls
                be.untake(a, perm)

    def inertial_target(self, dt: float):
        """s = x + dt v + dt^2 g becomes the current position, neighbours at s; returns x^n in the new order."""
        self.wall_pressure(dt, self.state.v, self.data.dens)  # dens: the last step's, at these positions
        self.be.advance(self.state.x, self.state.v, dt, self.g, self.data.x_old)
        self.move_walls(dt)  # the projection sees moving walls where they are at t + dt
        (x_old,) = self.neighbour_search(self.data.x_old)
        return x_old

    def project(self, dt: float, min_passes: int, max_passes: int, tol: float, warm_start: float = 0.0):
        """The local/global passes at the current lists (solves.pd_solve); x becomes the result."""
        st, d = self.state, self.data
        warm, scale = None, 0.0
        if warm_start > 0.0 and self.dt_prev is not None:  # Lam ~ p dt^2: rescaled to this step
            warm, scale = st.pd_warm, warm_start * (dt / self.dt_prev) ** 2
        passes, err, st.x, d.x_spare = pd_solve(
            self.be,
            self.fluid,
            x=st.x,
            x_spare=d.x_spare,
            s=d.s,
            lam_sum=st.pd_lambda,
            dens=d.dens,
            walls=self.boundary,
            nl=self.lists,
            dt=dt,
            stiffness=self.cfg.pf.stiffness,
            min_passes=min_passes,
            max_passes=max_passes,
            tol=tol,
            warm=warm,
            warm_scale=scale,
        )
        return passes, err

    def velocities(self, dt: float, x_old, disp=None, fill_pairs: bool = False):
        """v = (x - x^n) / dt from the projected positions, then the viscosity pass (XSPH, and
        SPlisHSPlasH's Standard viscosity if the scene sets one: method.md section 1).

        Leaves D rho/Dt of the unfiltered velocities in data.drho (PF's divergence error, IPSPH's
        divergence warm-start mask) and, if `disp` is given, the step's final PF displacement
        d(Lam) in it (IPSPH's next warm start). With `fill_pairs` the pass also fills the pair
        cache and returns it, for a solve that follows at these positions (IPSPH's)."""
        be, st, d, fl = self.be, self.state, self.data, self.fluid
        self.keep_outside_walls()
        be.displacement_velocity(st.x, x_old, dt, st.v)
        self.wall_rate(st.x, d.dens)
        pairs = be.viscosity(
            st.x,
            st.v,
            fl.mf,
            d.dens,
            st.pd_lambda,
            self.lists,
            fl.h,
            self.scene.viscosity,
            self.nu_standard * dt,
            d.v_out,
            d.drho,
            be.NO_DISPLACEMENT if disp is None else disp,
            self.pairs.buffer(self.lists) if fill_pairs else be.NO_PAIRS,
        )
        be.copy(st.v, d.v_out)
        return pairs

    def density(self):
        return self.data.dens.rho


class PF(ProjectiveMethod):
    name = "pf"
    phases = ("neighbourSearch", "solvePDConstraints", "xsph", "viscositySolve")

    def step(self, dt: float) -> StepReport:
        be, st, d = self.be, self.state, self.data
        rep = self.begin(dt)
        x_old = self.inertial_target(dt)
        with self.timer("solvePDConstraints"):
            rep.pd_passes, _ = self.project(dt, self.cfg.pf.passes, self.cfg.pf.passes, 0.0)
        with self.timer("xsph"):
            self.velocities(dt, x_old)
            rep.divergence_error = dt * be.mean_positive(d.drho) / self.fluid.rho0
        self.implicit_viscosity(dt, st.x, st.v, d.dens)  # viscosity_model implicit (method.md 10)
        be.pf_pressure(st.pressure, st.pd_lambda, self.fluid.rho0, dt)  # p = -rho0 Lam / dt^2 (method.md 3)
        self.wall_reaction(dt, lam=st.pd_lambda, after_move=True)
        return self.end(dt, d.dens)
