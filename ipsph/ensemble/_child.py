"""`python -m ipsph.ensemble._child run ...`: `ipsph run`, tied to the life of the process that started it.

A member runs as this child of its Dask task. Before anything else it asks Linux to send it
SIGTERM when its parent dies (prctl PR_SET_PDEATHSIG): a worker that is killed mid-member takes
its member down the way Ctrl-C does (the current step finishes, a final frame and a checkpoint
are written), so the rerun on another worker continues from that checkpoint, and no orphaned
simulation goes on writing into the folder. Then it is exactly `ipsph run` (`ipsph.cli.main`).
"""

from __future__ import annotations

import os
import signal
import sys


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


if __name__ == "__main__":
    want = os.environ.get("IPSPH_SWEEP_PARENT")
    if want and want.isdigit():
        _die_with_parent(int(want))
    from ipsph.cli import main

    sys.exit(main(sys.argv[1:]))
