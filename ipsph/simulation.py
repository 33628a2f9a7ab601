"""The Python API and the shared time loop: scene -> particles -> method -> steps and frames.

    sim = Simulation.from_scene("scene.toml")         # or a dict, or a Scene
    sim.run(on_frame=lambda sim, k: ...)              # frames land exactly on k / fps
    sim.step()                                        # one CFL step
    sim.positions, sim.velocities, sim.densities, sim.pressures, sim.ids

Time stepping (method.md section 1): one dt per step, from the CFL condition evaluated at the
end of the previous step, dt = clamp(cfl * 0.4 * d / max|v|, dt_min, dt_max) (with Standard
viscosity also at most H^2 / (60 nu)); steps whose CFL value fell below dt_min are counted, never
hidden. When the next step would cross a frame time, the remaining time is spread over the last
two steps (no sliver steps).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .backends import Backend, get_backend
from .boundary import Boundary
from .errors import ConfigError, NumericalFailure
from .methods import METHODS
from .methods.base import StepReport
from .model import Role, Scene
from .params import spacing, support
from .particles import ParticleState


@dataclass
class StepStats(StepReport):
    """A method's StepReport plus what the time loop adds."""

    step: int = 0
    time: float = 0.0
    max_speed: float = 0.0
    kinetic_energy: float = 0.0
    dt_clamped: bool = False
    emitted: int = 0  # particles emitted at the end of the step (ipsph.emitters)
    removed: int = 0  # particles removed by sinks and the domain box


# Explicit Standard viscosity is stable while nu dt lambda_max <= 2, lambda_max the largest
# eigenvalue of its operator: 59.6 / H^2 on the lattice (power iteration, method.md section 1).
# The step keeps half of that margin: dt <= H^2 / (60 nu).
VISCOUS_STEP = 60.0


# The pre-pass before t = 0 (method.md section 1, "A start at rest"): the method's own steps of
# dt_max with the velocities damped by SETTLE_DAMPING after each, until SETTLE_HOLD steps in a row
# end with every particle slower than SETTLE_SPEED (a tenth of the tank's 0.1 m/s acceptance), at
# most SETTLE_MAX_STEPS steps. A hold of one step: waiting for 100 quiet steps cost the tank 2-4x
# the steps and did not keep late rearrangements out of the run (method.md).
SETTLE_DAMPING = 0.9
SETTLE_SPEED = 0.01
SETTLE_HOLD = 1
SETTLE_MAX_STEPS = 4000
# simulation.settle = auto settles (with IPSPH and DFSPH; PF never comes to rest) fluid at rest
# that covers its container's floor: fluid above every d x d cell of the floor farther than
# SETTLE_REACH d from the walls (a box fluid filling a tank has its first layer 1.1 d from the wall
# particles).
SETTLE_REACH = 1.5


def wants_settle(scene: Scene, fluid_x: np.ndarray, fluid_v: np.ndarray, boundary_x: np.ndarray) -> bool:
    """Whether `simulation.settle` asks for the pre-pass: on, or auto and the fluid is a pool at rest."""
    if any(b.moving for b in scene.boundaries) or scene.emitters:
        # the pre-pass steps the method from rest at t = 0: moving walls and bodies would move and
        # emitters would not emit during it, so such scenes start as sampled
        if scene.settle == "on":
            raise ConfigError(
                "simulation.settle: 'on' cannot be combined with moving walls, rigid "
                "bodies or emitters (use 'auto' or 'off')"
            )
        return False
    if scene.settle != "auto":
        return scene.settle == "on"
    if scene.method == "pf":  # PF keeps a noise floor and never comes to rest (method.md section 3)
        return False
    g = np.asarray(scene.gravity, dtype=np.float64)
    if (
        len(fluid_x) == 0
        or len(boundary_x) == 0
        or np.any(fluid_v != 0.0)
        or not np.any(g)
        or not any(b.role == Role.CONTAINER for b in scene.boundaries)
    ):
        return False
    down = int(np.argmax(np.abs(g)))
    if np.count_nonzero(g) != 1:  # gravity along an axis only: "its floor" is a wall plane
        return False
    across = [k for k in range(3) if k != down]
    d = spacing(scene.particle_radius)
    reach = SETTLE_REACH * d
    lo, hi = boundary_x.min(axis=0)[across], boundary_x.max(axis=0)[across]
    # floor cells of size d (from the walls' lower corner) that lie inside [lo + reach, hi - reach]
    # must all have fluid above them
    first = math.ceil(reach / d)
    last = np.floor((hi - lo - reach) / d).astype(np.int64) - 1
    if np.any(last < first):
        return False
    cells = np.floor((fluid_x[:, across] - lo) / d).astype(np.int64)
    cells = cells[np.all((cells >= first) & (cells <= last), axis=1)]
    covered = np.zeros(last - first + 1, dtype=bool)
    covered[cells[:, 0] - first, cells[:, 1] - first] = True
    return bool(covered.all())


