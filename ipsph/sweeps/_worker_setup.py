"""Dask worker preload of the sweep's LocalCluster: a terminal's Ctrl-C is for the sweep, not its workers.

Ctrl-C sends SIGINT to the whole foreground process group, which holds the LocalCluster's worker
processes too; a worker that died of it would have its member rescheduled instead of stopped.
The workers ignore SIGINT, and the sweep's client stops their members (member.stop_members)."""

import signal
import threading


def dask_setup(worker=None):
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    else:  # pragma: no cover - Dask runs preloads on the worker's main thread
        raise RuntimeError("ipsph sweep: the worker preload did not run on the main thread")
