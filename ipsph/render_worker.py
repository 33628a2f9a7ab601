"""Renders during a run, in a child process, so the solver never waits for OpenGL.

The runner hands each frame's positions and velocities to `BackgroundRenderer.submit`; a
spawned child (lower CPU priority, its own `FrameRenderer`) turns them into PNGs while the
solver carries on, using the time the solver's threads leave idle. The queue is bounded, so a
slow renderer holds back the solver instead of filling memory. A crash of the GL stack in the
child (llvmpipe, EGL) costs the renders, never the simulation: the parent reports it in one
line and carries on without them.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import queue as queue_mod
from pathlib import Path

import numpy as np

QUEUE_FRAMES = 6      # frames in flight before submit() blocks
NICENESS = 5          # the solver keeps priority over the renderer


def _worker(jobs, results, config, bounds, radius, speed_range, surface_file, title):
    # one llvmpipe thread: the solver has the cores; llvmpipe's own threads cost more CPU than they save
    os.environ.setdefault("LP_NUM_THREADS", "1")
    try:
        os.nice(NICENESS)
    except OSError:  # pragma: no cover - not permitted on some systems
        pass
    from .render import FrameRenderer
    surface = None
    if surface_file is not None and Path(surface_file).is_file():
        import pyvista as pv
        surface = pv.read(surface_file)
    try:
        with FrameRenderer(config, bounds, radius, speed_range, surface, title=title) as renderer:
            while True:
                job = jobs.get()
                if job is None:
                    break
                points, velocities, png, time = job
                renderer.render(points, velocities, png, time=time)
                results.put(("ok", str(png)))
    except Exception as exc:  # reported by the parent as one warning line
        results.put(("error", f"{type(exc).__name__}: {' '.join(str(exc).split())}"))


class BackgroundRenderer:
    """A render worker process fed with frames; `close()` waits for the frames in flight."""

    def __init__(self, config, bounds, radius, speed_range, surface_file=None, title=None):
        ctx = mp.get_context("spawn")  # a fresh interpreter: no forked numba/OpenMP threads
        self._jobs = ctx.Queue(maxsize=QUEUE_FRAMES)
        self._results = ctx.Queue()
        self._proc = ctx.Process(target=_worker, daemon=True, name="ipsph-render",
                                 args=(self._jobs, self._results, config, list(bounds), float(radius),
                                       tuple(speed_range), None if surface_file is None else str(surface_file),
                                       title))
        self._proc.start()
        self.rendered = 0
        self.error: str | None = None

    def _drain(self) -> None:
        while True:
            try:
                status, what = self._results.get_nowait()
            except queue_mod.Empty:
                return
            if status == "ok":
                self.rendered += 1
            else:
                self.error = what

    @property
    def alive(self) -> bool:
        self._drain()
        return self.error is None and self._proc.is_alive()

    def submit(self, points: np.ndarray, velocities: np.ndarray, png: Path, time: float) -> bool:
        """Queue one frame (copied as float32); False once the worker has failed."""
        if not self.alive:
            return False
        job = (np.asarray(points, dtype=np.float32), np.asarray(velocities, dtype=np.float32), Path(png),
               float(time))
        while True:
            try:
                self._jobs.put(job, timeout=1.0)
                return True
            except queue_mod.Full:
                if not self.alive:
                    return False

    def close(self, timeout: float | None = None) -> None:
        """Let the worker finish the frames in flight, then stop it."""
        if self._proc.is_alive():
            try:
                self._jobs.put(None, timeout=5.0)
            except queue_mod.Full:
                pass
            self._proc.join(timeout)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        self._drain()
        if self.error is None and self._proc.exitcode not in (0, None):
            self.error = f"the render process ended with exit code {self._proc.exitcode}"

    def terminate(self) -> None:
        """Stop at once (interrupt): frames still queued are dropped."""
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        self._drain()
