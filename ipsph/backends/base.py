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
same bits whatever the thread count. The per-particle passes are the rows of `passes.PASSES`: the
methods below bind a row's arguments by name (`run_pass`) and a backend only launches it
(`launch_pass`); `nl` is the current `NeighbourLists`, `walls` the `Boundary`, `dens` a `Densities`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from .passes import PASSES, Pass

Array = Any  # a backend array (numpy on the CPU backend)

LISTS = {"nf": "fluid", "cf": "fluid_count", "nb": "boundary", "cb": "boundary_count"}  # NeighbourLists
WALLS = ("xb", "mb", "vb")  # Backend.wall_arrays


@dataclass
class Densities:
    """What the density pass leaves at one set of positions (method.md section 1): density rho,
    DFSPH factor alpha, PF multiplier lam, density error err = max(rho/rho0 - 1, 0), neighbour
    count n_nbrs, and the walls' gradient sum gb_i = sum_b m_b grad W_ib that every later pass
    at the same positions takes the walls from; gvb_i = sum_b m_b v_b . grad W_ib, the moving
    walls' part of D rho_i/Dt (`wall_rate`; stays 0 with static walls). The fields of `FIELD` are the
    field walls' (`wall_field`) and have no rows without them: wb and gw their density and its gradient
    (added into rho and gb by the density pass), ws the mean depth of the wall below each particle
    (`wall_pressure`), wm their support along the faces (xx, yy, zz, xy, xz, yz; method.md section 11)."""

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
    wm: Array

    # the field walls' fields and their shape per particle: rows only with field walls
    FIELD = {"wb": (), "gw": (3,), "ws": (), "wm": (6,)}

    @classmethod
    def allocate(cls, be: "Backend", n: int, field: bool = False) -> "Densities":
        m = n if field else 0
        walls = {name: be.zeros(m, shape) for name, shape in cls.FIELD.items()}
        return cls(
            be.zeros(n),
            be.zeros(n),
            be.zeros(n),
            be.zeros(n),
            be.zeros(n, dtype="int32"),
            be.zeros(n, (3,)),
            be.zeros(n),
            **walls,
        )

    def with_field(self, be: "Backend", n: int, support: bool = True) -> None:
        """Give the field walls' fields n rows (a scratch allocated without them); wm only with
        `support` (the method applies it: `Method.wall_support`)."""
        for name, shape in self.FIELD.items():
            setattr(self, name, be.zeros(n if support or name != "wm" else 0, shape))

    def arrays(self) -> tuple:
        return tuple(getattr(self, f.name) for f in fields(self))


