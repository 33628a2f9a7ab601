"""Projective Fluids [WKB16]: the reference method (method.md section 3).

Per step:

    inertial target     s = x + dt v + dt^2 g;  x := s;  neighbours at s (fixed for the step)
    solvePDConstraints  L local/global passes on C_i = max(rho_i/rho0 - 1, 0)
    velocities          v = (x - x^n) / dt;  XSPH

`pd_solve` is shared with IPSPH, which wraps the paper's average-density loop around it.
"""
from __future__ import annotations

import numpy as np

from .base import Method, StepReport
from .pf_passes import pf_global
from .sph_passes import (NO_DISPLACEMENT, NO_PAIR_CACHE, advance, density_factor_lambda, displacement_velocity,
                         mean, xsph)


def pd_solve(method: Method, dt: float, min_passes: int, max_passes: int, tol: float,
             warm_start: float = 0.0) -> tuple[int, float]:
    """Local/global passes from x = s until the mean density error <= tol [WKB16 sec. 4; paper Alg. 2].

    Each pass: local step (rho, lam at x) -> stop test -> global step (closed form, Jacobi).
    The final local step leaves rho, alpha, n_nbrs, err and gb valid at the projected positions.
    Accumulates the pressure multiplier in state.pd_lambda. Returns (passes, mean error).

    warm_start > 0 (IPSPH only, a [choice] of ours): before the first pass, displace s by
    `warm_start` times the previous step's final PF displacement d(Lam) (state.pd_warm, summed by
    the previous step's XSPH pass at its projected positions), rescaled to the new step
    (Lam ~ p dt^2), as DFSPH warm-starts its stiffness; Lam starts from the same scaled
    multipliers. The stop test is unchanged, so the result meets the same tolerance in fewer passes.
    """
    st = method.state
    xb, mb, nf, cf, nb, cb = method.lists()
    h, rho0 = method.h, method.rho0
    s = st.x.copy()                          # the inertial target
    a = dt * dt * method.cfg.pf_stiffness
    x, x_new = st.x, method.scratch_x
    lam_sum = st.pd_lambda
    if warm_start > 0.0 and method.dt_prev is not None:
        c = warm_start * (dt / method.dt_prev) ** 2
        x += (c / rho0) * st.pd_warm         # pf_global's pure displacement (a -> infinity) by c Lam
        lam_sum *= c
    else:
        lam_sum[:] = 0.0
    passes = 0
    while True:
        density_factor_lambda(x, method.mf, xb, mb, nf, cf, nb, cb, h, rho0, method.rho, method.alpha,
                              method.lam, method.err, method.n_nbrs, method.gb, NO_PAIR_CACHE)
        err = mean(method.err)
        if passes >= max_passes or (passes >= min_passes and err <= tol):
            break
        pf_global(x, s, method.mf, method.gb, nf, cf, h, rho0, method.lam, a, x_new, lam_sum)
        x, x_new = x_new, x
        passes += 1
    st.x = x
    method.scratch_x = x_new
    return passes, err


class ProjectiveMethod(Method):
    """Shared by PF and IPSPH: the inertial target, the constraint projection, the PF pressure."""

    def __init__(self, *args):
        super().__init__(*args)
        self.scratch_x = np.zeros((self.state.n, 3))
        self.state.zeros("pd_lambda")  # Lam: the step's accumulated multipliers (pressure, warm start)

    def prepare(self) -> None:
        """Densities at the current positions, so frame 0 carries them.

        The particle order is left alone (a resumed run must continue exactly as an
        uninterrupted one): the densities are computed on a sorted copy and scattered back.
        """
        st = self.state
        perm = self.search.update(st.x)
        xb, mb, nf, cf, nb, cb = self.lists()
        density_factor_lambda(np.ascontiguousarray(st.x[perm]), self.mf, xb, mb,
                              nf, cf, nb, cb, self.h, self.rho0, self.rho, self.alpha, self.lam, self.err,
                              self.n_nbrs, self.gb, NO_PAIR_CACHE)
        for a in (self.rho, self.alpha, self.lam, self.err, self.n_nbrs, self.gb):
            a[perm] = a.copy()

    def inertial_target(self, dt: float) -> np.ndarray:
        """s = x + dt v + dt^2 g becomes the current position; returns x^n in the new order."""
        st = self.state
        x_old = np.empty_like(st.x)
        advance(st.x, st.v, dt, self.g, x_old)
        (x_old,) = self.neighbour_search(x_old)
        return x_old

    def projected_velocities(self, dt: float, x_old: np.ndarray, disp: np.ndarray = NO_DISPLACEMENT,
                             fill_pair_cache: bool = False) -> None:
        """v = (x - x^n) / dt from the projected positions, then the viscosity pass (XSPH, and
        SPlisHSPlasH's Standard viscosity if the scene sets one: method.md section 1).

        Leaves D rho/Dt of the unfiltered velocities in self.drho (PF's divergence error, IPSPH's
        divergence warm-start mask) and, if `disp` has a row per particle, the step's final PF
        displacement d(Lam) in it (IPSPH's next warm start). With `fill_pair_cache` the pass
        also fills the pair cache for a solve that follows at these positions (IPSPH's).
        """
        st = self.state
        displacement_velocity(st.x, x_old, dt, st.v)
        _, _, nf, cf, _, _ = self.lists()
        xsph(st.x, st.v, self.mf, self.rho, self.gb, st.pd_lambda, nf, cf, self.h, self.scene.viscosity,
             self.scene.standard_viscosity * dt, self.scratch_v, self.drho, disp,
             self.pair_cache_to_fill() if fill_pair_cache else NO_PAIR_CACHE)
        st.v[:] = self.scratch_v

    def pf_pressure(self, dt: float) -> np.ndarray:
        """p_i = -rho0 Lam_i / dt^2 (>= 0): the constraint displacement as SPH pressure (method.md 3)."""
        return -self.rho0 * self.state.pd_lambda / (dt * dt)


class PF(ProjectiveMethod):
    name = "pf"
    phases = ("neighbourSearch", "solvePDConstraints", "xsph")

    def step(self, dt: float) -> StepReport:
        self.report = rep = StepReport(dt=dt)
        st = self.state
        x_old = self.inertial_target(dt)
        with self.timer("solvePDConstraints"):
            passes = self.cfg.pf_passes
            rep.pd_passes, _ = pd_solve(self, dt, passes, passes, 0.0)
        with self.timer("xsph"):
            self.projected_velocities(dt, x_old)
            rep.divergence_error = dt * mean(np.maximum(self.drho, 0.0)) / self.rho0
        st.pressure[:] = self.pf_pressure(dt)
        rep.density_error_mean, rep.density_error_max = self.density_errors()
        self.dt_prev = dt
        return rep
