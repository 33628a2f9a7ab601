"""`ipsph run`: one simulation writing a ParaView-ready output folder, and losing nothing.

Order of business: check the output folder, the particle budget and the radius against the
geometry (bad input exits 2 before any large allocation), sample the scene once (refusing one
with no fluid left; a refused run leaves no output folder), create the folder, write the
boundary once,
then per frame a VTU + the PVD (atomically) + a render (+ a checkpoint every
output.checkpoint_interval), per step a stats row. SIGINT/SIGTERM finish the current step,
write a final frame and a checkpoint and exit 130; a numerical failure stops with exit 3, a
failed write (disk full) with exit 4; run.json always says how the run ended. `--resume`
restores the checkpoint, drops frames and stats rows after it, and continues.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import io as out_io
from ..config import Scene
from ..errors import EXIT_INTERRUPTED, EXIT_OK, IpsphError, NumericalFailure, OutputError
from ..io import provenance
from ..io.prepare import check_output_folder, prepare_output_folder
from ..post import paraview
from ..sampling.scene import SampledScene, check_sampled, sample
from ..simulation import Simulation
from . import checkpoint as ckpt
from .clock import Interrupted, RunClock, StopOnSignal
from .folder import RunFolder
from .preflight import check_backend, check_geometry, check_render_size, check_size


@dataclass
class RunOptions:
    out_dir: Path
    render: bool = True
    overwrite: bool = False
    resume: bool = False
    threads: int | None = None
    max_particles: int | None = None
    progress: bool | None = None  # None: live on a TTY, else one line every PROGRESS_EVERY_S
    yes: bool = False  # run even when the estimate says hours and no one is at a terminal
    started: float | None = None  # time.perf_counter() when the process started (the CLI: its imports count)
    surface: bool | None = None  # None: the scene's output.surface (or render.mode = "surface")


def run(scene: Scene, opts: RunOptions) -> int:
    """Run `scene` into `opts.out_dir`; returns the exit code (errors before the run raise)."""
    clock = RunClock(opts.started)
    try:
        return _checked_run(scene, opts, clock)
    finally:
        clock.close()


def _checked_run(scene: Scene, opts: RunOptions, clock: RunClock) -> int:
    out = opts.out_dir
    check_backend(scene)
    check_output_folder(out, opts.overwrite, opts.resume)
    resume = _load_resume(out, scene) if opts.resume else None
    if resume is not None and scene.emitters:  # a later --end-time emits more: check the plan again
        from ..flow import check_resumed_capacity
        from ..sampling.budget import default_max_particles

        check_resumed_capacity(
            scene,
            len(resume.arrays["state.x"]),
            resume.scalars.get("flow"),
            opts.max_particles or default_max_particles(),
        )
    if resume is None:
        n_fluid = check_size(scene, opts.max_particles)  # first: it also runs the mesh checks (open, zero volume)
        check_geometry(scene)
        from ..gauges.placement import check_placement

        check_placement(scene)
        from . import estimate

        threads = opts.threads or int(os.environ.get("NUMBA_NUM_THREADS", 0)) or len(os.sched_getaffinity(0))
        if scene.backend == "cpu":  # the cost model is the CPU backend's (a GPU's is not measured yet)
            estimate.announce(
                scene,
                n_fluid,
                threads,
                yes=opts.yes,
                interactive=sys.stdin.isatty() and sys.stderr.isatty(),
                log=lambda line: print(line, file=sys.stderr),
            )
    renderer = None
    if opts.render and scene.render.enabled:
        check_render_size(scene)
        from ..post.render.worker import BackgroundRenderer

        renderer = BackgroundRenderer()  # start it now: it imports VTK while we sample
    surfacer = None
    wants = scene.output.surface or (scene.render.enabled and opts.render and scene.render.mode == "surface")
    if wants if opts.surface is None else opts.surface:  # start it now: it imports splashsurf while we sample
        from ..post.surface_worker import BackgroundSurfacer

        surfacer = BackgroundSurfacer()
    from . import jit_warm

    if scene.backend == "cpu":  # cold Numba cache: compile on the other core too
        clock.helper = jit_warm.start(jit_warm.run_kind(scene.method.value, scene.boundary_model))
    try:
        sampled = None
        if resume is None:
            sampled = _sample(scene, opts)  # the run's one sampling; refusals that need the particles
        prepare_output_folder(out, opts.overwrite, opts.resume)  # every check passed: now create/clear
        return _run(scene, opts, resume, sampled, renderer, clock, surfacer)
    except BaseException:
        for worker in (renderer, surfacer):
            if worker is not None:
                worker.terminate()
        raise
    finally:
        jit_warm.stop(clock.helper)


def _sample(scene: Scene, opts: RunOptions) -> SampledScene:
    """The scene's particles, sampled once, and the refusals only they can tell (before any output)."""
    import numba

    if opts.threads:
        numba.set_num_threads(int(opts.threads))
    for w in scene.warnings:
        print(f"ipsph: warning: {w}", file=sys.stderr)
    sampled = sample(scene)
    check_sampled(scene, sampled)
    for note in sampled.notes:
        print(f"ipsph: note: {note}", file=sys.stderr)
    return sampled