# The hydrostatic seed (method.md section 1): fluid at rest that stands on walls starts its solvers'
# warm starts from rho0 |g| depth, lowered towards free side faces. Runs of particles along an axis
# are broken by gaps wider than SEED_GAP d; a run's end is walled when a wall particle lies between
# d/2 and SEED_GAP d beyond it (a box fluid's first layer sits 1.1 d from the wall particles).
SEED_GAP = 1.5


def _runs(along: np.ndarray, row: np.ndarray, gap: float):
    """Runs of particles along one axis within rows of cells: (order, run, starts, ends), `order`
    sorting the particles by row then position, `run` each sorted particle's run, `starts` and
    `ends` the sorted indices of each run's first and last particle."""
    order = np.lexsort((along, row))
    a, r = along[order], row[order]
    new = np.ones(len(a), dtype=bool)
    new[1:] = (r[1:] != r[:-1]) | (a[1:] - a[:-1] > gap)
    starts = np.flatnonzero(new)
    ends = np.append(starts[1:], len(a)) - 1
    return order, np.cumsum(new) - 1, starts, ends


def hydrostatic_pressure(scene: Scene, fluid_x: np.ndarray, boundary_x: np.ndarray) -> np.ndarray | None:
    """The seed p_i = rho0 |g| D_i (1 - exp(-pi X_i / (2 H_i))) for fluid standing on walls, 0
    elsewhere; None when there is nothing to seed (no walls, no gravity, gravity not along an axis).

    D_i is the depth below the top of the particle's vertical run (the surface half a spacing above
    its highest particle), H_i that run's height and X_i the distance to the nearest free end of
    its horizontal runs (+inf when walls close them): the leading term of the harmonic correction
    that makes rho0 g D vanish on a free side face, which decays over 2 H / pi (method.md section 1).
    Vertical runs that do not stand on a wall (a falling block, a drop above the water) get none."""
    g = np.asarray(scene.gravity, dtype=np.float64)
    if len(fluid_x) == 0 or len(boundary_x) == 0 or np.count_nonzero(g) != 1:
        return None
    down = int(np.argmax(np.abs(g)))
    d = spacing(scene.particle_radius)
    gap = SEED_GAP * d
    y = fluid_x.copy()
    y[:, down] *= -np.sign(g[down])  # heights against gravity
    yb = boundary_x.copy()
    yb[:, down] *= -np.sign(g[down])
    cell = np.floor(y / d).astype(np.int64)
    wall_cell = np.floor(yb / d).astype(np.int64)
    lo = np.minimum(cell.min(axis=0), wall_cell.min(axis=0)) - 3
    span = np.maximum(cell.max(axis=0), wall_cell.max(axis=0)) + 4 - lo

    def key(c):
        c = c - lo
        return (c[:, 0] * span[1] + c[:, 1]) * span[2] + c[:, 2]

    walls = np.unique(key(wall_cell))

    def walled(ends: np.ndarray, axis: int, sign: float) -> np.ndarray:
        """Whether a wall particle lies between d/2 and gap beyond these particles along sign * axis."""
        hit = np.zeros(len(ends), dtype=bool)
        for beyond in (0.5 * d, gap):
            probe = np.floor(y[ends] / d).astype(np.int64)
            probe[:, axis] = np.floor((y[ends, axis] + sign * beyond) / d).astype(np.int64)
            hit |= np.isin(key(probe), walls)
        return hit

    def rows(axis: int) -> np.ndarray:
        """The row of cells along `axis` each particle is in (its key, with that axis's cell fixed)."""
        return key(np.column_stack([np.full(len(y), lo[k]) if k == axis else cell[:, k] for k in range(3)]))

    # vertical runs: depth, height, standing on walls
    order, run, starts, ends = _runs(y[:, down], rows(down), gap)
    top, bottom = y[order[ends], down], y[order[starts], down]
    standing = walled(order[starts], down, -1.0)
    depth = np.empty(len(y))
    height = np.empty(len(y))
    depth[order] = np.where(standing[run], top[run] - y[order, down] + 0.5 * d, 0.0)
    height[order] = top[run] - bottom[run] + d
    # horizontal runs: the distance to the nearest free end
    free = np.full(len(y), np.inf)
    for axis in (k for k in range(3) if k != down):
        order, run, starts, ends = _runs(y[:, axis], rows(axis), gap)
        a = y[order, axis]
        lo_end = np.where(walled(order[starts], axis, -1.0)[run], np.inf, a - y[order[starts], axis][run] + 0.5 * d)
        hi_end = np.where(walled(order[ends], axis, 1.0)[run], np.inf, y[order[ends], axis][run] - a + 0.5 * d)
        free[order] = np.minimum(free[order], np.minimum(lo_end, hi_end))
    return scene.density0 * np.abs(g[down]) * depth * (1.0 - np.exp(-0.5 * np.pi * free / height))


