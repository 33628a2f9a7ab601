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
import signal
import threading
import time as _time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

QUEUE_BYTES = 256 * 2**20  # frames in flight (24 B per particle) before submit() waits: the solver
QUEUE_FRAMES = (2, 256)  # runs ahead while the renderer starts or the machine is busy
NICENESS = 19  # lowest: renders use the cycles the solver leaves idle. At nice 5-10 the worker
# preempted solver threads mid parallel loop and the other thread spun at the barrier
# (default scene: x1.26 wall at nice 10, x1.08 at nice 19). On a machine busy with
# other jobs the renders fall behind; the solver runs ahead (QUEUE_BYTES) and the
# last frames render at normal priority where the OS permits raising it (`close`).
DRAIN_NOTICE_S = 2.0  # say what the run is waiting for when the last frames take longer


def _exit_with_parent(parent_pid: int, every_s: float = 1.0) -> None:
    """The worker ignores SIGINT (the run decides), so it must not outlive a run that died without
    stopping it (SIGKILL, a crash): a daemon thread exits the process once the parent is gone."""

    def watch():
        while os.getppid() == parent_pid:
            _time.sleep(every_s)
        os._exit(0)

    threading.Thread(target=watch, name="ipsph-render-watchdog", daemon=True).start()


def _worker(jobs, results, parent_pid=None):
    if parent_pid is not None:
        _exit_with_parent(parent_pid)
    # one llvmpipe thread: the solver has the cores; llvmpipe's own threads cost more CPU than they save
    os.environ.setdefault("LP_NUM_THREADS", "1")
    try:
        os.nice(NICENESS)
    except OSError:  # pragma: no cover - not permitted on some systems
        pass
    # VTK logs a failing GL stack over many lines; the parent reports the failure in one
    from vtkmodules.vtkCommonCore import vtkLogger, vtkObject

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    vtkObject.GlobalWarningDisplayOff()
    from ...io.vtu import read_surface
    from .frame import FrameRenderer
    from .png import save_png
    from .splat import warm_up

    warm_up()  # load the compiled kernels while the solver is still setting up
    try:
        setup = jobs.get()
        if setup is None:  # the run ended before its first frame
            return
        config, bounds, radius, speed_range, surface_file, title = setup
        surface = read_surface(surface_file) if surface_file is not None else None

        def write(img, png):
            save_png(img, png)
            results.put(("ok", str(png)))

        # A writer thread encodes frame k while frame k+1 is drawn: both mostly release the GIL,
        # so the last frames, rendered after the solver has finished, use both cores (default
        # scene: about half the frames are still queued then).
        with (
            FrameRenderer(config, bounds, radius, speed_range, surface, title=title) as renderer,
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="ipsph-png") as writer,
        ):
            renderer.prepare()  # the first GL use: a missing GL stack crashes here, before any frame
            results.put(("ready", ""))
            encoding = None
            while True:
                job = jobs.get()
                if job is None:
                    break
                if isinstance(job[0], str):  # render.mode = "surface": the frame's mesh from surfaces/
                    _, vtp, png, time = job
                    img = renderer.surface_image(read_surface(vtp), time=time)
                else:
                    points, velocities, png, time, moving = job
                    if moving is not None:
                        renderer.set_moving(read_surface(moving))
                    img = renderer.image(points, velocities, time=time)
                if encoding is not None:
                    encoding.result()  # one frame in the writer at a time; re-raises its error
                encoding = writer.submit(write, img, png)
            if encoding is not None:
                encoding.result()
    except Exception as exc:  # reported by the parent as one warning line
        results.put(("error", f"{type(exc).__name__}: {' '.join(str(exc).split())}"))


