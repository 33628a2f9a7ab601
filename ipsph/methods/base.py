"""What the three methods share: arrays, neighbour search with reordering, timers, reports."""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..boundary import Boundary
from ..model import Scene
from ..neighbours import NeighbourSearch
from ..particles import ParticleState
from .sph_passes import NO_PAIR_CACHE, mean

PAIR_CACHE_BYTES = 24  # per neighbour-list slot: mf grad W_ij, three float64


@dataclass
class StepReport:
    """The figures of one step (method.md section 5). Errors are fractions, not percent."""
    dt: float = 0.0
    density_error_mean: float = 0.0   # mean_i max(rho_i/rho0 - 1, 0) at the end-of-step positions
    density_error_max: float = 0.0    # max_i max(rho_i/rho0 - 1, 0)
    divergence_error: float = 0.0     # dt * mean_i max(D rho_i/Dt, 0) / rho0 after the step's solve
    pd_passes: int = 0
    divergence_iterations: int = 0
    density_iterations: int = 0
    solver_maxed: int = 0             # solves that stopped at their iteration cap, unconverged
    timings: dict[str, float] = field(default_factory=dict)  # seconds per phase


class Method:
    """Base class: owns the scratch arrays and the per-step timers; subclasses implement step()."""

    name = ""
    phases: tuple[str, ...] = ()

    def __init__(self, scene: Scene, state: ParticleState, boundary: Boundary, search: NeighbourSearch):
        self.scene = scene
        self.state = state
        self.boundary = boundary
        self.search = search
        r = scene.particle_radius
        self.h = 4.0 * r
        self.rho0 = float(scene.density0)
        self.g = np.asarray(scene.gravity, dtype=np.float64)
        self.cfg = scene.solver
        n = state.n
        # one fluid mass (one rest density and radius per scene): the passes take it as a scalar
        self.mf = float(state.m[0]) if n else 0.0
        if n and not np.all(state.m == self.mf):
            raise ValueError("all fluid particles must have the same mass")
        # per-step scratch (valid only inside a step, in the current particle order)
        self.rho = np.zeros(n)
        self.alpha = np.zeros(n)
        self.lam = np.zeros(n)
        self.err = np.zeros(n)
        self.n_nbrs = np.zeros(n, dtype=np.int32)
        self.k = np.zeros(n)
        self.drho = np.zeros(n)
        self.scratch_v = np.zeros((n, 3))
        self.gb = np.zeros((n, 3))                  # sum_b m_b grad W_ib, for the pressure solves
        # the pair cache mf grad W_ij (sph_passes.NO_PAIR_CACHE when off or not filled at the
        # current positions): `pair_cache_to_fill()` hands it to the filling pass, the pressure
        # solves read `pair_grad`, and every neighbour search invalidates it
        self.pair_grad = NO_PAIR_CACHE
        self._pair_store = NO_PAIR_CACHE
        state.zeros("pressure")                     # output field, follows reordering
        self.dt_prev: float | None = None
        self.report = StepReport()

    # -- helpers ------------------------------------------------------------------------------
    @contextmanager
    def timer(self, phase: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.report.timings[phase] = self.report.timings.get(phase, 0.0) + time.perf_counter() - t0

    def neighbour_search(self, *follow: np.ndarray) -> tuple[np.ndarray, ...]:
        """Sort the fluid by cell at the current positions and rebuild the lists.

        The state is permuted in place; extra arrays passed in `follow` are returned permuted.
        """
        self.pair_grad = NO_PAIR_CACHE
        with self.timer("neighbourSearch"):
            perm = self.search.update(self.state.x)
            self.state.permute(perm)
            return tuple(np.take(a, perm, axis=0) for a in follow)

    def lists(self):
        """(x_b, m_b, nf, cf, nb, cb): everything a pass needs to see neighbours and walls."""
        nl = self.search.lists
        return self.boundary.x, self.boundary.m, nl.fluid, nl.fluid_count, nl.boundary, nl.boundary_count

    def pair_cache_to_fill(self) -> np.ndarray:
        """The pair cache for this step's lists, to hand to the pass that fills it, or
        NO_PAIR_CACHE when it would exceed `solver.pair_cache_mb`. Marks it valid (`pair_grad`):
        call it only for a pass at the positions the following solves use."""
        n, k = self.search.lists.fluid.shape
        if n == 0 or PAIR_CACHE_BYTES * n * k > self.cfg.pair_cache_mb * 2.0**20:
            self._pair_store = self.pair_grad = NO_PAIR_CACHE
            return NO_PAIR_CACHE
        if self._pair_store.shape != (n, 3, k):   # first use, or the list stride grew
            self._pair_store = np.empty((n, 3, k))
        self.pair_grad = self._pair_store
        return self.pair_grad

    @property
    def pair_cache_nbytes(self) -> int:
        """Memory held by the pair cache (0 when it is off or over its budget)."""
        return self._pair_store.nbytes

    def density_errors(self) -> tuple[float, float]:
        """(mean, max) compression of the last `density_factor_lambda` evaluation: both over
        max(rho_i / rho0 - 1, 0), so neither goes negative when no particle is compressed
        (a free-falling or spreading fluid at the start)."""
        return mean(self.err), max(float(self.rho.max()) / self.rho0 - 1.0, 0.0) if len(self.rho) else 0.0

    # -- interface ----------------------------------------------------------------------------
    def prepare(self) -> None:
        """Called once before the first step (and after a checkpoint restore)."""

    def step(self, dt: float) -> StepReport:
        raise NotImplementedError

    def density(self) -> np.ndarray:
        """Density at the current positions (valid after prepare() and after every step)."""
        return self.rho