def _run(scene: Scene, opts: RunOptions, resume, sampled, renderer, clock: RunClock, surfacer=None) -> int:
    from ..scene import scene_to_dict

    out = opts.out_dir
    import numba

    if opts.threads:
        numba.set_num_threads(int(opts.threads))
    if resume is not None:
        for w in scene.warnings:
            print(f"ipsph: warning: {w}", file=sys.stderr)
    t_setup = time.perf_counter() - (sampled.seconds if sampled is not None else 0.0)
    if resume is None:
        fluid_x, fluid_v, boundary_x, notes = sampled.fluid_x, sampled.fluid_v, sampled.boundary_x, sampled.notes
        sim = Simulation(scene, fluid_x, fluid_v, boundary_x, wall_counts=sampled.wall_counts)
        if sim.settle_report:
            st = sim.settle_report
            notes.append(
                f"settled before t = 0 (simulation.settle = {scene.settle}): {st['steps']} steps, particles "
                f"moved {st['moved_mean_r']:.2f} r on average (at most {st['moved_max_r']:.2f} r)"
                + ("" if st["converged"] else f", still at {st['max_speed']:.3g} m/s")
            )
            print(f"ipsph: note: {notes[-1]}", file=sys.stderr)
    else:
        sim = ckpt.restore(scene, resume)
        fluid_x, boundary_x, notes = sim.positions, sim.boundary.x, []
        threads = int(resume.scalars["threads"])
        if threads != numba.get_num_threads():
            print(
                f"ipsph: note: resuming with {numba.get_num_threads()} threads, the checkpoint was written with "
                f"{threads}: pass --threads {threads} for a continuation bit-identical to an uninterrupted run",
                file=sys.stderr,
            )
    from ..flow import extent_points

    pts = np.concatenate([fluid_x, boundary_x, extent_points(scene)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    info = {
        "scene": scene_to_dict(scene),
        "scene_file": str(scene.source) if scene.source else None,
        "method": scene.method.value,
        "backend": scene.backend,
        "precision": scene.precision,
        "status": "running",
        "completed": False,
        "exit_code": None,
        "particle_radius": scene.particle_radius,
        "fluid_particles": sim.n_fluid,
        "boundary_particles": sim.n_boundary,
        "wall_fit": sim.boundary.fit_report,
        "settle": sim.settle_report,
        "domain_bounds": [float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), float(lo[2]), float(hi[2])],
        "frames": 0,
        "steps": 0,
        "sim_time": 0.0,
        "wall_seconds": None,
        "threads": numba.get_num_threads(),
        "notes": notes,
        "warnings": list(scene.warnings),
        "versions": provenance.versions(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    if resume is not None:
        now = info["started"]
        info.update(_previous_info(out))
        info["resumed"] = info.get("resumed", []) + [{"time": resume.time, "step": resume.steps, "at": now}]
    progress = (sys.stderr.isatty() or "log") if opts.progress is None else opts.progress
    folder = RunFolder(out, sim, scene, info, renderer, progress, resume, surfacer)
    info["setup_seconds"] = time.perf_counter() - t_setup
    _write_info(out, info, sim, folder)
    code, status = EXIT_OK, "completed"
    clock.start_loop()
    t0 = time.perf_counter()
    try:
        with StopOnSignal() as stop:  # handlers restored before folder.close(): Ctrl-C there skips renders
            folder.stopping = lambda: stop.signal is not None

            def on_step(s):
                folder.step(s)
                if stop.signal:
                    raise Interrupted()

            try:
                sim.run(on_frame=folder.frame, on_step=clock.after_first_step(on_step))
            except Interrupted:
                code, status = EXIT_INTERRUPTED, "interrupted"
                folder.frame(sim, -1)  # the final frame at the interrupt time
                folder.checkpoint(sim)
                print(
                    f"\nipsph: interrupted at t = {sim.time:.4g} s (step {sim.steps}); {folder.frames} frames are "
                    f"in {out}; continue with the same command and --resume",
                    file=sys.stderr,
                )
    except NumericalFailure as exc:
        code, status = exc.exit_code, "failed"
        info["error"] = str(exc)
        print(f"\nipsph: error: {exc}; {folder.frames} finished frames are kept in {out}", file=sys.stderr)
    except IpsphError as exc:  # WriteError (disk full, ...): the .pvd still lists only complete frames
        code, status = exc.exit_code, "failed"
        info["error"] = str(exc)
        print(
            f"\nipsph: error: {exc}; the {folder.frames} frames listed in {out / out_io.RUN_PVD} are intact",
            file=sys.stderr,
        )
    finally:
        folder.close(interrupted=status == "interrupted")
        info.update(
            status=status,
            completed=status == "completed",
            exit_code=code,
            wall_seconds=time.perf_counter() - t0,
            finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )
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
        print(
            f"ipsph: note: the fluid reached {folder.max_speed:.2f} m/s, above the renders' colour range "
            f"{rng[0]:g}-{rng[1]:.2f} m/s (faster particles are white); `ipsph render {out} --speed-range 0 "
            f"{math.ceil(folder.max_speed * 10) / 10:g}` re-renders with the full range",
            file=sys.stderr,
        )
    if folder.solver_maxed and status != "failed":
        print(
            f"ipsph: warning: {folder.solver_maxed} solves stopped at their iteration cap before reaching the "
            f"tolerance (run.json solver_maxed, stats.csv solver_maxed); raise solver.*.max_iterations / "
            f"max_passes or lower the time step",
            file=sys.stderr,
        )
    return code


def _load_resume(out: Path, scene: Scene) -> ckpt.Checkpoint:
    """The checkpoint of the run in `out`, checked against `scene` (exit 2 when it does not fit)."""
    ck = ckpt.load(out / out_io.CHECKPOINT_FILE)
    ckpt.check_compatible(ck, scene)
    if ck.time >= scene.end_time * (1.0 - 1e-12):
        raise OutputError(
            f"--resume: the checkpoint in {out} is at t = {ck.time:.6g} s, at or past "
            f"simulation.end_time = {scene.end_time:.6g} s; pass a later --end-time to continue"
        )
    if not (out / out_io.RUN_PVD).is_file() or not (out / out_io.STATS_CSV).is_file():
        raise OutputError(
            f"--resume: {out} lacks {out_io.RUN_PVD} or {out_io.STATS_CSV} of the earlier run; "
            f"start afresh with --overwrite"
        )
    if scene.gauges and not (out / out_io.GAUGES_CSV).is_file():
        raise OutputError(
            f"--resume: {out} lacks {out_io.GAUGES_CSV} of the earlier run; start afresh with --overwrite"
        )
    return ck


def _previous_info(out: Path) -> dict:
    """What a resumed run keeps from the earlier run.json: when it started, its resumes, its camera and colours."""
    try:
        old = provenance.read_run_json(out / out_io.RUN_JSON)
    except IpsphError:
        return {}
    keep = {
        k: old[k] for k in ("started", "resumed", "domain_bounds", "fluid_particles") if k in old
    }  # the count at t = 0
    rng = (old.get("render") or {}).get("speed_range")
    if rng:
        keep["render_speed_range"] = tuple(rng)
    return keep


def _write_info(out: Path, info: dict, sim: Simulation, folder: RunFolder) -> None:
    info.update(
        frames=folder.frames,
        steps=sim.steps,
        sim_time=sim.time,
        clamped_steps=sim.clamped_steps,
        solver_maxed=folder.solver_maxed,
        timings_ms={p: float(np.median(v)) for p, v in folder.timings.items()},
        render_seconds=folder.render_seconds,
        write_seconds=folder.write_seconds,
    )
    if sim.flow is not None:  # emitted / removed totals, ids (docs/output-format.md)
        info.update(flow=sim.flow.summary(), fluid_particles_now=sim.n_fluid)
    provenance.write_run_json(out / out_io.RUN_JSON, info)


def _summary(out: Path, sim: Simulation, folder: RunFolder, info: dict) -> None:
    sp = info["time_split_seconds"]
    per_sim = sp["stepping"] / sim.time if sim.time > 0 else math.nan
    renders = (
        f", waiting for renders {sp['renders']:.1f} s" if folder.renderer is not None or sp["renders"] > 0.05 else ""
    )
    print(
        f"ipsph: done: {info['method'].upper()}, {sim.n_fluid:,} fluid + {sim.n_boundary:,} boundary particles, "
        f"{sim.steps} steps to t = {sim.time:.3g} s, {folder.frames} frames in {out / out_io.RUN_PVD}"
        + (f"; {sim.clamped_steps} steps hit dt_min" if sim.clamped_steps else ""),
        file=sys.stderr,
    )
    print(
        f"ipsph: {sp['total']:.1f} s in all: setup {sp['setup']:.1f} s, compile {sp['compile']:.1f} s, "
        f"stepping {sp['stepping']:.1f} s ({per_sim:.2f} s per simulated second){renders}",
        file=sys.stderr,
    )