class BackgroundRenderer:
    """A render worker process fed with frames; `close()` waits for the frames in flight.

    Start it early (`BackgroundRenderer()`): the worker imports VTK and loads its kernels while
    the solver samples the scene; `configure()` then gives it the camera, colours and walls.
    """

    def __init__(self):
        ctx = mp.get_context("spawn")  # a fresh interpreter: no forked numba/OpenMP threads
        self._jobs = ctx.Queue()  # bounded in bytes by submit()
        self._results = ctx.Queue()
        self._proc = ctx.Process(
            target=_worker, daemon=True, name="ipsph-render", args=(self._jobs, self._results, os.getpid())
        )
        # Ctrl-C in a terminal signals the whole process group. The parent decides what the worker
        # does then (finish the frames in flight, or terminate() it), so the worker starts with
        # SIGINT ignored: an interpreter that starts so installs no KeyboardInterrupt handler, and
        # no traceback from the middle of a frame (or of its imports) reaches the terminal.
        ignore = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if ignore else None
        try:
            self._proc.start()
        finally:
            if ignore:
                signal.signal(signal.SIGINT, previous)
        self.rendered = 0
        self.submitted = 0
        self.ready = False  # the worker has its GL context and static layers
        self.error: str | None = None

    def configure(self, config, bounds, radius, speed_range, surface_file=None, title=None) -> None:
        """The series' render settings (once, before the first frame)."""
        self._jobs.put(
            (
                config,
                [float(b) for b in bounds],
                float(radius),
                tuple(float(v) for v in speed_range),
                None if surface_file is None else str(surface_file),
                title,
            )
        )

    def _drain(self) -> None:
        while True:
            try:
                status, what = self._results.get_nowait()
            except queue_mod.Empty:
                return
            if status == "ok":
                self.rendered += 1
            elif status == "ready":
                self.ready = True
            else:
                self.error = what

    def _check_exit(self) -> None:
        """A worker that died says why: a signal (a missing or broken GL stack segfaults in VTK)
        or an exit status."""
        code = self._proc.exitcode
        if self.error is not None or code in (0, None):
            return
        if code < 0:
            from .gl import GL_HINT

            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            self.error = f"the render process crashed ({name}); no usable GL/EGL stack? {GL_HINT}"
        else:
            self.error = f"the render process ended with exit code {code}"

    @property
    def alive(self) -> bool:
        self._drain()
        if not self._proc.is_alive():
            self._drain()
            self._check_exit()
        return self.error is None and self._proc.is_alive()

    @property
    def backlog(self) -> int:
        """Frames submitted and not rendered yet."""
        self._drain()
        return self.submitted - self.rendered

    def submit(
        self, points: np.ndarray, velocities: np.ndarray, png: Path, time: float, moving: Path | None = None
    ) -> bool:
        """Queue one frame (copied as float32); False once the worker has failed. Waits while the
        frames in flight fill QUEUE_BYTES, so a slow renderer holds the solver back, not memory.
        `moving`: the frame's moving-wall surfaces (OUT/bodies/*.vtp), drawn where they are."""
        if not self.alive:
            return False
        job = (
            np.asarray(points, dtype=np.float32),
            np.asarray(velocities, dtype=np.float32),
            Path(png),
            float(time),
            None if moving is None else str(moving),
        )
        frame_bytes = max(job[0].nbytes + job[1].nbytes, 1)
        capacity = min(max(QUEUE_BYTES // frame_bytes, QUEUE_FRAMES[0]), QUEUE_FRAMES[1])
        while self.backlog >= capacity:
            if not self.alive:
                return False
            _time.sleep(0.02)
        self._jobs.put(job)
        self.submitted += 1
        return True

    def submit_surface(self, vtp: Path, png: Path, time: float) -> bool:
        """Queue the render of a surface mesh the surface process wrote (render.mode = "surface")."""
        if not self.alive:
            return False
        self._jobs.put(("surface", str(vtp), Path(png), float(time)))
        self.submitted += 1
        return True

    def close(self, timeout: float | None = None, notice=None) -> None:
        """Let the worker finish the frames in flight, then stop it. `notice(backlog)` is called
        once if that takes longer than DRAIN_NOTICE_S."""
        if self._proc.is_alive():
            self._jobs.put(None)
            try:  # the solver is done: the last frames need not yield to it any more
                os.setpriority(os.PRIO_PROCESS, self._proc.pid, 0)
            except OSError:  # lowering niceness needs CAP_SYS_NICE or RLIMIT_NICE; then it stays
                pass
            t0 = _time.perf_counter()
            while self._proc.is_alive():
                self._proc.join(0.25)
                waited = _time.perf_counter() - t0
                if notice is not None and waited > DRAIN_NOTICE_S and self.backlog > 0:
                    notice(self.backlog)
                    notice = None
                if timeout is not None and waited > timeout:
                    break
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        self._drain()
        self._check_exit()

    def terminate(self) -> None:
        """Stop at once (interrupt, or the worker died): frames still queued are dropped."""
        self._jobs.cancel_join_thread()  # never block exit on frames nobody will read
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        self._drain()
