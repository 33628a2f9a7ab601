"""`ipsph run`: one simulation writing a ParaView-ready output folder, and losing nothing.

Order of business: check the output folder, the particle budget and the radius against the
geometry (bad input exits 2 before any large allocation), sample, write the boundary once,
then per frame a VTU + the PVD (atomically) + a render (+ a checkpoint every
output.checkpoint_interval), per step a stats row. SIGINT/SIGTERM finish the current step,
write a final frame and a checkpoint and exit 130; a numerical failure stops with exit 3, a
failed write (disk full) with exit 4; run.json always says how the run ended. `--resume`
restores the checkpoint, drops frames and stats rows after it, and continues.
"""
from __future__ import annotations

import math
import os
import shutil
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import checkpoint as ckpt
from . import paraview
from . import io as out_io
from .io import provenance, pvd, stats, vtu  # noqa: F401  (submodules used via out_io)
from .errors import EXIT_INTERRUPTED, EXIT_OK, IpsphError, NumericalFailure, OutputError
from .model import Scene
from .simulation import Simulation, StepStats, sample_scene

PHASES = ("neighbourSearch", "densities", "solvePDConstraints", "xsph", "divergenceSolve", "densitySolve")
STATS_COLUMNS = ("step", "time", "dt", "particles", "density_error_mean_pct", "density_error_max_pct",
                 "divergence_error_pct", "pd_passes", "divergence_iterations", "density_iterations",
                 "max_speed", "kinetic_energy", "dt_clamped", "solver_maxed", "ms_step") \
    + tuple(f"ms_{p}" for p in PHASES)
BYTES_PER_PARTICLE = 1024  # the solver's budget per fluid particle (docs/performance.md)
PROGRESS_EVERY_S = 10.0    # progress lines when stderr is not a terminal (a log file, a batch job)
INTERRUPT_RENDER_WAIT_S = 10.0  # after Ctrl-C the frames in flight get this long to render; --resume does the rest


class Interrupted(Exception):
    """SIGINT / SIGTERM arrived; the run stops after the current step."""


@dataclass
class RunOptions:
    out_dir: Path
    render: bool = True
    overwrite: bool = False
    resume: bool = False
    threads: int | None = None
    max_particles: int | None = None
    progress: bool | None = None   # None: live on a TTY, else one line every PROGRESS_EVERY_S
    yes: bool = False              # run even when the estimate says hours and no one is at a terminal
    started: float | None = None   # time.perf_counter() when the process started (the CLI: its imports count)
    surface: bool | None = None    # None: the scene's output.surface (or render.mode = "surface")


# -- checks before any allocation ------------------------------------------------------------------
def check_output_folder(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse an unwritable folder, or one holding an earlier run (unless overwrite/resume).
    Creates and deletes nothing: a refused run leaves no trace (`prepare_output_folder` does that
    once every check has passed)."""
    out = out.expanduser()
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is a file; choose another -o")
    if (out / out_io.RUN_JSON).exists() and not (overwrite or resume):
        raise OutputError(f"output folder {out} holds an earlier run; pass --overwrite to replace it "
                          f"or --resume to continue it")
    if resume and not (out / out_io.RUN_JSON).exists():
        raise OutputError(f"--resume: output folder {out} (resolved {out.resolve()}) holds no earlier run "
                          f"to continue; run without --resume")
    existing = out.resolve()
    while not existing.exists():  # the deepest folder that exists must let us create the rest
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is not writable: "
                          f"{existing} is {'not a folder' if not existing.is_dir() else 'read-only'}")


# Everything a run (and `ipsph render` / `ipsph plot` into it) writes: --overwrite removes all of it.
WRITTEN_DIRS = (out_io.FRAMES_DIR, out_io.RENDERS_DIR, out_io.PLOTS_DIR, out_io.SURFACES_DIR)
WRITTEN_FILES = (out_io.RUN_PVD, out_io.BOUNDARY_VTU, out_io.BOUNDARY_SURFACE, out_io.STATS_CSV,
                 out_io.RUN_JSON, ckpt.CHECKPOINT_FILE, "video.mp4", "video.gif", out_io.PARAVIEW_SCRIPT,
                 *(p.series for p in out_io.PARTS if p.series))


def prepare_output_folder(out: Path, overwrite: bool, resume: bool) -> None:
    """Create the folder, prove it writable, and with --overwrite remove the earlier run's files."""
    out = out.expanduser()
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".ipsph-write-test-{os.getpid()}"
        probe.write_bytes(b"ok")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is not writable: "
                          f"{exc.strerror or exc}") from exc
    if overwrite and not resume:
        for name in WRITTEN_DIRS:
            shutil.rmtree(out / name, ignore_errors=True)
        for name in WRITTEN_FILES:
            (out / name).unlink(missing_ok=True)


