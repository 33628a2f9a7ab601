"""What the three methods share: the backend they run on, the fluid's constants, the neighbour
search with reordering, the pair-cache budget, timers and the step report.

A method owns no numpy: its arrays come from `self.be` (the backend), its scratch lives in a
small per-method container (`DFSPHData`, `PFData`, `IPSPHData`), and its `step()` is the
algorithm box, one backend pass or shared solve (`solves.py`) per line.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field, fields, is_dataclass, replace
from types import SimpleNamespace

from ..backends import Backend, Densities
from ..boundary import Boundary
from ..config import Scene
from .state import ParticleState
from .viscosity import WALL_FACTOR, ViscosityScratch, viscous_solve

PAIR_CACHE_BYTES = 24  # per neighbour-list slot: mf grad W_ij, three float64


@dataclass
class StepReport:
    """The figures of one step (method.md section 5). Errors are fractions, not percent."""

    dt: float = 0.0
    density_error_mean: float = 0.0  # mean_i max(rho_i/rho0 - 1, 0) at the end-of-step positions
    density_error_max: float = 0.0  # max_i max(rho_i/rho0 - 1, 0)
    divergence_error: float = 0.0  # dt * mean_i max(D rho_i/Dt, 0) / rho0 after the step's solve
    pd_passes: int = 0
    divergence_iterations: int = 0
    density_iterations: int = 0
    viscosity_iterations: int = 0  # implicit viscosity: conjugate-gradient iterations
    solver_maxed: int = 0  # solves that stopped at their iteration cap, unconverged
    wall_projections: int = 0  # field walls: particles moved back to phi_min outside a surface
    timings: dict[str, float] = field(default_factory=dict)  # seconds per phase


@dataclass(frozen=True)
class Fluid:
    """The scalars every pass takes: fluid mass mf (one per scene), support H, rest density rho0."""

    mf: float
    h: float
    rho0: float


class PairCache:
    """The budgeted store of the pair cache mf grad W_ij, (n, 3, K) in the fluid lists' layout.

    `buffer(nl)` hands the filling pass a buffer for the current lists (or `be.NO_PAIRS` when it
    would exceed `solver.pair_cache_mb`); the pass returns it filled, and the method hands that
    value to the solves at the same positions. Nothing here says whether it is valid: the value
    returned by the filling pass is."""

    def __init__(self, be: Backend, budget_mb: float):
        self.be = be
        self.budget = budget_mb * 2.0**20
        self._store = be.NO_PAIRS

    def buffer(self, nl):
        n, k = nl.fluid.shape
        if n == 0 or PAIR_CACHE_BYTES * n * k > self.budget:
            self._store = self.be.NO_PAIRS
        elif self._store.shape != (n, 3, k):  # first use, or the list stride grew
            self._store = self.be.pair_buffer(n, k)
        return self._store

    @property
    def nbytes(self) -> int:
        return self._store.nbytes


def _head(obj, be: Backend, n: int, capacity: int):
    """The scratch container with every array of `capacity` rows replaced by a view of its first n."""
    if is_dataclass(obj):
        return replace(obj, **{f.name: _head(getattr(obj, f.name), be, n, capacity) for f in fields(obj)})
    if hasattr(obj, "shape") and len(obj.shape) and obj.shape[0] == capacity and obj is not be.NO_PAIRS:
        return be.head(obj, n)
    return obj


def _densities(obj):
    """The Densities in a (nested) scratch dataclass."""
    if isinstance(obj, Densities):
        yield obj
    elif is_dataclass(obj):
        for f in fields(obj):
            yield from _densities(getattr(obj, f.name))


def _arrays(obj):
    """The arrays in a (nested) scratch dataclass."""
    if is_dataclass(obj):
        for f in fields(obj):
            yield from _arrays(getattr(obj, f.name))
    elif hasattr(obj, "nbytes"):
        yield obj


class Method:
    """Base class; subclasses set `name`, `phases` and implement `step()` (and `prepare()`)."""

    name = ""
    phases: tuple[str, ...] = ()
    # field walls: the method's stiffness updates apply the walls' support along their faces
    # (Densities.wm gets rows, method.md section 11); without, the field pass does not compute it
    wall_support = False

    def __init__(self, scene: Scene, state: ParticleState, boundary: Boundary, search, be: Backend, mf: float):
        self.scene = scene
        self.state = state
        self.boundary = boundary
        self.search = search
        self.be = be
        self.cfg = scene.solver
        self.fluid = Fluid(float(mf), scene.support, float(scene.density0))
        self.g = be.asarray(scene.gravity)
        self.pairs = PairCache(be, self.cfg.pair_cache_mb)
        state.zeros("pressure")  # output field, follows reordering
        self.dt_prev: float | None = None
        self.report = StepReport()
        self.walls = None  # a rigid.WallDriver when walls move (Simulation sets it)
        # nu of the explicit Standard model in the viscosity pass (0 with the other models)
        self.nu_standard = scene.kinematic_viscosity_m2s if scene.viscosity_model == "standard" else 0.0

    # -- scratch at capacity, used at the active count ---------------------------------------
    def allocate_scratch(self, data_cls) -> None:
        """`self.data`: the method's scratch, allocated once for the state's capacity and used
        through views of its first n rows (the same arrays when n = capacity: no emitters)."""
        self._scratch = data_cls.allocate(self.be, self.state.capacity)
        if self.boundary.field is not None:  # field walls: the densities' Densities.FIELD get their rows
            for dens in _densities(self._scratch):
                dens.with_field(self.be, self.state.capacity, support=self.wall_support)
        implicit = self.scene.viscosity_model == "implicit" and self.scene.kinematic_viscosity_m2s > 0.0
        self._visc_scratch = ViscosityScratch.allocate(self.be, self.state.capacity) if implicit else None
        self.resize(self.state.n)

    def resize(self, n: int) -> None:
        """The particle count changed (emission, removal): re-view the scratch at n rows. The
        caller then runs `prepare()`, which recomputes what the method derives from positions."""
        cap = self.state.capacity
        self.data = self._scratch if n == cap else _head(self._scratch, self.be, n, cap)
        vs = self._visc_scratch
        self.visc = vs if vs is None or n == cap else _head(vs, self.be, n, cap)

    # -- bookkeeping --------------------------------------------------------------------------
    @contextmanager
    def timer(self, phase: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.be.synchronize()  # a GPU's kernels are asynchronous: time them, not their launch
            self.report.timings[phase] = self.report.timings.get(phase, 0.0) + time.perf_counter() - t0

    def begin(self, dt: float) -> StepReport:
        self.report = StepReport(dt=dt)
        return self.report

    def end(self, dt: float, dens) -> StepReport:
        """The end-of-step density errors (of `dens`, at the final positions); dt becomes dt_prev."""
        rep = self.report
        rep.density_error_mean, rep.density_error_max = self.density_errors(dens)
        self.dt_prev = dt
        return rep

    def density_errors(self, dens) -> tuple[float, float]:
        """(mean, max) compression of a density pass's result: both over max(rho_i / rho0 - 1, 0), so
        neither goes negative when no particle is compressed (a free-falling or spreading fluid)."""
        be, n = self.be, self.state.n
        return be.mean(dens.err), max(be.max(dens.rho) / self.fluid.rho0 - 1.0, 0.0) if n else 0.0

    # -- the implicit viscosity (methods.viscosity; a no-op with the other models) --------------
    def implicit_viscosity(self, dt: float, x, v, dens) -> None:
        """v <- (I - nu dt L)^-1 v at the positions x (method.md section 10), walls as
        simulation.viscosity_walls says; `dens` the densities at x."""
        if self.visc is None:
            return
        with self.timer("viscositySolve"):
            sc = self.scene
            it, _, capped = viscous_solve(
                self.be,
                self.fluid,
                x,
                v,
                dens,
                self.boundary,
                self.lists,
                dt,
                sc.kinematic_viscosity_m2s,
                WALL_FACTOR[sc.viscosity_walls],
                self.cfg.viscosity,
                self.visc,
                sc.particle_radius,
            )
            self.report.viscosity_iterations = it
            self.report.solver_maxed += capped

    # -- moving walls (ipsph.boundary.rigid; all three no-ops with static walls) -------------------------
    def move_walls(self, dt: float) -> None:
        """Moving walls to where they are at the end of this step (before the neighbour search that sees them)."""
        if self.walls is not None:
            self.walls.move(dt)

    def wall_pressure(self, dt: float, v, dens) -> None:
        """Field walls: the hydrostatic increment of the mirrored wall pressure, once per step on v
        (the walls' pressure is the particle's plus rho0 |g.n| times the wall's mean depth below it)."""
        if self.boundary.field is not None:
            self.be.wall_pressure(dens, self.g, self.fluid.rho0, dt, v)

    def keep_outside_walls(self) -> None:
        """Field walls: every particle at least phi_min outside every surface, its velocity into the
        wall removed (brief section 8); the count goes to the step report. No-op with wall particles."""
        field = self.boundary.field
        if field is None:
            return
        st = self.state
        if getattr(self, "_moved", None) is None or self._moved.shape[0] != st.n:
            self._moved = self.be.zeros(st.n, dtype="int32")
        self.report.wall_projections += self.be.wall_project(st.x, st.v, field, self._moved)

    def wall_rate(self, x, dens) -> None:
        """The moving walls' part of D rho/Dt at these positions (dens.gvb; stays 0 for static walls)."""
        if self.boundary.moving:
            self.be.wall_rate(x, self.boundary, self.lists, self.fluid.h, dens)

    def wall_reaction(self, dt: float, lam=None, k=(), after_move: bool = False) -> None:
        """The fluid's force and torque on the moving walls from what this step's pressure parts
        applied: the PF multipliers `lam` and the DFSPH-type stiffness totals `k` (rigid.WallDriver).
        `after_move`: the walls moved earlier in this step (PF, IPSPH), with the last reaction as the
        prediction of this one; the bodies' velocities then take the difference."""
        if self.walls is not None:
            be = self.be
            nl = self.lists  # the wall lists on the host (a device backend's are device arrays)
            walls_nl = SimpleNamespace(boundary=be.to_host(nl.boundary), boundary_count=be.to_host(nl.boundary_count))
            self.walls.reaction(
                be.to_host(self.state.x),
                walls_nl,
                dt,
                None if lam is None else be.to_host(lam),
                tuple(be.to_host(a) for a in k),
                after_move,
            )

    @property
    def lists(self):
        """The current neighbour lists (NeighbourLists)."""
        return self.search.lists

    def neighbour_search(self, *follow):
        """Sort the fluid by cell at the current positions and rebuild the lists.

        The state is permuted in place; extra arrays passed in `follow` are returned permuted.
        """
        with self.timer("neighbourSearch"):
            perm = self.search.update(self.state.x)
            self.state.permute(perm)
            return tuple(self.be.take(a, perm) for a in follow)

    @property
    def nbytes(self) -> int:
        """Memory of the method's own arrays: its scratch container and the pair cache."""
        own = (*_arrays(getattr(self, "_scratch", self.data)), *_arrays(getattr(self, "_visc_scratch", None)))
        unique = {id(a): a for a in (*own, self.pairs._store)}
        return sum(int(a.nbytes) for a in unique.values())

    @property
    def pair_cache_nbytes(self) -> int:
        """Memory held by the pair cache (0 when it is off or over its budget)."""
        return self.pairs.nbytes

    def state_dict(self) -> dict:
        """The method's scalars across steps (its per-particle memory lives in the ParticleState)."""
        return {"dt_prev": self.dt_prev}

    def load_state_dict(self, d: dict) -> None:
        self.dt_prev = None if d["dt_prev"] is None else float(d["dt_prev"])

    # -- interface ----------------------------------------------------------------------------
    def prepare(self) -> None:
        """Called once before the first step (and after a checkpoint restore)."""

    def seed(self, p, dt: float) -> None:
        """Start the warm starts from the pressure field `p` of fluid at rest (the hydrostatic seed,
        method.md section 1), as if a last step of `dt` had ended with it; a method without warm
        starts ignores it."""

    def step(self, dt: float) -> StepReport:
        raise NotImplementedError

    def density(self):
        """Density at the current positions (valid after prepare() and after every step)."""
        raise NotImplementedError