class Backend:
    """The interface: the per-particle passes are written here, once, over `launch_pass` and
    `wall_arrays`; everything else raises here (`CPUBackend` implements it)."""

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

    # -- per-particle passes (the table `passes.PASSES`, each launched by `run_pass`) ---------------
    def launch_pass(self, p: Pass, nl, args: list):
        """Run pass `p`'s launcher on `args` (in `p.inputs` order); `nl` gives the lists' strides."""
        raise NotImplementedError

    def wall_arrays(self, walls) -> tuple:
        """(xb, mb, vb): the walls' positions, masses and velocities as this backend's arrays."""
        raise NotImplementedError

    def run_pass(self, name: str, nl=None, dens: Densities | None = None, walls=None, **given):
        """Launch the table's pass `name`, each argument by its name: from `given`, else the lists
        (nf, cf, nb, cb of `nl`), the walls (xb, mb, vb of `walls`), the walls' pressure share
        (mirror: `wall_mirror`) or a field of `dens`. Returns what the launcher returns."""
        p = PASSES[name]
        args = [given[a] if a in given else self._argument(name, a, nl, dens, walls) for a in p.inputs]
        return self.launch_pass(p, nl, args)

    def _argument(self, name: str, a: str, nl, dens, walls):
        """run_pass's argument `a` of pass `name` when the caller did not give it."""
        if a in LISTS:
            return getattr(nl, LISTS[a])
        if a in WALLS:
            return self.wall_arrays(walls)[WALLS.index(a)]
        if a == "mirror":
            return self.wall_mirror
        if dens is not None and hasattr(dens, a):
            return getattr(dens, a)
        raise TypeError(f"pass {name}: no value for its argument {a!r}")

    def densities(self, x, mf, walls, nl, h, rho0, out: Densities, pairs) -> Array:
        """rho, alpha, lam, err, n_nbrs, gb of `out` at x; fills the pair cache `pairs` if it has a row
        per particle. Field walls: their reading (`wall_field`) first, then the density pass that adds it."""
        named = {"x": x, "mf": mf, "h": h, "rho0": rho0, "pair_grad": pairs}
        if walls.field is None:
            self.run_pass("density_factor_lambda", nl, out, walls, **named)
        else:
            self.wall_field(x, walls.field, rho0, out)
            self.run_pass("field_density_factor_lambda", nl, out, walls, **named)
        return pairs

    def divergence_residual(self, x, v, mf, dens, nl, pairs, h, dt, drho, k) -> None:
        self.run_pass("divergence_residual", nl, dens, x=x, v=v, mf=mf, pair_grad=pairs, h=h, dt=dt, drho=drho, k=k)

    def density_residual(self, x, v, mf, dens, nl, pairs, h, rho0, dt, err, k) -> None:
        named = {"x": x, "v": v, "mf": mf, "pair_grad": pairs, "h": h, "rho0": rho0, "dt": dt, "rho_err": err, "k": k}
        self.run_pass("density_residual", nl, dens, **named)

    def apply_stiffness(self, x, mf, dens, nl, pairs, h, k, dt, v, k_total) -> None:
        self.run_pass("apply_stiffness", nl, dens, x=x, mf=mf, pair_grad=pairs, h=h, k=k, dt=dt, v=v, k_total=k_total)

    def viscosity(self, x, v, mf, dens, lam, nl, h, zeta, nu_dt, v_out, drho, disp, pairs) -> Array:
        named = {"x": x, "v": v, "mf": mf, "lam": lam, "h": h, "zeta": zeta, "nu_dt": nu_dt}
        self.run_pass("xsph", nl, dens, **named, v_out=v_out, drho=drho, disp=disp, pair_grad=pairs)
        return pairs

    def pf_global(self, x, s, mf, dens, nl, h, rho0, a, x_out, lam_sum) -> None:
        self.run_pass("pf_global", nl, dens, x=x, s=s, mf=mf, h=h, rho0=rho0, a=a, x_out=x_out, lam_sum=lam_sum)

    def viscous_setup(self, x, v, mf, dens, walls, nl, h, rho0, nu_dt, wall_factor, full, b, diag, wmat) -> None:
        """The implicit viscosity's b, Jacobi diagonal, wall blocks (viscous_bodies.viscous_setup_at)."""
        named = {"x": x, "v": v, "mf": mf, "h": h, "rho0": rho0, "nu_dt": nu_dt, "wall_factor": wall_factor}
        self.run_pass("viscous_setup", nl, dens, walls, **named, full=full, b=b, diag=diag, wmat=wmat)

    def viscous_apply(self, x, p, mf, dens, nl, h, nu_dt, wmat, out, pdot) -> None:
        """out = A p, pdot_i = V_i p_i . out_i (viscous_bodies.viscous_apply_at)."""
        self.run_pass("viscous_apply", nl, dens, x=x, p=p, mf=mf, h=h, nu_dt=nu_dt, wmat=wmat, out=out, pdot=pdot)

    def cg_precondition(self, r, diag, rho, mf, z, rz, rr) -> None:
        """z = r / diag, rz_i = V_i r_i . z_i, rr_i = V_i |r_i|^2 (element-wise)."""
        self.run_pass("cg_precondition", r=r, diag=diag, rho=rho, mf=mf, z=z, rz=rz, rr=rr)

    def wall_field(self, x, field, rho0, out: Densities) -> None:
        """Field walls: out.wb, out.gw, out.gvb, out.ws and out.wm at x (`field_bodies.wall_field_at`)."""
        self.run_pass("wall_field", dens=out, x=x, h=field.h, rho0=rho0, wall=field.wall, objects=field.arrays())

    def wall_pressure(self, dens: Densities, g, rho0: float, dt: float, v) -> None:
        """Field walls: the hydrostatic part of the mirrored wall pressure on v (`field_bodies.wall_pressure_at`)."""
        self.run_pass("wall_pressure", dens=dens, g=g, rho0=rho0, dt=dt, v=v)

    def wall_project(self, x, v, field, moved) -> int:
        """Field walls: keep x at least field.phi_min outside every surface (`field_bodies.wall_project_at`);
        returns how many particles moved."""
        named = {"x": x, "v": v, "h": field.h, "phi_min": field.phi_min, "objects": field.arrays(), "moved": moved}
        return int(self.run_pass("wall_project", **named))

    def wall_rate(self, x, walls, nl, h, dens) -> None:
        """dens.gvb: the moving walls' part of D rho/Dt (walls.v)."""
        self.run_pass("wall_rate", nl, dens, walls, x=x, h=h)

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