def available_memory() -> int:
    """Bytes of memory available to this run now (psutil; 8 GiB if it cannot tell)."""
    try:
        import psutil
        return int(psutil.virtual_memory().available)
    except Exception:  # pragma: no cover - psutil is a dependency
        return 8 << 30


def default_max_particles() -> int:
    """Half the available memory at BYTES_PER_PARTICLE per particle."""
    return int(available_memory() // 2 // BYTES_PER_PARTICLE)


RENDER_BYTES_PER_PIXEL = 112  # render process peak: static layers, depth/owner/shade buffers, frame and
                              # PNG rows, VTK's and llvmpipe's framebuffers (measured 100 B/px at 3840x2160)


def check_render_size(scene: Scene) -> None:
    """Refuse an image size whose render process would need over half the available memory (exit 2)."""
    from .errors import ConfigError
    px = int(scene.render.width) * int(scene.render.height)
    need = px * RENDER_BYTES_PER_PIXEL
    avail = available_memory()
    if need > avail // 2:
        raise ConfigError(
            f"render.width x render.height = {scene.render.width} x {scene.render.height} would need about "
            f"{need / 2**30:.1f} GiB in the render process, over half the available {avail / 2**30:.1f} GiB; "
            f"use a smaller image, or --no-render and `ipsph render OUT --size W H` on a larger machine")


def check_size(scene: Scene, max_particles: int | None) -> int:
    """Estimate the fluid count before sampling and refuse what would not fit (exit 2)."""
    return check_fluid_count(scene.fluids, scene.particle_radius, max_particles)


def check_fluid_count(fluids, radius: float, max_particles: int | None) -> int:
    """The estimated fluid count of `fluids` at `radius`; ConfigError above the limit (default: memory)."""
    from . import sampling
    from .errors import ConfigError
    limit = max_particles or default_max_particles()
    total = 0
    for spec in fluids:
        n = sampling.estimate_fluid_count(spec, radius)
        total += n
        if total > limit:
            ext = _extent_hint(spec)
            raise ConfigError(
                f"fluid '{spec.name}' would need about {total:,} particles ({total * BYTES_PER_PARTICLE / 2**30:.1f} GiB) "
                f"at particle_radius {radius} m, over the limit of {limit:,} (--max-particles){ext}")
    return total


def check_geometry(scene: Scene) -> None:
    """Refuse a particle radius too large for a fluid body: fewer than 2 particles across it (exit 2)."""
    from .errors import ConfigError
    d = 2.0 * scene.particle_radius
    for i, spec in enumerate(scene.fluids):
        ext = _fluid_extent(spec)
        if ext is None:
            continue
        # box fluids: SPlisHSPlasH's round(extent / d) - 1 per axis; meshes: the lattice across the bounds
        n = np.floor(ext / d + 0.5) - 1 if spec.shape == "box" else np.floor(ext / d)
        if n.min() < 2:
            a = int(np.argmin(n))
            need = ext[a] / (5.0 if spec.shape == "box" else 4.0)
            raise ConfigError(
                f"fluid[{i}] '{spec.name}': simulation.particle_radius {scene.particle_radius} m is too large for "
                f"its extent of {ext[a]:.4g} m along {'xyz'[a]} ({int(max(n[a], 0))} particle(s) across, at least 2 "
                f"needed); use particle_radius <= {need:.3g} m (a tenth of that or less for useful results)")


def _fluid_extent(spec) -> np.ndarray | None:
    """Extent (m) of a fluid body after its transform's scale, or None when its mesh cannot be read."""
    if spec.shape == "box" and spec.box_min is not None:
        return np.abs(np.subtract(spec.box_max, spec.box_min) * np.asarray(spec.transform.scale))
    try:
        from .meshes import load_mesh, transform_mesh
        b = np.asarray(transform_mesh(load_mesh(spec.mesh), spec.transform).bounds).reshape(3, 2)
    except Exception:  # the sampler reports unreadable meshes with the full story
        return None
    return b[:, 1] - b[:, 0]


def _extent_hint(spec) -> str:
    ext = _fluid_extent(spec)
    if ext is None:
        return ""
    hint = f"; its {'mesh ' if spec.shape != 'box' else ''}extent is {ext[0]:.4g} x {ext[1]:.4g} x {ext[2]:.4g} m"
    if ext.max() > 100:
        hint += " (a mesh 1000x too large is probably in millimetres: scale it by 0.001)"
    return hint


# -- the run ---------------------------------------------------------------------------------------
class OutputFolder:
    """Writes frames, the PVD, stats rows, checkpoints and run.json for one Simulation.

    With `resume` (a loaded checkpoint) the folder is continued: frames and renders after the
    checkpoint are deleted and dropped from the PVD, stats rows after its step are cut.
    """

    def __init__(self, out: Path, sim: Simulation, scene: Scene, info: dict, renderer, progress: bool,
                 resume: ckpt.Checkpoint | None = None, surfacer=None):
        self.out, self.sim, self.scene, self.info = out, sim, scene, info
        self.fields = scene.output.fields
        self.checkpoint_interval = scene.output.checkpoint_interval
        self.field_data = paraview.frame_field_data(scene.particle_radius)
        (out / out_io.FRAMES_DIR).mkdir(parents=True, exist_ok=True)
        if resume is None:
            b = sim.boundary
            boundary_file = None
            if b.n:
                out_io.vtu.write_particles(out / out_io.BOUNDARY_VTU, b.x,
                                           {"volume": b.psi, "id": np.arange(b.n, dtype=np.int64)}, 0.0,
                                           field_data=self.field_data)
                boundary_file = out_io.BOUNDARY_VTU
            surface = out_io.BOUNDARY_SURFACE if scene.boundaries else None  # written below
            self.pvd = out_io.pvd.PvdSeries(out / out_io.RUN_PVD, boundary_file, static={"boundary_surface": surface})
            self.stats = out_io.stats.StatsWriter(out / out_io.STATS_CSV, STATS_COLUMNS)
            self.frames, self.last_frame_time, self.solver_maxed = 0, None, 0
            self.last_checkpoint_time = 0.0
        else:
            self.pvd = out_io.pvd.PvdSeries.load(out / out_io.RUN_PVD)
            self.pvd.truncate_after(resume.time)
            self.frames = int(resume.scalars["frames"])
            self.last_frame_time = resume.scalars["last_frame_time"]
            self.solver_maxed = int(resume.scalars["solver_maxed"])
            self.last_checkpoint_time = resume.time
            self._delete_frames_from(self.frames)
            self.stats = out_io.stats.StatsWriter(out / out_io.STATS_CSV, STATS_COLUMNS,
                                                  truncate_after_step=resume.steps)
        self.surface = self._write_surface()
        self.renderer = self._configure_renderer(renderer) if renderer is not None else None
        self.surfacer = surfacer  # surfaces/*.vtp beside the solver (ipsph.surface_worker)
        if surfacer is not None:
            from .surface import container_bounds
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
        for folder, pattern in ((out_io.FRAMES_DIR, "fluid_*.vtu"), (out_io.RENDERS_DIR, "frame_*.png"),
                                (out_io.SURFACES_DIR, "surface_*.*")):
            for f in (self.out / folder).glob(pattern):
                index = f.stem.rsplit("_", 1)[-1]
                if index.isdigit() and int(index) >= first:
                    f.unlink(missing_ok=True)
        for folder in (self.out, self.out / out_io.FRAMES_DIR, self.out / out_io.RENDERS_DIR,
                       self.out / out_io.SURFACES_DIR):
            for f in folder.glob(".*.tmp"):
                f.unlink(missing_ok=True)

    def _render_missing(self) -> None:
        """On --resume with renders: the earlier frames without a render (an interrupt, --no-render or a
        missing GL stack cut them short) are queued first, from their VTU files; when the frames hold
        no velocity field (or the renderer fails), one line says how to make them."""
        missing = [k for k in range(self.frames)
                   if not (self.out / out_io.RENDERS_DIR / f"frame_{k:06d}.png").is_file()]
        if not missing or self.renderer is None:  # --no-render: no renders wanted now
            return
        if "velocity" in self.fields:
            for k in missing:
                x, fields, t = out_io.vtu.read_particles(self.out / out_io.frame_file(k))
                png = self.out / out_io.RENDERS_DIR / f"frame_{k:06d}.png"
                if not self.renderer.submit(x, fields["velocity"], png, float(t or 0.0)):
                    self._render_failed()
                    break
            else:
                print(f"ipsph: note: rendering the {len(missing)} earlier frames that have no render "
                      f"({out_io.RENDERS_DIR}/frame_{missing[0]:06d}.png ...)", file=sys.stderr)
                return
        print(f"ipsph: note: {len(missing)} earlier frames have no render; `ipsph render {self.out}` "
              f"makes them", file=sys.stderr)

    def checkpoint(self, sim: Simulation) -> None:
        """Write OUT/checkpoint.npz (atomically) with everything a bit-identical resume needs."""
        import numba
        t0 = time.perf_counter()
        ckpt.save(self.out / ckpt.CHECKPOINT_FILE, sim, frames=self.frames, last_frame_time=self.last_frame_time,
                  solver_maxed=self.solver_maxed, threads=numba.get_num_threads())
        self.last_checkpoint_time = sim.time
        self.info["checkpoint"] = {"file": ckpt.CHECKPOINT_FILE, "time": sim.time, "step": sim.steps}
        self.write_seconds += time.perf_counter() - t0

    def _write_surface(self):
        if not self.scene.boundaries:
            return None
        import pyvista as pv
        from .sampling import boundary_surface
        surf = pv.merge([boundary_surface(spec) for spec in self.scene.boundaries])
        out_io.vtu.write_surface(self.out / out_io.BOUNDARY_SURFACE, surf)
        return surf

    def _configure_renderer(self, worker):
        # No GL probe here: the render worker is itself a child process, so a missing GL stack
        # crashes it, not the run, and it starts while the solver sets up (a probe costs ~1 s).
        from . import render
        sim, scene = self.sim, self.scene
        speed = max((float(np.linalg.norm(f.velocity)) for f in scene.fluids), default=0.0)
        bounds = self.info["domain_bounds"]
        top = float(sim.positions[:, 1].max()) if sim.n_fluid else bounds[3]
        rng = scene.render.speed_range or self.info.pop("render_speed_range", None) \
            or render.default_speed_range(speed, scene.gravity, top, bounds[2])
        self.info["render"] = {**_asdict(scene.render), "enabled": True, "speed_range": list(rng)}
        surface = self.out / out_io.BOUNDARY_SURFACE if self.surface is not None else None
        worker.configure(scene.render, bounds, scene.particle_radius, rng, surface,
                         title=f"{scene.name} - {scene.method.value.upper()} - {sim.n_fluid:,} particles")
        return worker

    def frame(self, sim: Simulation, k: int) -> None:
        t0 = time.perf_counter()
        if self.last_frame_time is not None and sim.time <= self.last_frame_time:
            return
        name = out_io.frame_file(self.frames)
        fields = {}
        for f in self.fields:
            fields[f] = {"velocity": lambda: sim.velocities.astype(np.float32),
                         "density": lambda: sim.densities.astype(np.float32),
                         "pressure": lambda: sim.pressures.astype(np.float32),
                         "mass": lambda: sim.masses.astype(np.float32),
                         "id": lambda: sim.ids}[f]()
        out_io.vtu.write_particles(self.out / name, sim.positions.astype(np.float32), fields, sim.time,
                                   field_data=self.field_data)
        self._surfaces_done()  # listed by the same .pvd rewrite as the frame
        self.pvd.add(sim.time, name)
        t1 = time.perf_counter()
        self.write_seconds += t1 - t0
        if self.surfacer is not None:  # after the frame is on disk; never waits for the surface process
            self.surfacer.submit(self.frames, sim.time, sim.positions, sim.velocities, _warn)
        if self.renderer is not None and self.scene.render.mode != "surface":
            png = self.out / out_io.RENDERS_DIR / f"frame_{self.frames:06d}.png"
            if not self.renderer.submit(sim.positions, sim.velocities, png, sim.time):
                self._render_failed()
            self.render_seconds += time.perf_counter() - t1  # time the solver waited for renders
        self.frames += 1
        self.last_frame_time = sim.time
        interval = self.checkpoint_interval
        if interval is not None and sim.time - self.last_checkpoint_time >= interval - 1e-9 * max(1.0, interval):
            self.checkpoint(sim)

    def step(self, s: StepStats) -> None:
        row = {"step": s.step, "time": s.time, "dt": s.dt, "particles": self.sim.n_fluid,
               "density_error_mean_pct": 100 * s.density_error_mean,
               "density_error_max_pct": 100 * s.density_error_max,
               "divergence_error_pct": 100 * s.divergence_error, "pd_passes": s.pd_passes,
               "divergence_iterations": s.divergence_iterations, "density_iterations": s.density_iterations,
               "max_speed": s.max_speed, "kinetic_energy": s.kinetic_energy, "dt_clamped": s.dt_clamped,
               "solver_maxed": s.solver_maxed, "ms_step": 1000 * s.timings.get("step", 0.0)}
        for p in PHASES:  # empty for a phase this method does not have (not a timing of 0 ms)
            row[f"ms_{p}"] = 1000 * s.timings[p] if p in s.timings else None
        for p, v in s.timings.items():
            self.timings.setdefault(p, []).append(1000 * v)
        self.solver_maxed += s.solver_maxed
        self.max_speed = max(self.max_speed, float(s.max_speed))
        self.stats.write(row)
        if self.progress:
            self._progress(s)
        if _STOP["signal"]:
            raise Interrupted()

    def _surfaces_done(self) -> bool:
        """List the surfaces the surface process finished in run.pvd (and render them in surface mode)."""
        done = self.surfacer.collect(_warn) if self.surfacer is not None else []
        for index, t, name in done:
            self.pvd.add_surface(t, name)
            if self.renderer is not None and self.scene.render.mode == "surface":
                png = self.out / out_io.RENDERS_DIR / f"frame_{index:06d}.png"
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

    def _progress(self, s: StepStats) -> None:
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
        line = (f"t = {s.time:7.3f} / {end:.3f} s ({100 * s.time / end:3.0f} %)  ETA {eta:>6}  "
                f"frame {self.frames:4d}  step {s.step:6d}  density error {100 * s.density_error_mean:.3f} %  "
                f"{rate:6.1f} steps/s")
        sys.stderr.write(f"\r  {line} " if tty else f"ipsph: {line}\n")
        sys.stderr.flush()

    def _render_failed(self, running: bool = True) -> None:
        why = self.renderer.error or "the render process stopped"
        if self.renderer.ready:
            carries_on = "; the simulation carries on" if running and not _STOP["signal"] else ""
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
        if self.surfacer is not None:  # first: in surface mode its last surfaces still go to the renderer
            self._close_surfaces()
        if self.renderer is not None:
            t0 = time.perf_counter()
            try:
                self.renderer.close(timeout=INTERRUPT_RENDER_WAIT_S if interrupted else None, notice=lambda n: print(
                    f"ipsph: rendering the last {n} frames (Ctrl-C skips them; `ipsph render {self.out}` "
                    f"makes them later)", file=sys.stderr))  # the frames still in flight
            except KeyboardInterrupt:
                missing = self.renderer.backlog
                self.renderer.terminate()
                print(f"ipsph: warning: renders interrupted, {missing} frames not rendered; "
                      f"`ipsph render {self.out}` makes them", file=sys.stderr)
                self.info["render"] = {**self.info.get("render", {}), "interrupted": True}
                self.renderer = None
                return
            self.render_seconds += time.perf_counter() - t0
            left = self.renderer.backlog
            if interrupted and left > 0:  # stopped after INTERRUPT_RENDER_WAIT_S: the user asked to stop
                print(f"ipsph: note: {left} frames were not rendered before the interrupt; --resume renders "
                      f"them first (or `ipsph render {self.out}`)", file=sys.stderr)
                self.info["render"] = {**self.info.get("render", {}), "interrupted": True}
                self.renderer = None
                return
            if self.renderer.error and not interrupted:  # (on an interrupt: our own stop, or --resume retries)
                self._render_failed(running=False)


_STOP = {"signal": None}


def _on_signal(signum, _frame):
    _STOP["signal"] = signum


def _warn(msg: str) -> None:
    print(f"\n{msg}" if msg.startswith("ipsph: warning") else msg, file=sys.stderr)


def _asdict(obj):
    from .io.provenance import to_jsonable
    return to_jsonable(obj)


class RunClock:
    """Where a run's wall time goes: Numba's compilation (its "numba:compile" events: compiling,
    not loading from the cache) counted apart from the phase it happens in."""

    def __init__(self, begin: float | None = None):
        from numba.core import event
        self.begin = time.perf_counter() if begin is None else begin
        self.loop_begin = None
        self.compile_before_loop = 0.0
        self.helper = None  # the jit_warm process of a cold start
        self._event, self._timer = event, event.TimingListener()
        event.register("numba:compile", self._timer)

    @property
    def compile_seconds(self) -> float:
        return self._timer.duration if self._timer.done else 0.0

    def start_loop(self) -> None:
        self.loop_begin = time.perf_counter()
        self.compile_before_loop = self.compile_seconds

    def close(self) -> None:
        self._event.unregister("numba:compile", self._timer)

    def after_first_step(self, on_step):
        """`on_step`, stopping the compile helper (jit_warm) once the first step has run: every
        kernel of the step is compiled or loaded by then, and the stepping gets both cores."""
        def wrapped(s):
            if self.helper is not None:
                from . import jit_warm
                jit_warm.stop(self.helper)
                self.helper = None
            on_step(s)
        return wrapped

    def split(self, loop_seconds: float, render_wait: float) -> dict:
        """total = setup + compile + stepping + waiting for renders (seconds)."""
        total = time.perf_counter() - self.begin
        before = (self.loop_begin or self.begin) - self.begin
        compile_loop = self.compile_seconds - self.compile_before_loop
        return {"total": total, "setup": max(before - self.compile_before_loop, 0.0),
                "compile": self.compile_seconds,
                "stepping": max(loop_seconds - compile_loop - render_wait, 0.0), "renders": render_wait}


def run(scene: Scene, opts: RunOptions) -> int:
    """Run `scene` into `opts.out_dir`; returns the exit code (errors before the run raise)."""
    clock = RunClock(opts.started)
    try:
        return _checked_run(scene, opts, clock)
    finally:
        clock.close()


def _checked_run(scene: Scene, opts: RunOptions, clock: RunClock) -> int:
    out = opts.out_dir
    check_output_folder(out, opts.overwrite, opts.resume)
    resume = _load_resume(out, scene) if opts.resume else None
    if resume is None:
        n_fluid = check_size(scene, opts.max_particles)  # first: it also runs the mesh checks (open, zero volume)
        check_geometry(scene)
        from . import estimate
        threads = opts.threads or int(os.environ.get("NUMBA_NUM_THREADS", 0)) or len(os.sched_getaffinity(0))
        estimate.announce(scene, n_fluid, threads, yes=opts.yes,
                          interactive=sys.stdin.isatty() and sys.stderr.isatty(),
                          log=lambda line: print(line, file=sys.stderr))
    renderer = None
    if opts.render and scene.render.enabled:
        check_render_size(scene)
    prepare_output_folder(out, opts.overwrite, opts.resume)  # every check passed: now create/clear
    if opts.render and scene.render.enabled:  # start it now: it imports VTK while we sample
        from .render_worker import BackgroundRenderer
        renderer = BackgroundRenderer()
    surfacer = None
    wants = scene.output.surface or (scene.render.enabled and opts.render and scene.render.mode == "surface")
    if wants if opts.surface is None else opts.surface:  # start it now: it imports splashsurf while we sample
        from .surface_worker import BackgroundSurfacer
        surfacer = BackgroundSurfacer()
    from . import jit_warm
    clock.helper = jit_warm.start(scene.method.value)  # cold Numba cache: compile on the other core too
    try:
        return _run(scene, opts, resume, renderer, clock, surfacer)
    except BaseException:
        for worker in (renderer, surfacer):
            if worker is not None:
                worker.terminate()
        raise
    finally:
        jit_warm.stop(clock.helper)


def _run(scene: Scene, opts: RunOptions, resume, renderer, clock: RunClock, surfacer=None) -> int:
    from .scene import scene_to_dict
    out = opts.out_dir
    import numba
    if opts.threads:
        numba.set_num_threads(int(opts.threads))
    for w in scene.warnings:
        print(f"ipsph: warning: {w}", file=sys.stderr)
    t_setup = time.perf_counter()
    if resume is None:
        fluid_x, fluid_v, boundary_x, notes = sample_scene(scene)
        for note in notes:
            print(f"ipsph: note: {note}", file=sys.stderr)
        if len(fluid_x) == 0:
            from .errors import ConfigError
            raise ConfigError("the scene has no fluid particles after sampling (check [[fluid]] entries and "
                              "that the fluid lies inside its container)")
        sim = Simulation(scene, fluid_x, fluid_v, boundary_x)
    else:
        sim = ckpt.restore(scene, resume)
        fluid_x, boundary_x, notes = sim.positions, sim.boundary.x, []
        threads = int(resume.scalars["threads"])
        if threads != numba.get_num_threads():
            print(f"ipsph: note: resuming with {numba.get_num_threads()} threads, the checkpoint was written with "
                  f"{threads}: pass --threads {threads} for a continuation bit-identical to an uninterrupted run",
                  file=sys.stderr)
    lo = np.minimum(fluid_x.min(axis=0), boundary_x.min(axis=0)) if len(boundary_x) else fluid_x.min(axis=0)
    hi = np.maximum(fluid_x.max(axis=0), boundary_x.max(axis=0)) if len(boundary_x) else fluid_x.max(axis=0)
    info = {"scene": scene_to_dict(scene), "scene_file": str(scene.source) if scene.source else None,
            "method": scene.method.value, "status": "running", "completed": False, "exit_code": None,
            "particle_radius": scene.particle_radius, "fluid_particles": sim.n_fluid,
            "boundary_particles": sim.n_boundary, "wall_fit": sim.boundary.fit_report,
            "domain_bounds": [float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), float(lo[2]), float(hi[2])],
            "frames": 0, "steps": 0, "sim_time": 0.0, "wall_seconds": None, "threads": numba.get_num_threads(),
            "notes": notes, "warnings": list(scene.warnings), "versions": out_io.provenance.versions(),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if resume is not None:
        now = info["started"]
        info.update(_previous_info(out))
        info["resumed"] = info.get("resumed", []) + [{"time": resume.time, "step": resume.steps, "at": now}]
    progress = (sys.stderr.isatty() or "log") if opts.progress is None else opts.progress
    folder = OutputFolder(out, sim, scene, info, renderer, progress, resume, surfacer)
    info["setup_seconds"] = time.perf_counter() - t_setup
    _write_info(out, info, sim, folder)
    old = {s: signal.signal(s, _on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    _STOP["signal"] = None
    code, status = EXIT_OK, "completed"
    clock.start_loop()
    t0 = time.perf_counter()
    try:
        try:
            sim.run(on_frame=folder.frame, on_step=clock.after_first_step(folder.step))
        except Interrupted:
            code, status = EXIT_INTERRUPTED, "interrupted"
            folder.frame(sim, -1)  # the final frame at the interrupt time
            folder.checkpoint(sim)
            print(f"\nipsph: interrupted at t = {sim.time:.4g} s (step {sim.steps}); {folder.frames} frames are "
                  f"in {out}; continue with the same command and --resume", file=sys.stderr)
    except NumericalFailure as exc:
        code, status = exc.exit_code, "failed"
        info["error"] = str(exc)
        print(f"\nipsph: error: {exc}; {folder.frames} finished frames are kept in {out}", file=sys.stderr)
    except IpsphError as exc:  # WriteError (disk full, ...): the .pvd still lists only complete frames
        code, status = exc.exit_code, "failed"
        info["error"] = str(exc)
        print(f"\nipsph: error: {exc}; the {folder.frames} frames listed in {out / out_io.RUN_PVD} are intact",
              file=sys.stderr)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        folder.close(interrupted=status == "interrupted")
        info.update(status=status, completed=status == "completed", exit_code=code,
                    wall_seconds=time.perf_counter() - t0, finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        info["time_split_seconds"] = clock.split(info["wall_seconds"], folder.render_seconds)
        info["compile_seconds"] = info["time_split_seconds"]["compile"]
        try:
            _write_info(out, info, sim, folder)
            paraview.write_view_script(out)
        except IpsphError as exc:  # e.g. the disk is still full: say so, keep the run's exit code
            print(f"ipsph: warning: {exc}", file=sys.stderr)
    if status == "completed" and progress is not None:
        _summary(out, sim, folder, info)
    rng = (info.get("render") or {}).get("speed_range")
    if rng and info["render"].get("enabled") and folder.max_speed > 1.05 * rng[1]:
        print(f"ipsph: note: the fluid reached {folder.max_speed:.2f} m/s, above the renders' colour range "
              f"{rng[0]:g}-{rng[1]:.2f} m/s (faster particles are white); `ipsph render {out} --speed-range 0 "
              f"{math.ceil(folder.max_speed * 10) / 10:g}` re-renders with the full range", file=sys.stderr)
    if folder.solver_maxed and status != "failed":
        print(f"ipsph: warning: {folder.solver_maxed} solves stopped at their iteration cap before reaching the "
              f"tolerance (run.json solver_maxed, stats.csv solver_maxed); raise solver.*.max_iterations / "
              f"max_passes or lower the time step", file=sys.stderr)
    return code


def _load_resume(out: Path, scene: Scene) -> ckpt.Checkpoint:
    """The checkpoint of the run in `out`, checked against `scene` (exit 2 when it does not fit)."""
    ck = ckpt.load(out / ckpt.CHECKPOINT_FILE)
    ckpt.check_compatible(ck, scene)
    if ck.time >= scene.end_time * (1.0 - 1e-12):
        raise OutputError(f"--resume: the checkpoint in {out} is at t = {ck.time:.6g} s, at or past "
                          f"simulation.end_time = {scene.end_time:.6g} s; pass a later --end-time to continue")
    if not (out / out_io.RUN_PVD).is_file() or not (out / out_io.STATS_CSV).is_file():
        raise OutputError(f"--resume: {out} lacks {out_io.RUN_PVD} or {out_io.STATS_CSV} of the earlier run; "
                          f"start afresh with --overwrite")
    return ck


def _previous_info(out: Path) -> dict:
    """What a resumed run keeps from the earlier run.json: when it started, its resumes, its camera and colours."""
    try:
        old = out_io.provenance.read_run_json(out / out_io.RUN_JSON)
    except IpsphError:
        return {}
    keep = {k: old[k] for k in ("started", "resumed", "domain_bounds") if k in old}
    rng = (old.get("render") or {}).get("speed_range")
    if rng:
        keep["render_speed_range"] = tuple(rng)
    return keep


def _write_info(out: Path, info: dict, sim: Simulation, folder: OutputFolder) -> None:
    info.update(frames=folder.frames, steps=sim.steps, sim_time=sim.time, clamped_steps=sim.clamped_steps,
                solver_maxed=folder.solver_maxed,
                timings_ms={p: float(np.median(v)) for p, v in folder.timings.items()},
                render_seconds=folder.render_seconds, write_seconds=folder.write_seconds)
    out_io.provenance.write_run_json(out / out_io.RUN_JSON, info)


def _summary(out: Path, sim: Simulation, folder: OutputFolder, info: dict) -> None:
    sp = info["time_split_seconds"]
    per_sim = sp["stepping"] / sim.time if sim.time > 0 else math.nan
    renders = f", waiting for renders {sp['renders']:.1f} s" if folder.renderer is not None or sp["renders"] > 0.05 else ""
    print(f"ipsph: done: {info['method'].upper()}, {sim.n_fluid:,} fluid + {sim.n_boundary:,} boundary particles, "
          f"{sim.steps} steps to t = {sim.time:.3g} s, {folder.frames} frames in {out / out_io.RUN_PVD}"
          + (f"; {sim.clamped_steps} steps hit dt_min" if sim.clamped_steps else ""), file=sys.stderr)
    print(f"ipsph: {sp['total']:.1f} s in all: setup {sp['setup']:.1f} s, compile {sp['compile']:.1f} s, "
          f"stepping {sp['stepping']:.1f} s ({per_sim:.2f} s per simulated second){renders}", file=sys.stderr)