def sample_scene(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Fluid positions and velocities, wall particles, and notes on what was removed.

    Fluid particles inside an obstacle, outside every container, or closer than d = 2r to a
    wall particle are removed and counted (the lattice would otherwise start inside a wall).
    """
    from . import sampling

    r = scene.particle_radius
    xs, vs = [np.zeros((0, 3))], [np.zeros((0, 3))]
    frame = sampling.lattice_frame(scene)  # mesh fluids share the walls' rest lattice
    for spec in scene.fluids:
        x = sampling.fluid_positions(spec, r, frame=frame)
        xs.append(x)
        vs.append(np.tile(np.asarray(spec.velocity, dtype=np.float64), (len(x), 1)))
    fluid_x, fluid_v = np.concatenate(xs), np.concatenate(vs)
    walls = [sampling.boundary_positions(spec, r) for spec in scene.boundaries]
    boundary_x = np.concatenate([np.zeros((0, 3))] + walls)
    notes = [n for spec in (*scene.fluids, *scene.boundaries) for n in sampling.mesh_notes(spec)]
    if len(scene.boundaries) and len(fluid_x):
        kept, removed = sampling.remove_overlaps(
            fluid_x, boundary_x, sampling.default_overlap_distance(r), boundaries=scene.boundaries, radius=r
        )
        if any(spec.dynamic for spec in scene.boundaries):  # a wider gap around rigid bodies (rigid.BODY_GAP_D)
            from .rigid import body_gap_mask

            kept &= body_gap_mask(fluid_x, scene, walls, r)
            removed = int(len(fluid_x) - kept.sum())
        if removed:
            notes.append(
                f"{removed} of {len(fluid_x)} fluid particles overlapped a wall or lay outside the "
                f"containers and were removed"
            )
            fluid_x, fluid_v = fluid_x[kept], fluid_v[kept]
    if scene.emitters:
        from .emitters import wall_notes

        notes += wall_notes(scene, boundary_x)
    return np.ascontiguousarray(fluid_x), np.ascontiguousarray(fluid_v), np.ascontiguousarray(boundary_x), notes


def _wall_groups(scene: Scene, n_walls: int) -> np.ndarray | None:
    """Per wall particle, which moving wall it belongs to (rigid.boundary_groups; None: all static)."""
    if not any(b.moving for b in scene.boundaries):
        return None
    from .rigid import boundary_groups
    from .sampling import boundary_positions

    counts = [len(boundary_positions(spec, scene.particle_radius)) for spec in scene.boundaries]
    if sum(counts) != n_walls:
        raise ValueError(f"{n_walls} wall particles given, the scene's walls sample {sum(counts)}")
    return boundary_groups(scene, counts)


def _host(array_of, doc: str) -> property:
    """A read-only view of one of the backend's arrays, as a numpy array."""
    return property(lambda sim: sim.be.to_host(array_of(sim)), doc=doc)


class Simulation:
    """One fluid simulation: particle state, static walls, a method and the clock."""

    def __init__(
        self,
        scene: Scene,
        fluid_x: np.ndarray,
        fluid_v: np.ndarray,
        boundary_x: np.ndarray,
        fluid_ids: np.ndarray | None = None,
        backend: str | Backend | None = None,
        capacity: int | None = None,
        settle: bool = True,
    ):
        self.scene = scene
        backend = scene.backend if backend is None else backend  # simulation.backend, .precision, .device
        self.be = get_backend(backend, scene.precision, scene.device) if isinstance(backend, str) else backend
        r = scene.particle_radius
        self.spacing = spacing(r)
        self.support = support(r)
        # every particle carries the water of its lattice cell, rho0 d^3 (method.md section 1); one
        # fluid mass: the passes take it as a scalar
        mass = scene.density0 * self.spacing**3
        self.flow = None  # emitters, sinks, domain box (ipsph.emitters); None: a fixed particle count
        if scene.emitters or scene.sinks or scene.domain.min is not None:
            from .emitters import Flow, planned_emission

            first_id = int(np.max(fluid_ids)) + 1 if fluid_ids is not None and len(fluid_ids) else len(fluid_x)
            self.flow = Flow(scene, first_id)
            if capacity is None:
                capacity = len(fluid_x) + planned_emission(scene)
        self.state = ParticleState(fluid_x, fluid_v, np.full(len(fluid_x), mass), fluid_ids, self.be, capacity)
        from .sampling import rest_lattice

        lattice = rest_lattice(scene, boundary_x) if scene.fit_wall_volumes else None
        groups = _wall_groups(scene, len(boundary_x))
        self.boundary = Boundary(boundary_x, self.support, scene.density0, lattice, self.spacing, groups)
        self.walls = None  # moving walls and rigid bodies (ipsph.rigid)
        if groups is not None:
            from .rigid import WallDriver

            self.walls = WallDriver(scene, self.boundary, self.support, mass)
        self.search = self.be.neighbour_search(self.support, self.boundary)
        self.method = METHODS[scene.method](scene, self.state, self.boundary, self.search, self.be, mass)
        self.method.walls = self.walls
        self.time = 0.0
        self.steps = 0
        self.clamped_steps = 0
        ts = scene.time_step
        self.dt_min = ts.dt_min
        self.dt_max = ts.resolved_dt_max(r)
        self.domain = self._domain(boundary_x)
        self.method.prepare()
        self.settle_report: dict = {}
        settled = settle and wants_settle(scene, fluid_x, fluid_v, boundary_x)  # not when restoring a checkpoint
        if settled:
            self.settle_report = self.settle()
        vmax, _ = self.be.speed_energy(self.state.v, self.state.m)
        self.dt_next, self._clamped = self._cfl(self._wall_speed(vmax))
        if ts.dt_initial is not None:
            self.dt_next = min(ts.dt_initial, self.dt_max, max(self._viscous_dt(), self.dt_min))
        if settle and not settled and vmax == 0.0 and self.walls is None:
            self.seed_hydrostatic()

    def seed_hydrostatic(self) -> None:
        """Fluid at rest standing on walls starts the method's warm starts from its hydrostatic
        pressure (`hydrostatic_pressure`, method.md section 1): the first steps then correct that
        seed near the walls and the free surfaces instead of loading the column up from the floor."""
        p = hydrostatic_pressure(self.scene, self.be.to_host(self.state.x), self.boundary.x)
        if p is not None and np.any(p):
            self.method.seed(self.be.asarray(p), self.dt_next)

    def settle(self, max_steps: int = SETTLE_MAX_STEPS) -> dict:
        """The pre-pass before t = 0: run the method's steps of dt_max (at most the viscous limit)
        from rest, damping the velocities (v <- SETTLE_DAMPING v) after each, until SETTLE_HOLD
        steps in a row leave every particle below SETTLE_SPEED (or max_steps). The fluid then
        starts at rest (v = 0) in the solver's discrete equilibrium, and the method keeps its warm starts: the first step starts from the
        hydrostatic pressure instead of loading it up. The clock stays at 0. Returns a report
        (steps, the last step's top speed, how far the particles moved, in r)."""
        be, st, r = self.be, self.state, self.scene.particle_radius
        t0 = time.perf_counter()
        start = be.to_host(st.x)[np.argsort(be.to_host(st.id))]
        dt = min(self.dt_max, max(self._viscous_dt(), self.dt_min))  # the CFL rule's bounds at rest
        steps, still, vmax, top = 0, 0, math.inf, 0.0
        while steps < max_steps and still < SETTLE_HOLD:
            self.method.step(dt)
            steps += 1
            if self._first_unhealthy() >= 0:
                self._fail(self._first_unhealthy(), "while settling before t = 0")
            vmax, _ = be.speed_energy(st.v, st.m)
            still = still + 1 if vmax <= SETTLE_SPEED else 0
            top = max(top, vmax) if still else 0.0  # the fastest particle of the quiet stretch
            be.scale(st.v, SETTLE_DAMPING)
        be.scale(st.v, 0.0)
        self.method.prepare()
        moved = np.linalg.norm(be.to_host(st.x)[np.argsort(be.to_host(st.id))] - start, axis=1) / r
        return {
            "steps": steps,
            "dt": dt,
            "max_speed": float(top if still else vmax),
            "converged": bool(still >= SETTLE_HOLD),
            "moved_mean_r": float(moved.mean()),
            "moved_max_r": float(moved.max()),
            "seconds": time.perf_counter() - t0,
        }

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_scene(cls, scene, overrides=()) -> "Simulation":
        """Build from a Scene, a scene file path or a scene dict; samples meshes into particles."""
        from .scene import load_scene, scene_from_dict

        if isinstance(scene, (str, Path)):
            scene = load_scene(Path(scene), list(overrides))
        elif isinstance(scene, dict):
            scene = scene_from_dict(scene, Path.cwd())
        fluid_x, fluid_v, boundary_x, _ = sample_scene(scene)
        return cls(scene, fluid_x, fluid_v, boundary_x)

    def _domain(self, boundary_x):
        """Fluid leaving the containers' bounds (plus one support radius) has escaped; with a
        [domain] box, fluid outside it is removed, so nothing can escape it."""
        if self.scene.domain.min is not None:
            return np.asarray(self.scene.domain.min) - self.support, np.asarray(self.scene.domain.max) + self.support
        if not any(b.role == Role.CONTAINER for b in self.scene.boundaries) or len(boundary_x) == 0:
            return np.full(3, -np.inf), np.full(3, np.inf)
        return boundary_x.min(axis=0) - self.support, boundary_x.max(axis=0) + self.support

    # -- clock --------------------------------------------------------------------------------
    def _cfl(self, vmax: float) -> tuple[float, bool]:
        """dt = clamp(min(cfl * 0.4 * d / max|v|, dt_viscous), dt_min, dt_max); True when clamped
        up to dt_min. dt_viscous = H^2 / (VISCOUS_STEP nu) with Standard viscosity, else infinite."""
        raw = self.scene.time_step.cfl_factor * 0.4 * self.spacing / vmax if vmax > 0 else math.inf
        raw = min(raw, self._viscous_dt())
        return min(max(raw, self.dt_min), self.dt_max), raw < self.dt_min

    def _viscous_dt(self) -> float:
        """H^2 / (VISCOUS_STEP nu): the explicit Standard viscosity's step limit (inf without it)."""
        nu = self.scene.standard_viscosity
        return self.support * self.support / (VISCOUS_STEP * nu) if nu > 0.0 else math.inf

    def step(self, dt: float | None = None) -> StepStats:
        """Advance one step of `dt` (default: the CFL step) and check the state's health."""
        dt = self.dt_next if dt is None else float(dt)
        t0 = time.perf_counter()
        if self.walls is not None:
            self.walls.t = self.time
        try:
            rep = self.method.step(dt)
        except NumericalFailure as exc:  # raised inside the step (e.g. the neighbour grid blew up)
            self.time += dt
            self.steps += 1
            self._fail(self._first_unhealthy(), str(exc))
        self.time += dt
        self.steps += 1
        emitted = removed = 0
        if self.flow is not None:  # emit, remove: the count changes here only
            emitted, removed = self.flow.after_step(self)
        st = self.state
        bad = self._first_unhealthy()
        if bad >= 0:
            self._fail(bad)
        vmax, ke = self.be.speed_energy(st.v, st.m)
        clamped = self._clamped  # this step's CFL value fell below dt_min
        self.clamped_steps += clamped
        self.dt_next, self._clamped = self._cfl(self._wall_speed(vmax))
        self.be.synchronize()
        rep.timings["step"] = time.perf_counter() - t0
        return StepStats(
            **vars(rep),
            step=self.steps,
            time=self.time,
            max_speed=vmax,
            kinetic_energy=ke,
            dt_clamped=clamped,
            emitted=emitted,
            removed=removed,
        )

    def _wall_speed(self, vmax: float) -> float:
        """The CFL speed: the fluid's, or a moving wall's if faster (a body never moves more than
        the CFL fraction of d per step, so it cannot tunnel through a wall layer)."""
        return vmax if self.walls is None else max(vmax, self.walls.max_speed())

    def _first_unhealthy(self) -> int:
        if self.walls is not None and len(self.boundary.x):  # the containers may move
            self.domain = self._domain(self.boundary.x)
        return self.be.first_unhealthy(self.state.x, self.state.v, self.domain[0], self.domain[1])

    def _fail(self, i: int, inner: str | None = None):
        """Raise NumericalFailure naming step, time, particle id and quantity (i < 0: no particle found)."""
        where = f"numerical failure at step {self.steps}, t = {self.time:.6g} s"
        hint = "try a smaller time step (time_step.dt_max) or cfl_factor"
        if i < 0:
            raise NumericalFailure(f"{where}: {inner}; {hint}")
        be = self.be
        x, v = be.to_host(self.state.x)[i], be.to_host(self.state.v)[i]
        pid = int(be.to_host(self.state.id)[i])
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            what = f"non-finite {'position' if not np.all(np.isfinite(x)) else 'velocity'}"
        else:
            what = f"left the domain at x = ({x[0]:.4g}, {x[1]:.4g}, {x[2]:.4g}) m"
        raise NumericalFailure(
            f"{where}: particle id {pid} {what} (|v| = {np.linalg.norm(v):.4g} m/s)"
            + (f" ({inner})" if inner else "")
            + f"; {hint}"
        )

    def _landing_dt(self, t_target: float) -> tuple[float, bool]:
        """The next dt towards t_target: the CFL dt, or half / all of what remains (no slivers)."""
        rem = t_target - self.time
        dt = self.dt_next
        if rem <= dt * (1.0 + 1e-9):
            return rem, True
        return (0.5 * rem if rem < 2.0 * dt else dt), False

    def _step_towards(self, t_target: float, on_step) -> None:
        dt, last = self._landing_dt(t_target)
        stats = self.step(dt)
        if last:
            self.time = stats.time = t_target
        if on_step is not None:
            on_step(stats)

    def _before(self, t_target: float) -> bool:
        return t_target - self.time > 1e-12 * max(1.0, abs(t_target))

    def advance_to(self, t_target: float, on_step=None) -> None:
        """Step until `time == t_target` exactly: the last two steps share the remaining time."""
        while self._before(t_target):
            self._step_towards(t_target, on_step)

    def run(
        self,
        end_time: float | None = None,
        fps: float | None = None,
        on_frame=None,
        on_step=None,
        every_step: bool | None = None,
    ) -> None:
        """Run to `end_time`, calling on_frame(sim, k) at t = k / fps (k = 0 first) or after every step."""
        out = self.scene.output
        end_time = self.scene.end_time if end_time is None else end_time
        fps = out.fps if fps is None else fps
        every_step = out.every_step if every_step is None else every_step
        # the last frame at or before now (a resumed run may stand between two frames)
        frame = int(math.floor(self.time * fps + 1e-9)) if not every_step else self.steps
        if on_frame is not None and self.time == 0.0:
            on_frame(self, frame)
        if every_step:
            while self._before(end_time):
                self._step_towards(end_time, on_step)
                if on_frame is not None:
                    on_frame(self, self.steps)
            return
        n_frames = int(math.floor(end_time * fps + 1e-9))
        while frame < n_frames:
            frame += 1
            self.advance_to(frame / fps, on_step)
            if on_frame is not None:
                on_frame(self, frame)
        if self._before(end_time):  # end_time is not on the frame grid: its state is a frame too
            self.advance_to(end_time, on_step)
            if on_frame is not None:
                on_frame(self, frame + 1)

    # -- state ------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """Everything a bit-identical continuation needs, between two steps: the particles, the
        walls and the neighbour grid in their current order, and the clock (copies: later steps
        do not change it)."""
        return {
            "particles": self.state.state_dict(),
            "boundary": self.boundary.state_dict(),
            "search": self.search.state_dict(),
            "method": self.method.state_dict(),
            **({"walls": self.walls.state_dict()} if self.walls is not None else {}),
            "clock": {
                "time": self.time,
                "steps": self.steps,
                "clamped_steps": int(self.clamped_steps),
                "dt_next": self.dt_next,
                "next_clamped": bool(self._clamped),
            },
            **({"flow": self.flow.state_dict()} if self.flow else {}),
        }

    def load_state_dict(self, d: dict) -> None:
        """Continue from `state_dict()` of a Simulation of the same scene (ValueError if it does not
        fit). The walls and the grid go back before any neighbour search, so the sort of the
        (already sorted) fluid is the identity; then the method recomputes what it derives from
        positions."""
        self.boundary.load_state_dict(d["boundary"])
        self.search.load_state_dict(d["search"])
        self.state.load_state_dict(d["particles"])
        c = d["clock"]
        self.time, self.steps = float(c["time"]), int(c["steps"])
        self.clamped_steps = int(c["clamped_steps"])
        self.dt_next, self._clamped = float(c["dt_next"]), bool(c["next_clamped"])
        if self.flow is not None:
            self.flow.load_state_dict(d["flow"])
        self.method.resize(self.state.n)
        self.method.load_state_dict(d["method"])
        if self.walls is not None:
            self.walls.load_state_dict(d["walls"])
        self.method.prepare()

    # -- particle arrays, on the host (current order; `ids` maps them to the initial numbering) --
    positions = _host(lambda sim: sim.state.x, "(n, 3) positions [m]")
    velocities = _host(lambda sim: sim.state.v, "(n, 3) velocities [m/s]")
    densities = _host(lambda sim: sim.method.density(), "(n,) densities at the current positions [kg/m^3]")
    pressures = _host(lambda sim: sim.state.pressure, "(n,) pressures [Pa]")
    masses = _host(lambda sim: sim.state.m, "(n,) masses [kg]")
    ids = _host(lambda sim: sim.state.id, "(n,) ids: the particles' initial numbering")

    @property
    def n_fluid(self) -> int:
        return self.state.n

    @property
    def n_boundary(self) -> int:
        return self.boundary.n
