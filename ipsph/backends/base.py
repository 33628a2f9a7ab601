"""The backend seam: what a method may ask of the machine its particles live on.

A `Backend` owns the particle and scratch arrays (allocation, host transfer), every
per-particle pass (their bodies are written once, in `bodies`) and the few vector operations a
step needs. A method holds a backend and calls only these; it never touches particle arrays with
numpy, so the same method code runs on any backend. Two are registered in
`ipsph.backends.BACKENDS`: `CPUBackend` (`cpu.py`, Numba `prange` over the bodies) and
`CUDABackend` (`cuda.py`, the same bodies as CUDA device functions). Each backend's neighbour
search is `ipsph.neighbours.search_for(backend, ...)`.

Conventions every backend keeps: particles along the first axis; real arrays in the backend's
precision (float64 on the CPU; float64 or float32 on CUDA); passes write index i from the work
item of particle i only (no atomics); reductions in a fixed order, so the same inputs give the
same bits whatever the thread count. Pass arguments mirror the launchers in
`cpu_passes`; `nl` is the current `NeighbourLists`, `walls` the `Boundary`, `dens` a `Densities`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

Array = Any  # a backend array (numpy on the CPU backend)


@dataclass
class Densities:
    """What the density pass leaves at one set of positions (method.md section 1): density rho,
    DFSPH factor alpha, PF multiplier lam, density error err = max(rho/rho0 - 1, 0), neighbour
    count n_nbrs, and the walls' gradient sum gb_i = sum_b m_b grad W_ib that every later pass
    at the same positions takes the walls from; gvb_i = sum_b m_b v_b . grad W_ib, the moving
    walls' part of D rho_i/Dt (`wall_rate`; stays 0 with static walls). With field walls, wb and gw
    are their density and its gradient (`wall_field`, added into rho and gb by the density pass) and
    ws the mean depth of the wall below each particle (`wall_pressure`); without, they have no rows."""

    rho: Array
    alpha: Array
    lam: Array
    err: Array
    n_nbrs: Array
    gb: Array
    gvb: Array
    wb: Array
    gw: Array
    ws: Array

    @classmethod
    def allocate(cls, be: "Backend", n: int, field: bool = False) -> "Densities":
        m = n if field else 0
        return cls(
            be.zeros(n),
            be.zeros(n),
            be.zeros(n),
            be.zeros(n),
            be.zeros(n, dtype="int32"),
            be.zeros(n, (3,)),
            be.zeros(n),
            be.zeros(m),
            be.zeros(m, (3,)),
            be.zeros(m),
        )

    def arrays(self) -> tuple:
        return tuple(getattr(self, f.name) for f in fields(self))


class Backend:
    """The interface (every method raises here; `CPUBackend` implements it)."""

    # The walls' share in every pressure term, as a multiple of the particle's own (bodies.stiffness_at):
    # 1 carries the particle's pressure once (Akinci's walls), 2 mirrors it onto the wall. The wall
    # model sets it (`Simulation`): it belongs to the walls, the passes only apply it.
    wall_mirror: float = 1.0

    name = ""
    NO_PAIRS: Array = None  # the empty pair cache: a pass given it neither fills nor reads it
    NO_DISPLACEMENT: Array = None  # viscosity(..., disp=NO_DISPLACEMENT): no PF displacement

    # -- arrays -------------------------------------------------------------------------------------
    def zeros(self, n: int, shape=(), dtype="float64") -> Array:
        raise NotImplementedError

    def empty(self, n: int, shape=(), dtype="float64") -> Array:
        raise NotImplementedError

    def asarray(self, host, dtype="float64") -> Array:
        raise NotImplementedError  # host -> backend

    def to_host(self, a: Array):
        raise NotImplementedError  # backend -> numpy

    def pair_buffer(self, n: int, k: int) -> Array:
        raise NotImplementedError  # (n, 3, k)

    # -- vector operations --------------------------------------------------------------------------
    def fill(self, a, value: float) -> None:
        raise NotImplementedError

    def copy(self, dst, src) -> None:
        raise NotImplementedError

    def axpy(self, y, alpha: float, x) -> None:
        raise NotImplementedError  # y += alpha x

    def scale(self, a, c: float) -> None:
        raise NotImplementedError  # a *= c

    def take(self, a, perm) -> Array:
        raise NotImplementedError  # new[i] = a[perm[i]]; len(perm) <= len(a)

    def concat(self, a, b) -> Array:
        raise NotImplementedError  # a new array: a's rows, then b's

    def head(self, a, n: int) -> Array:
        raise NotImplementedError  # a view of the first n rows (no copy)

    def untake(self, a, perm) -> None:
        raise NotImplementedError  # a[perm[i]] = old a[i], in place

    def mean(self, a) -> float:
        raise NotImplementedError

    def mean_positive(self, a) -> float:
        raise NotImplementedError  # mean of max(a, 0)

    def max(self, a) -> float:
        raise NotImplementedError

    def speed_energy(self, v, m) -> tuple[float, float]:
        raise NotImplementedError

    def first_unhealthy(self, x, v, lo, hi) -> int:
        raise NotImplementedError

    def pf_pressure(self, out, lam, rho0: float, dt: float) -> None:
        raise NotImplementedError

    def stiffness_pressure(self, out, k, rho, add: bool = False) -> None:
        raise NotImplementedError

    # -- per-particle passes (bodies.*_at) ----------------------------------------------------------
    def densities(self, x, mf, walls, nl, h, rho0, out: Densities, pairs) -> Array:
        raise NotImplementedError

    def divergence_residual(self, x, v, mf, dens, nl, pairs, h, dt, drho, k) -> None:
        raise NotImplementedError

    def density_residual(self, x, v, mf, dens, nl, pairs, h, rho0, dt, err, k) -> None:
        raise NotImplementedError

    def apply_stiffness(self, x, mf, dens, nl, pairs, h, k, dt, v, k_total) -> None:
        raise NotImplementedError

    def viscosity(self, x, v, mf, dens, lam, nl, h, zeta, nu_dt, v_out, drho, disp, pairs) -> Array:
        raise NotImplementedError

    def pf_global(self, x, s, mf, dens, nl, h, rho0, a, x_out, lam_sum) -> None:
        raise NotImplementedError

    def viscous_setup(self, x, v, mf, dens, walls, nl, h, rho0, nu_dt, wall_factor, full, b, diag, wmat) -> None:
        raise NotImplementedError  # the implicit viscosity's b, Jacobi diagonal, wall blocks (viscous_bodies.viscous_setup_at)

    def viscous_apply(self, x, p, mf, dens, nl, h, nu_dt, wmat, out, pdot) -> None:
        raise NotImplementedError  # out = A p, pdot_i = V_i p_i . out_i (bodies.viscous_apply_at)

    def cg_precondition(self, r, diag, rho, mf, z, rz, rr) -> None:
        raise NotImplementedError  # z = r / diag, rz_i = V_i r_i . z_i, rr_i = V_i |r_i|^2 (element-wise)

    def wall_field(self, x, field, rho0, out: Densities) -> None:
        """Field walls: out.wb, out.gw and out.gvb at x (`field_bodies.wall_field_at`)."""
        raise NotImplementedError

    def wall_pressure(self, dens: Densities, g, rho0: float, dt: float, v) -> None:
        """Field walls: the hydrostatic part of the mirrored wall pressure on v (`field_bodies.wall_pressure_at`)."""
        raise NotImplementedError

    def wall_project(self, x, v, field, moved) -> int:
        """Field walls: keep x at least field.phi_min outside every surface (`field_bodies.wall_project_at`)."""
        raise NotImplementedError

    def wall_rate(self, x, walls, nl, h, dens) -> None:
        raise NotImplementedError  # dens.gvb (walls.v: moving walls)

    def advance(self, x, v, dt, g, x_old) -> None:
        raise NotImplementedError

    def displacement_velocity(self, x, x_old, dt, v) -> None:
        raise NotImplementedError

    def accelerate(self, v, dt, g) -> None:
        raise NotImplementedError

    def warm_stiffness(self, k_total, scale, rate, n_nbrs, min_nbrs, warm) -> None:
        raise NotImplementedError

    # -- timing -------------------------------------------------------------------------------------
    def synchronize(self) -> None:
        """Wait for the work launched so far (a timer reads the clock after it): asynchronous
        backends (CUDA) override it; on the CPU every pass has returned when it ends."""
