"""The CPU backend: numpy arrays, Numba `prange` launchers (`cpu_passes`), serial reductions."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..params import PRECISIONS
from . import cpu_field as F
from . import cpu_passes as P
from .base import Backend, Densities


class CPUBackend(Backend):
    name = "cpu"

    def __init__(self, precision: str = "float64", device: int = 0):
        if precision not in PRECISIONS:
            raise ConfigError(f"simulation.precision = {precision!r}: use one of {', '.join(PRECISIONS)}")
        # the storage type of the real arrays; the bodies compute in float64 either way (their
        # scalars are float64) and sum in float64 (docs/method.md, "Backends and precision")
        self.precision = precision
        self.real = np.dtype(precision)
        self.NO_PAIRS = P.NO_PAIR_CACHE.astype(self.real)
        self.NO_DISPLACEMENT = P.NO_DISPLACEMENT.astype(self.real)
        self._every_particle = P.EVERY_PARTICLE.astype(self.real)

    # -- arrays -------------------------------------------------------------------------------------
    def _dtype(self, dtype):
        """'float64' (every caller's default) means this backend's precision."""
        dt = np.dtype(dtype)
        return self.real if dt == np.float64 else dt

    def zeros(self, n, shape=(), dtype="float64"):
        return np.zeros((n, *shape), dtype=self._dtype(dtype))

    def empty(self, n, shape=(), dtype="float64"):
        return np.empty((n, *shape), dtype=self._dtype(dtype))

    def asarray(self, host, dtype="float64"):
        return np.ascontiguousarray(host, dtype=self._dtype(dtype))

    def to_host(self, a):
        return a

    def pair_buffer(self, n, k):
        return np.empty((n, 3, k), dtype=self.real)

    # -- vector operations (numpy where it is the same arithmetic in the same order) ----------------
    def fill(self, a, value):
        a[:] = value

    def copy(self, dst, src):
        dst[:] = src

    def axpy(self, y, alpha, x):
        y += alpha * x

    def scale(self, a, c):
        a *= c

    def take(self, a, perm):
        return np.take(a, perm, axis=0)  # faster than a[perm] (docs/performance.md)

    def concat(self, a, b):
        return np.concatenate((a, b))

    def head(self, a, n):
        return a[:n]

    def untake(self, a, perm):
        a[perm] = a.copy()

    def mean(self, a):
        return P.mean(a)

    def mean_positive(self, a):
        return P.mean_positive(a)

    def max(self, a):
        return float(a.max())

    def speed_energy(self, v, m):
        return P.speed_energy(v, m)

    def first_unhealthy(self, x, v, lo, hi):
        return P.first_unhealthy(x, v, lo, hi)

    def pf_pressure(self, out, lam, rho0, dt):
        out[:] = -rho0 * lam / (dt * dt)

    def stiffness_pressure(self, out, k, rho, add=False):
        if add:
            out += k * rho * rho
        else:
            out[:] = k * rho * rho

    # -- per-particle passes ------------------------------------------------------------------------
    def densities(self, x, mf, walls, nl, h, rho0, out: Densities, pairs):
        args = (x, mf, walls.x, walls.m, nl.fluid, nl.fluid_count, nl.boundary, nl.boundary_count, h, rho0)
        dens = (out.rho, out.alpha, out.lam, out.err, out.n_nbrs, out.gb, pairs)
        if walls.field is None:
            P.density_factor_lambda(*args, *dens)
        else:  # field walls: their reading first, then the density pass that adds it (its own launcher)
            self.wall_field(x, walls.field, rho0, out)
            F.field_density_factor_lambda(*args, *dens, out.wb, out.gw, self.wall_mirror)
        return pairs

    def wall_field(self, x, field, rho0, out: Densities) -> None:
        F.wall_field(x, field.h, rho0, field.wall, field.arrays(), out.wb, out.gw, out.gvb, out.ws)

    def wall_pressure(self, dens: Densities, g, rho0, dt, v) -> None:
        F.wall_pressure(dens.gw, dens.ws, g, rho0, dt, v)

    def wall_project(self, x, v, field, moved) -> int:
        return int(F.wall_project(x, v, field.h, field.phi_min, field.arrays(), moved))

    def divergence_residual(self, x, v, mf, dens, nl, pairs, h, dt, drho, k):
        P.divergence_residual(
            x, v, mf, dens.gb, dens.gvb, nl.fluid, nl.fluid_count, pairs, h, dens.alpha, dens.n_nbrs, dt, drho, k
        )

    def density_residual(self, x, v, mf, dens, nl, pairs, h, rho0, dt, err, k):
        P.density_residual(
            x, v, mf, dens.gb, dens.gvb, nl.fluid, nl.fluid_count, pairs, h, dens.rho, dens.alpha, rho0, dt, err, k
        )

    def apply_stiffness(self, x, mf, dens, nl, pairs, h, k, dt, v, k_total):
        P.apply_stiffness(x, mf, dens.gb, nl.fluid, nl.fluid_count, pairs, h, k, dt, v, k_total, self.wall_mirror)

    def viscosity(self, x, v, mf, dens, lam, nl, h, zeta, nu_dt, v_out, drho, disp, pairs):
        P.xsph(
            x,
            v,
            mf,
            dens.rho,
            dens.gb,
            dens.gvb,
            lam,
            nl.fluid,
            nl.fluid_count,
            h,
            zeta,
            nu_dt,
            v_out,
            drho,
            disp,
            pairs,
            self.wall_mirror,
        )
        return pairs

    def viscous_setup(self, x, v, mf, dens, walls, nl, h, rho0, nu_dt, wall_factor, full, b, diag, wmat):
        P.viscous_setup(
            x,
            v,
            mf,
            dens.rho,
            walls.x,
            walls.m,
            walls.v,
            nl.fluid,
            nl.fluid_count,
            nl.boundary,
            nl.boundary_count,
            h,
            rho0,
            nu_dt,
            wall_factor,
            full,
            b,
            diag,
            wmat,
        )

    def viscous_apply(self, x, p, mf, dens, nl, h, nu_dt, wmat, out, pdot):
        P.viscous_apply(x, p, mf, dens.rho, nl.fluid, nl.fluid_count, h, nu_dt, wmat, out, pdot)

    def cg_precondition(self, r, diag, rho, mf, z, rz, rr):
        P.cg_precondition(r, diag, rho, mf, z, rz, rr)

    def wall_rate(self, x, walls, nl, h, dens):
        P.wall_rate(x, walls.x, walls.m, walls.v, nl.boundary, nl.boundary_count, h, dens.gvb)

    def pf_global(self, x, s, mf, dens, nl, h, rho0, a, x_out, lam_sum):
        P.pf_global(x, s, mf, dens.gb, nl.fluid, nl.fluid_count, h, rho0, dens.lam, a, x_out, lam_sum, self.wall_mirror)

    def advance(self, x, v, dt, g, x_old):
        P.advance(x, v, dt, g, x_old)

    def displacement_velocity(self, x, x_old, dt, v):
        P.displacement_velocity(x, x_old, dt, v)

    def accelerate(self, v, dt, g):
        P.accelerate(v, dt, g)

    def warm_stiffness(self, k_total, scale, rate, n_nbrs, min_nbrs, warm):
        P.warm_stiffness(k_total, scale, self._every_particle if rate is None else rate, n_nbrs, min_nbrs, warm)
