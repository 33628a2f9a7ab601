"""The one module that imports numba-cuda (the `[cuda]` extra): everything else takes `cuda`
from here, so a move to its successor (numba-cuda-mlir) is a change to this file only.

    from ._cuda import cuda, SIMULATOR, device_function, unavailable

`unavailable(device)` says in one line what is missing (the extra, the driver, the device) or
returns None; it allocates nothing. With NUMBA_ENABLE_CUDASIM=1 (read by numba-cuda when it is
first imported) kernels run on numba-cuda's CPU simulator, which is how the tests run this backend.

`device_function(f)` turns one of the `@njit` bodies of `bodies` into what a kernel calls: on a
GPU the njit function itself (numba-cuda compiles a CPU-jitted function called from a kernel as a
device function, with the same source), on the simulator its pure-Python twin, given the plain
arrays behind the simulator's wrappers (interpreting is faster there than compiling each body for
the CPU, and the source that runs is the same).
"""

from __future__ import annotations

import importlib.util
import os
import types

SIMULATOR = os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")
# small scenes launch small grids on purpose: no warning per launch (the user's setting wins)
os.environ.setdefault("NUMBA_CUDA_LOW_OCCUPANCY_WARNINGS", "0")
INSTALLED = importlib.util.find_spec("numba_cuda") is not None

if INSTALLED:
    from numba import cuda  # numba-cuda's redirect of numba.cuda (numba's own target is deprecated)
else:  # pragma: no cover - the extra is not installed
    cuda = None


def unavailable(device: int = 0) -> str | None:
    """None when a CUDA device `device` can be used (or the simulator is on), else why not."""
    if not INSTALLED:
        return "the CUDA backend needs numba-cuda: pip install 'ipsph[cuda]'"
    if SIMULATOR:
        return None
    try:
        if not cuda.is_available():
            return "no CUDA driver or GPU found (numba-cuda: cuda.is_available() is False)"
        n = len(cuda.gpus)
    except Exception as exc:  # a broken driver install raises here
        return f"the CUDA driver failed: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
    if not 0 <= device < n:
        return f"no CUDA device {device}: this machine has {n} (use --device 0..{n - 1})"
    return None


def select(device: int) -> None:
    """Make `device` the current one (a no-op on the simulator)."""
    if not SIMULATOR:
        cuda.select_device(device)


# -- bodies as device functions ---------------------------------------------------------------------
_TWINS: dict = {}


def _python_twin(f):
    """The pure-Python version of an @njit function, its calls to other @njit functions included."""
    py = getattr(f, "py_func", None)
    if py is None:
        return f
    if f in _TWINS:
        return _TWINS[f]
    g = dict(py.__globals__)
    twin = types.FunctionType(py.__code__, g, py.__name__, py.__defaults__, py.__closure__)
    _TWINS[f] = twin
    for name, value in py.__globals__.items():
        if getattr(value, "py_func", None) is not None:
            g[name] = _python_twin(value)
    return twin


def _plain(a):
    """The numpy array behind a simulator kernel argument (anything else as it is)."""
    item = getattr(a, "_item", None)
    return getattr(item, "_ary", a) if item is not None else a


def device_function(f):
    """What a kernel calls for the @njit body f (see the module docstring)."""
    if not SIMULATOR:
        return f
    twin = _python_twin(f)

    def call(*args):
        return twin(*[_plain(a) for a in args])

    call.__name__ = f.py_func.__name__
    return call
