"""The CPU backend: numpy arrays, Numba `prange` launchers (`cpu_passes`, `cpu_field`: built from the
pass table, `passes`), serial reductions."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..params import PRECISIONS
from . import cpu_field as F
from . import cpu_passes as P
from .base import Backend


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

    # -- per-particle passes (the table's launchers, built in cpu_passes and cpu_field) --------------
    def launch_pass(self, p, nl, args):
        return getattr(F if p.home == "cpu_field" else P, p.name)(*args)

    def wall_arrays(self, walls):
        return walls.x, walls.m, walls.v

    def advance(self, x, v, dt, g, x_old):
        P.advance(x, v, dt, g, x_old)

    def displacement_velocity(self, x, x_old, dt, v):
        P.displacement_velocity(x, x_old, dt, v)

    def accelerate(self, v, dt, g):
        P.accelerate(v, dt, g)

    def warm_stiffness(self, k_total, scale, rate, n_nbrs, min_nbrs, warm):
        P.warm_stiffness(k_total, scale, self._every_particle if rate is None else rate, n_nbrs, min_nbrs, warm)
