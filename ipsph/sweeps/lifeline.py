"""A member's `ipsph run`, tied to the life of the process that started it.

A member runs as `python -m ipsph run ...`, a child of its Dask task, with IPSPH_SWEEP_PARENT set
to the task's pid; `ipsph.__main__` calls `die_with_parent` first. That asks Linux to send it
SIGTERM when its parent dies (prctl PR_SET_PDEATHSIG): a worker that is killed mid-member takes
its member down the way Ctrl-C does (the current step finishes, a final frame and a checkpoint
are written), so the rerun on another worker continues from that checkpoint, and no orphaned
simulation goes on writing into the folder. Then it is exactly `ipsph run`.
"""

from __future__ import annotations

import os
import signal
import sys

PARENT_ENV = "IPSPH_SWEEP_PARENT"  # set by member.py for its child


def _die_with_parent(parent: int) -> None:
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before prctl took effect
        os.kill(os.getpid(), signal.SIGTERM)


def die_with_parent() -> None:
    """When IPSPH_SWEEP_PARENT names this process's parent: die (SIGTERM) when that parent dies."""
    want = os.environ.get(PARENT_ENV)
    if want and want.isdigit():
        _die_with_parent(int(want))
