"""What a run keeps beside its time loop: where its wall time goes (`RunClock`: compilation apart
from stepping, the compile helper stopped after the first step) and the signals that stop it
(`StopOnSignal`, `Interrupted`).
"""

from __future__ import annotations

import signal
import time


class Interrupted(Exception):
    """SIGINT / SIGTERM arrived; the run stops after the current step."""


class StopOnSignal:
    """SIGINT / SIGTERM while inside: remember the signal (the run stops after the current step)."""

    def __init__(self):
        self.signal = None

    def __enter__(self):
        self._old = {s: signal.signal(s, self._note) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _note(self, signum, _frame):
        self.signal = signum

    def __exit__(self, *exc):
        for s, h in self._old.items():
            signal.signal(s, h)
        return False


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
        return {
            "total": total,
            "setup": max(before - self.compile_before_loop, 0.0),
            "compile": self.compile_seconds,
            "stepping": max(loop_seconds - compile_loop - render_wait, 0.0),
            "renders": render_wait,
        }
