"""The Python API and the shared time loop: scene -> particles -> method -> steps and frames.

    sim = Simulation.from_scene("scene.toml")         # or a dict, or a Scene
    sim.run(on_frame=lambda sim, k: ...)              # frames land exactly on k / fps
    sim.step()                                        # one CFL step
    sim.positions, sim.velocities, sim.densities, sim.pressures, sim.ids

Time stepping (method.md section 1): one dt per step, from the CFL condition evaluated at the
end of the previous step, `Scene.cfl_step`: dt = clamp(cfl * 0.4 * d / max|v|, dt_min, dt_max)
(with Standard viscosity also at most H^2 / (60 nu)); steps whose CFL value fell below dt_min are counted, never
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
from .boundary import model_of
from .config import Role, Scene
from .errors import NumericalFailure
from .methods import METHODS
from .methods.base import StepReport
from .methods.settle import SETTLE_MAX_STEPS, hydrostatic_pressure, wants_settle
from .methods.settle import settle as settle_pass
from .methods.state import ParticleState
from .neighbours import search_for
from .sampling.scene import sample, sample_scene, wall_groups  # noqa: F401 - sample_scene: part of the Python API here


@dataclass
class StepStats(StepReport):
    """A method's StepReport plus what the time loop adds."""

    step: int = 0
    time: float = 0.0
    max_speed: float = 0.0
    kinetic_energy: float = 0.0
    dt_clamped: bool = False
    emitted: int = 0  # particles emitted at the end of the step (ipsph.flow)
    removed: int = 0  # particles removed by sinks and the domain box


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
        wall_counts: list[int] | None = None,
    ):
        self.scene = scene
        backend = scene.backend if backend is None else backend  # simulation.backend, .precision, .device
        self.be = get_backend(backend, scene.precision, scene.device) if isinstance(backend, str) else backend
        self.spacing = scene.spacing
        self.support = scene.support
        mass = scene.fluid_mass  # one fluid mass: the passes take it as a scalar
        self.flow = None  # emitters, sinks, domain box (ipsph.flow); None: a fixed particle count
        if scene.emitters or scene.sinks or scene.domain.min is not None:
            from .flow import Flow, planned_emission

            first_id = int(np.max(fluid_ids)) + 1 if fluid_ids is not None and len(fluid_ids) else len(fluid_x)
            self.flow = Flow(scene, first_id)
            if capacity is None:
                capacity = len(fluid_x) + planned_emission(scene)
        self.state = ParticleState(fluid_x, fluid_v, np.full(len(fluid_x), mass), fluid_ids, self.be, capacity)
        from .sampling.fluid import rest_lattice

        lattice = rest_lattice(scene, boundary_x) if scene.fit_wall_volumes else None
        groups, depth = wall_groups(scene, len(boundary_x), wall_counts)
        walls = model_of(scene)
        self.boundary = walls.particles(boundary_x, self.support, scene.density0, lattice, self.spacing, groups, depth)
        self.boundary.field = walls.field(scene)
        self.be.wall_mirror = walls.pressure_mirror
        if self.boundary.field is not None:  # no wall particles: the surfaces stand in for them below
            boundary_x = walls.surface_points(scene)
        self.wall_points = boundary_x  # the walls as points, for the host's geometric questions
        self.walls = None  # moving walls and rigid bodies (ipsph.boundary.rigid)
        if groups is not None:
            from .boundary.rigid import WallDriver

            self.walls = WallDriver(scene, self.boundary, self.support, mass)
        self.search = search_for(self.be, self.support, self.boundary)
        self.method = METHODS[scene.method](scene, self.state, self.boundary, self.search, self.be, mass)
        self.method.walls = self.walls
        self.time = 0.0
        self.steps = 0
        self.clamped_steps = 0
        ts = scene.time_step
        self.dt_min = ts.dt_min
        self.dt_max = scene.dt_max
        self.domain = self._domain(boundary_x)
        self.method.prepare()
        self.settle_report: dict = {}
        settled = settle and wants_settle(scene, fluid_x, fluid_v, boundary_x)  # not when restoring a checkpoint
        if settled:
            self.settle_report = self.settle()
        vmax, _ = self.be.speed_energy(self.state.v, self.state.m)
        self.dt_next, self._clamped = self._cfl(self._wall_speed(vmax))
        if ts.dt_initial is not None:
            self.dt_next = min(ts.dt_initial, scene.rest_dt())
        if settle and not settled and vmax == 0.0 and self.walls is None:
            self.seed_hydrostatic()

    def settle(self, max_steps: int = SETTLE_MAX_STEPS) -> dict:
        """The pre-pass before t = 0 (`ipsph.methods.settle.settle`); returns its report."""
        return settle_pass(self, max_steps)

    def seed_hydrostatic(self) -> None:
        """Fluid at rest standing on walls starts the method's warm starts from its hydrostatic
        pressure (`ipsph.methods.settle.hydrostatic_pressure`, method.md section 1): the first steps then
        correct that seed near the walls and the free surfaces instead of loading the column up
        from the floor."""
        p = hydrostatic_pressure(self.scene, self.be.to_host(self.state.x), self.wall_points)
        if p is not None and np.any(p):
            self.method.seed(self.be.asarray(p), self.dt_next)

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_scene(cls, scene, overrides=()) -> "Simulation":
        """Build from a Scene, a scene file path or a scene dict; samples meshes into particles.
        `overrides` (`--set` items, `key.path=value`) apply to a file or a dict; a resolved Scene
        takes none (ValueError: change it with `dataclasses.replace`)."""
        from .scene import load_scene, scene_from_dict
        from .scene.overrides import apply_overrides

        if isinstance(scene, (str, Path)):
            scene = load_scene(Path(scene), list(overrides))
        elif isinstance(scene, dict):
            scene = scene_from_dict(apply_overrides(scene, overrides), Path.cwd())
        elif list(overrides):
            raise ValueError("Simulation.from_scene: overrides apply to a scene file or dict, not to a resolved Scene")
        s = sample(scene)
        return cls(scene, s.fluid_x, s.fluid_v, s.boundary_x, wall_counts=s.wall_counts)

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
        """The CFL step at the fastest speed `vmax` (`Scene.cfl_step`) and whether it was clamped up to dt_min."""
        return self.scene.cfl_step(vmax)

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
            emitted, removed = self.flow.after_step(self.state, self.be, self.time)
            if emitted or removed:
                self.method.resize(self.state.n)
                self.method.prepare()
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
