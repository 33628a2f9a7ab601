"""Surface meshes during a run, in a child process beside the solver (like the renders).

The runner writes each particle frame first and then hands its positions and velocities to
`BackgroundSurfacer.submit`; a spawned child at the lowest CPU priority reconstructs the surface
(`ipsph.post.surface`) and writes OUT/surfaces/surface_NNNNNN.vtp atomically, using the cycles the
solver leaves idle. The solver never waits for a surface: when the frames in flight fill the
queue (QUEUE_BYTES, as for renders), that frame's surface is skipped and listed as missing
(`ipsph surface OUT` makes it later). A frame whose reconstruction fails is one warning line; a
crash of the child costs the surfaces, never the run. `collect()` returns the surfaces written
since the last call, so the runner lists them in run.pvd (and renders them in surface mode).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue as queue_mod
import time as _time
from pathlib import Path

import numpy as np

from .render.worker import DRAIN_NOTICE_S, NICENESS, QUEUE_BYTES, QUEUE_FRAMES


def _worker(jobs, results):
    try:
        os.nice(NICENESS)
    except OSError:  # pragma: no cover - not permitted on some systems
        pass
    try:
        setup = jobs.get()
        if setup is None:
            return
        out, radius, rho0, config, clip, threads = setup
        from ..io import surface_file
        from . import surface

        surface.set_threads(threads)
        while True:
            job = jobs.get()
            if job is None:
                break
            index, time, points, velocities = job
            name = surface_file(index, "vtp")
            try:
                s = surface.reconstruct(points, velocities, radius, rho0, config, clip)
                surface.write_surface(Path(out) / name, s, "vtp", time=time)
            except surface.SurfaceFailed as exc:
                results.put(("failed", index, time, str(exc)))
                continue
            except Exception as exc:  # e.g. a WriteError (disk full): this frame fails, the next may not
                results.put(("failed", index, time, f"{type(exc).__name__}: {' '.join(str(exc).split())}"))
                continue
            results.put(("ok", index, time, name, s.seconds, len(s.triangles)))
        import resource

        use = resource.getrusage(resource.RUSAGE_SELF)
        results.put(("done", -1, 0.0, use.ru_utime + use.ru_stime))
    except Exception as exc:  # reported by the parent as one warning line
        results.put(("error", -1, 0.0, f"{type(exc).__name__}: {' '.join(str(exc).split())}"))


class BackgroundSurfacer:
    """A surface process fed with frames; start it early, `configure()` once, then `submit()` per frame."""

    def __init__(self):
        ctx = mp.get_context("spawn")  # a fresh interpreter: no forked numba/OpenMP threads
        self._jobs = ctx.Queue()
        self._results = ctx.Queue()
        self._proc = ctx.Process(target=_worker, daemon=True, name="ipsph-surface", args=(self._jobs, self._results))
        self._proc.start()
        self.submitted = 0
        self.finished = 0
        self.written: dict[int, str] = {}  # frame index -> surface file (relative to OUT)
        self.missing: dict[int, str] = {}  # frame index -> why it has no surface
        self.seconds = 0.0  # reconstruction time in the child, summed
        self.cpu_seconds = None  # the child's CPU time, reported when it ends
        self.error: str | None = None
        self._pending: dict[int, float] = {}  # submitted, not reported yet: index -> time
        self._done: list[tuple[int, float, str]] = []

    def configure(
        self, out: Path, radius: float, rho0: float, config, clip_bounds=None, threads: int | None = None
    ) -> None:
        """Where to write, the fluid, the [surface] settings, the containers' box (ipsph.post.surface.reconstruct)."""
        self._jobs.put((str(out), float(radius), float(rho0), config, clip_bounds, threads))

    def _drain(self, log) -> None:
        while True:
            try:
                status, index, time, *rest = self._results.get_nowait()
            except queue_mod.Empty:
                break
            if status == "error":
                self.error = rest[0]
                continue
            if status == "done":  # the child's CPU seconds over its life: imports and every surface
                self.cpu_seconds = rest[0]
                continue
            self.finished += 1
            self._pending.pop(index, None)
            if status == "ok":
                name, secs, _ = rest
                self.written[index] = name
                self.seconds += secs
                self._done.append((index, time, name))
            else:
                self.missing[index] = rest[0]
                log(f"ipsph: warning: frame {index} (t = {time:.4g} s) has no surface: {rest[0]}")
        if self.error is None and not self._proc.is_alive() and self._proc.exitcode not in (0, None):
            self.error = f"the surface process ended with exit code {self._proc.exitcode}"

    def _failed(self, log) -> None:
        for index in self._pending:
            self.missing[index] = f"the surface process stopped ({self.error})"
        if self._pending:
            log(f"ipsph: warning: surfaces stopped ({self.error}); the simulation carries on")
        self._pending.clear()

    def submit(self, index: int, time: float, points: np.ndarray, velocities: np.ndarray | None, log) -> None:
        """Queue frame `index` (copied as float32), or skip its surface when the queue is full."""
        self._drain(log)
        if self.error is not None:
            self.missing[index] = f"the surface process stopped ({self.error})"
            return
        job = (
            int(index),
            float(time),
            np.asarray(points, dtype=np.float32),
            None if velocities is None else np.asarray(velocities, dtype=np.float32),
        )
        frame_bytes = max(job[2].nbytes + (0 if job[3] is None else job[3].nbytes), 1)
        capacity = min(max(QUEUE_BYTES // frame_bytes, QUEUE_FRAMES[0]), QUEUE_FRAMES[1])
        if len(self._pending) >= capacity:
            self.missing[index] = "skipped: the surface process was behind (the solver never waits for it)"
            return
        self._jobs.put(job)
        self._pending[int(index)] = float(time)
        self.submitted += 1

    def collect(self, log) -> list[tuple[int, float, str]]:
        """Surfaces written since the last call: (frame index, time, file relative to OUT)."""
        self._drain(log)
        if self.error is not None:
            self._failed(log)
        done, self._done = self._done, []
        return done

    @property
    def backlog(self) -> int:
        return len(self._pending)

    def close(self, log, notice=None) -> None:
        """Let the child finish the frames in flight (at normal priority where permitted), then stop it."""
        if self._proc.is_alive():
            self._jobs.put(None)
            try:
                os.setpriority(os.PRIO_PROCESS, self._proc.pid, 0)
            except OSError:
                pass
            t0 = _time.perf_counter()
            while self._proc.is_alive():
                self._proc.join(0.25)
                self._drain(log)
                if notice is not None and _time.perf_counter() - t0 > DRAIN_NOTICE_S and self._pending:
                    notice(len(self._pending))
                    notice = None
        self._drain(log)
        if self._pending:  # the child ended without reporting them
            self.error = self.error or f"the surface process ended with exit code {self._proc.exitcode}"
            self._failed(log)

    def terminate(self, why: str = "interrupted") -> None:
        """Stop at once: frames still queued get no surface."""
        self._jobs.cancel_join_thread()
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        for index in self._pending:
            self.missing[index] = why
        self._pending.clear()

    def finish(self, out: Path, frames: int, log) -> None:
        """The end of a run: wait for the frames in flight (Ctrl-C skips them), then one line listing the
        frames without a surface (`collect()` still returns the last surfaces written)."""
        try:
            self.close(
                log,
                notice=lambda n: log(
                    f"ipsph: reconstructing the surfaces of the last {n} frames "
                    f"(Ctrl-C skips them; `ipsph surface {out}` makes them later)"
                ),
            )
        except KeyboardInterrupt:
            self.terminate("interrupted after the run; `ipsph surface` makes it")
        if self.missing:
            listed = ", ".join(str(k) for k in sorted(self.missing)[:20]) + (" ..." if len(self.missing) > 20 else "")
            log(
                f"ipsph: warning: {len(self.missing)} of {frames} frames have no surface (frames {listed}; reasons "
                f"in run.json surface.missing); `ipsph surface {out}` makes those it can"
            )

    def summary(self) -> dict:
        """For run.json: counts, the child's reconstruction seconds, and the frames without a surface."""
        return {
            "enabled": True,
            "written": len(self.written),
            "reconstruction_seconds": self.seconds,
            "process_cpu_seconds": self.cpu_seconds,
            "missing": {str(k): v for k, v in sorted(self.missing.items())},
        }
