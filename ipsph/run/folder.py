"""The output folder of one running simulation (layout: `ipsph.io`): its frames, the PVD, stats
rows, checkpoints, run.json, renders and surfaces handed to their processes, the progress line.
No signal handling and no solver: the runner drives it from the time loop's callbacks. (The checks
before a run, and creating the folder: `ipsph.io.prepare`.)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .. import io
from ..io import provenance, pvd, stats, vtu
from ..post import paraview
from . import checkpoint as ckpt

PROGRESS_EVERY_S = 10.0  # progress lines when stderr is not a terminal (a log file, a batch job)
INTERRUPT_RENDER_WAIT_S = 10.0  # after Ctrl-C the frames in flight get this long to render; --resume does the rest


class RunFolder:
    """Writes frames, the PVD, stats rows, checkpoints and run.json for one Simulation.

    With `resume` (a loaded checkpoint) the folder is continued: frames and renders after the
    checkpoint are deleted and dropped from the PVD, stats rows after its step are cut.
    """

    def __init__(
        self,
        out: Path,
        sim,
        scene,
        info: dict,
        renderer,
        progress: bool,
        resume: ckpt.Checkpoint | None = None,
        surfacer=None,
    ):
        self.out, self.sim, self.scene, self.info = out, sim, scene, info
        self.stopping = lambda: False  # the runner's: has a stop been requested (a signal)?
        self.fields = scene.output.fields
        self.checkpoint_interval = scene.output.checkpoint_interval
        self.field_data = paraview.frame_field_data(scene.particle_radius)
        (out / io.FRAMES_DIR).mkdir(parents=True, exist_ok=True)
        if resume is None:
            b = sim.boundary
            boundary_file = None
            if b.n:
                vtu.write_particles(
                    out / io.BOUNDARY_VTU,
                    b.x,
                    {"volume": b.psi, "id": np.arange(b.n, dtype=np.int64)},
                    0.0,
                    field_data=self.field_data,
                )
                boundary_file = io.BOUNDARY_VTU
            surface = io.BOUNDARY_SURFACE if scene.boundaries else None  # written below
            self.pvd = pvd.PvdSeries(out / io.RUN_PVD, boundary_file, static={"boundary_surface": surface})
            self.stats = stats.StatsWriter(out / io.STATS_CSV, stats.STATS_COLUMNS)
            self.frames, self.last_frame_time, self.solver_maxed = 0, None, 0
            self.last_checkpoint_time = 0.0
        else:
            self.pvd = pvd.PvdSeries.load(out / io.RUN_PVD)
            self.pvd.truncate_after(resume.time)
            self.frames = int(resume.scalars["frames"])
            self.last_frame_time = resume.scalars["last_frame_time"]
            self.solver_maxed = int(resume.scalars["solver_maxed"])
            self.last_checkpoint_time = resume.time
            self._delete_frames_from(self.frames)
            self.stats = stats.StatsWriter(out / io.STATS_CSV, stats.STATS_COLUMNS, truncate_after_step=resume.steps)
        self.gauges = None  # [[gauge]]: gauges.csv, sampled after every step (ipsph.gauges)
        if scene.gauges:
            from ..gauges import recorder

            self.gauges = recorder.GaugeLog(
                sim, out / recorder.GAUGES_CSV, resume_time=None if resume is None else resume.time
            )
            self.info["gauges"] = recorder.listing(self.gauges)
        self.surface = self._write_surface()
        self.bodies = None  # moving walls and rigid bodies: bodies.csv, bodies/*.vtp (io.bodies)
        if sim.walls is not None:
            from ..io.bodies import BodiesLog

            self.bodies = BodiesLog(out, None if resume is None else resume.time)
        self.renderer = self._configure_renderer(renderer) if renderer is not None else None
        self.surfacer = surfacer  # surfaces/*.vtp beside the solver (ipsph.post.surface_worker)
        if surfacer is not None:
            from ..boundary.containers import container_bounds

            clip = container_bounds(scene.boundaries)
            surfacer.configure(out, scene.particle_radius, scene.density0, scene.surface, clip)
            self.info["surface"] = {"enabled": True, **_asdict(scene.surface), "clip_bounds": clip}
        if resume is not None and scene.render.enabled:
            self._render_missing()
        self.progress = progress
        self._first_step, self._progress_at = None, 0.0
        self.max_speed = 0.0
        self.t_start = time.perf_counter()
        self.steps_start = sim.steps
        self.render_seconds = 0.0
        self.write_seconds = 0.0
        self.timings: dict[str, list[float]] = {}

    def _delete_frames_from(self, first: int) -> None:
        """Remove frame files (and their renders) numbered `first` and later: a resumed run rewrites them.
        Temporary files a killed run left behind go too (nothing references them)."""
        for folder, pattern in (
            (io.FRAMES_DIR, "fluid_*.vtu"),
            (io.RENDERS_DIR, "frame_*.png"),
            (io.SURFACES_DIR, "surface_*.*"),
            (io.BODIES_DIR, "bodies_*.vtp"),
        ):
            for f in (self.out / folder).glob(pattern):
                index = f.stem.rsplit("_", 1)[-1]
                if index.isdigit() and int(index) >= first:
                    f.unlink(missing_ok=True)
        for folder in (self.out, self.out / io.FRAMES_DIR, self.out / io.RENDERS_DIR, self.out / io.SURFACES_DIR):
            for f in folder.glob(".*.tmp"):
                f.unlink(missing_ok=True)

    def _render_missing(self) -> None:
        """On --resume with renders: the earlier frames without a render (an interrupt, --no-render or a
        missing GL stack cut them short) are queued first, from their VTU files; when the frames hold
        no velocity field (or the renderer fails), one line says how to make them."""
        missing = [k for k in range(self.frames) if not (self.out / io.render_file(k)).is_file()]
        if not missing or self.renderer is None:  # --no-render: no renders wanted now
            return
        if "velocity" in self.fields:
            for k in missing:
                x, fields, t = vtu.read_particles(self.out / io.frame_file(k))
                png = self.out / io.render_file(k)
                if not self.renderer.submit(x, fields["velocity"], png, float(t or 0.0)):
                    self._render_failed()
                    break
            else:
                print(
                    f"ipsph: note: rendering the {len(missing)} earlier frames that have no render "
                    f"({io.render_file(missing[0])} ...)",
                    file=sys.stderr,
                )
                return
        print(
            f"ipsph: note: {len(missing)} earlier frames have no render; `ipsph render {self.out}` makes them",
            file=sys.stderr,
        )

    def checkpoint(self, sim) -> None:
        """Write OUT/checkpoint.npz (atomically) with everything a bit-identical resume needs."""
        import numba

        t0 = time.perf_counter()
        ckpt.save(
            self.out / ckpt.CHECKPOINT_FILE,
            sim,
            frames=self.frames,
            last_frame_time=self.last_frame_time,
            solver_maxed=self.solver_maxed,
            threads=numba.get_num_threads(),
        )
        self.last_checkpoint_time = sim.time
        self.info["checkpoint"] = {"file": ckpt.CHECKPOINT_FILE, "time": sim.time, "step": sim.steps}
        self.write_seconds += time.perf_counter() - t0

    def _write_surface(self):
        if not self.scene.boundaries:
            return None
        import pyvista as pv

        from ..geometry.shapes import boundary_surface

        static = [spec for spec in self.scene.boundaries if not spec.moving]  # moving ones: bodies/
        if not static:
            return None
        surf = pv.merge([boundary_surface(spec) for spec in static])
        vtu.write_surface(self.out / io.BOUNDARY_SURFACE, surf)
        return surf

    def _configure_renderer(self, worker):
        # No GL probe here: the render worker is itself a child process, so a missing GL stack
        # crashes it, not the run, and it starts while the solver sets up (a probe costs ~1 s).
        from ..post import render

        sim, scene = self.sim, self.scene
        speed = max(
            [float(np.linalg.norm(f.velocity)) for f in scene.fluids] + [e.velocity for e in scene.emitters],
            default=0.0,
        )
        bounds = self.info["domain_bounds"]
        tops = [float(sim.positions[:, 1].max())] if sim.n_fluid else []
        tops += [float(e.position[1]) for e in scene.emitters]
        top = max(tops) if tops else bounds[3]
        rng = (
            scene.render.speed_range
            or self.info.pop("render_speed_range", None)
            or render.default_speed_range(speed, scene.gravity, top, bounds[2])
        )
        self.info["render"] = {**_asdict(scene.render), "enabled": True, "speed_range": list(rng)}
        surface = self.out / io.BOUNDARY_SURFACE if self.surface is not None else None
        worker.configure(
            scene.render,
            bounds,
            scene.particle_radius,
            rng,
            surface,
            title=f"{scene.name} - {scene.method.value.upper()} - "
            + (f"{sim.n_fluid:,} particles" if sim.flow is None else "emitters and sinks"),
        )
        return worker

    def frame(self, sim, k: int) -> None:
        t0 = time.perf_counter()
        if self.last_frame_time is not None and sim.time <= self.last_frame_time:
            return
        name = io.frame_file(self.frames)
        fields = {}
        for f in self.fields:
            fields[f] = {
                "velocity": lambda: sim.velocities.astype(np.float32),
                "density": lambda: sim.densities.astype(np.float32),
                "pressure": lambda: sim.pressures.astype(np.float32),
                "mass": lambda: sim.masses.astype(np.float32),
                "id": lambda: sim.ids,
            }[f]()
        vtu.write_particles(
            self.out / name, sim.positions.astype(np.float32), fields, sim.time, field_data=self.field_data
        )
        self._surfaces_done()  # listed by the same .pvd rewrite as the frame
        moving = {} if self.bodies is None else {"bodies": self.bodies.frame(sim, self.frames)}
        self.pvd.add(sim.time, name, **moving)
        t1 = time.perf_counter()
        self.write_seconds += t1 - t0
        if self.surfacer is not None:  # after the frame is on disk; never waits for the surface process
            self.surfacer.submit(self.frames, sim.time, sim.positions, sim.velocities, _warn)
        if self.renderer is not None and self.scene.render.mode != "surface":
            png = self.out / io.render_file(self.frames)
            if not self.renderer.submit(
                sim.positions, sim.velocities, png, sim.time, *(self.out / m for m in moving.values())
            ):
                self._render_failed()
            self.render_seconds += time.perf_counter() - t1  # time the solver waited for renders
        self.frames += 1
        self.last_frame_time = sim.time
        interval = self.checkpoint_interval
        if interval is not None and sim.time - self.last_checkpoint_time >= interval - 1e-9 * max(1.0, interval):
            self.checkpoint(sim)

    def step(self, s) -> None:
        if self.bodies is not None:
            self.bodies.step(self.sim)
        row = stats.step_row(s, self.sim.n_fluid)
        for p, v in s.timings.items():
            self.timings.setdefault(p, []).append(1000 * v)
        self.solver_maxed += s.solver_maxed
        self.max_speed = max(self.max_speed, float(s.max_speed))
        self.stats.write(row)
        if self.gauges is not None:
            self.gauges.sample()
        if self.progress:
            self._progress(s)

    def _plot_gauges(self) -> None:
        """plots/gauges.png at the end of a run (a failure is a warning: the numbers are in gauges.csv)."""
        from ..gauges.plot import plot_gauges

        try:
            path = plot_gauges(self.out / io.GAUGES_CSV, self.out / io.PLOTS_DIR / "gauges.png")
        except Exception as exc:  # noqa: BLE001 - matplotlib's errors are many; the run's result stands
            print(f"ipsph: warning: gauges not plotted: {' '.join(str(exc).split())}", file=sys.stderr)
            return
        self.info["gauges"]["plot"] = str(path.relative_to(self.out))

    def _surfaces_done(self) -> bool:
        """List the surfaces the surface process finished in run.pvd (and render them in surface mode)."""
        done = self.surfacer.collect(_warn) if self.surfacer is not None else []
        for index, t, name in done:
            self.pvd.add_surface(t, name)
            if self.renderer is not None and self.scene.render.mode == "surface":
                png = self.out / io.render_file(index)
                if not self.renderer.submit_surface(self.out / name, png, t):
                    self._render_failed()
        return bool(done)

    def _close_surfaces(self) -> None:
        """Wait for the last surfaces (Ctrl-C skips them), list them, say which frames have none."""
        self.surfacer.finish(self.out, self.frames, _warn)
        if self._surfaces_done():
            self.pvd.write()
        self.info["surface"] = {**self.info.get("surface", {}), **self.surfacer.summary()}
        self.surfacer = None

    def _progress(self, s) -> None:
        """The live line on a terminal (every step); elsewhere one line every PROGRESS_EVERY_S.
        The ETA is the run's own rate since its first step (which holds the JIT compilation)."""
        from .estimate import eta_seconds, fmt_duration

        now = time.perf_counter()
        if self._first_step is None:
            self._first_step = (now, s.time, s.step)
            self._progress_at = now
        tty = self.progress is True
        if not tty and now - self._progress_at < PROGRESS_EVERY_S:
            return
        self._progress_at = now
        end = self.scene.end_time
        w0, t0, k0 = self._first_step
        rate = (s.step - k0) / max(now - w0, 1e-9)
        eta = fmt_duration(eta_seconds(s.time, end, t0, now - w0)) if s.step > k0 else "?"
        line = (
            f"t = {s.time:7.3f} / {end:.3f} s ({100 * s.time / end:3.0f} %)  ETA {eta:>6}  "
            f"frame {self.frames:4d}  step {s.step:6d}  density error {100 * s.density_error_mean:.3f} %  "
            f"{rate:6.1f} steps/s"
        )
        sys.stderr.write(f"\r  {line} " if tty else f"ipsph: {line}\n")
        sys.stderr.flush()

    def _render_failed(self, running: bool = True) -> None:
        why = self.renderer.error or "the render process stopped"
        if self.renderer.ready:
            carries_on = "; the simulation carries on" if running and not self.stopping() else ""
            print(f"\nipsph: warning: renders stopped ({why}){carries_on}", file=sys.stderr)
        else:
            print(f"\nipsph: warning: renders skipped: {why}", file=sys.stderr)
        self.info["render"] = {**self.info.get("render", {}), "enabled": False, "skipped": why}
        self.renderer.terminate()
        self.renderer = None

    def close(self, interrupted: bool = False) -> None:
        if self.progress is True:
            sys.stderr.write("\n")
        self.stats.close()
        if self.gauges is not None:
            self.gauges.close()
            if not interrupted:
                self._plot_gauges()
        if self.surfacer is not None:  # first: in surface mode its last surfaces still go to the renderer
            self._close_surfaces()
        if self.renderer is not None:
            t0 = time.perf_counter()
            try:
                self.renderer.close(
                    timeout=INTERRUPT_RENDER_WAIT_S if interrupted else None,
                    notice=lambda n: print(
                        f"ipsph: rendering the last {n} frames (Ctrl-C skips them; `ipsph render {self.out}` "
                        f"makes them later)",
                        file=sys.stderr,
                    ),
                )  # the frames still in flight
            except KeyboardInterrupt:
                missing = self.renderer.backlog
                self.renderer.terminate()
                print(
                    f"ipsph: warning: renders interrupted, {missing} frames not rendered; "
                    f"`ipsph render {self.out}` makes them",
                    file=sys.stderr,
                )
                self.info["render"] = {**self.info.get("render", {}), "interrupted": True}
                self.renderer = None
                return
            self.render_seconds += time.perf_counter() - t0
            left = self.renderer.backlog
            if interrupted and left > 0:  # stopped after INTERRUPT_RENDER_WAIT_S: the user asked to stop
                print(
                    f"ipsph: note: {left} frames were not rendered before the interrupt; --resume renders "
                    f"them first (or `ipsph render {self.out}`)",
                    file=sys.stderr,
                )
                self.info["render"] = {**self.info.get("render", {}), "interrupted": True}
                self.renderer = None
                return
            if self.renderer.error and not interrupted:  # (on an interrupt: our own stop, or --resume retries)
                self._render_failed(running=False)


def _warn(msg: str) -> None:
    print(f"\n{msg}" if msg.startswith("ipsph: warning") else msg, file=sys.stderr)


def _asdict(obj):
    return provenance.to_jsonable(obj)
