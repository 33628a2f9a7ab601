"""The CUDA backend: particle arrays on an NVIDIA GPU, the passes of `cuda_passes` (the bodies of
`bodies` as device functions), fixed-order reductions (its neighbour search: `ipsph.neighbours.cuda`).

    be = get_backend("cuda", precision="float32", device=0)

State stays on the device from the first step to the last: host copies are made only for
frames, checkpoints, the step report's scalars (reductions) and the grid check of the neighbour
search (the fluid's bounding box). `precision` is the storage type of the real-valued
per-particle arrays (float64 or float32; docs/method.md, "Precision"); the bodies' arithmetic
is float64 either way (their scalars are float64), and integer arrays keep their types.

Without numba-cuda, a driver or the device, construction raises ConfigError naming what is
missing before anything is allocated; NUMBA_ENABLE_CUDASIM=1 runs it on numba-cuda's simulator.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..params import PRECISIONS
from . import _cuda
from .base import Backend


class CUDABackend(Backend):
    name = "cuda"

    def __init__(self, precision: str = "float64", device: int = 0):
        if precision not in PRECISIONS:
            raise ConfigError(f"simulation.precision = {precision!r}: use one of {', '.join(PRECISIONS)}")
        why = _cuda.unavailable(device)
        if why is not None:
            raise ConfigError(f"--backend cuda: {why}")
        _cuda.select(device)
        from . import cuda_passes as P

        self.P = P
        self.precision = precision
        self.device = device
        self.real = np.dtype(precision)
        from .cuda_reduce import Reducer

        self.reducer = Reducer()
        self.NO_PAIRS = self._new((0, 3, 0), self.real)
        self.NO_DISPLACEMENT = self._new((0, 3), self.real)
        self._every_particle = self._new((0,), self.real)
        self._walls: dict[int, tuple] = {}

    # -- arrays -------------------------------------------------------------------------------------
    def _dtype(self, dtype):
        """'float64' (every caller's default) means this backend's precision."""
        dt = np.dtype(dtype)
        return self.real if dt == np.float64 else dt

    def _new(self, shape, dtype):
        return self._allocate(lambda: _cuda.cuda.device_array(shape, dtype=dtype), shape, dtype)

    def _allocate(self, make, shape, dtype):
        """make() (a device allocation), with the GPU's out-of-memory error as one line (exit 2)."""
        try:
            return make()
        except Exception as exc:
            if "OUT_OF_MEMORY" not in str(exc).upper().replace(" ", "_"):
                raise
            mem = self.memory()
            have = f" ({mem[0] / 2**30:.1f} of {mem[1] / 2**30:.1f} GiB free)" if mem else ""
            size = int(np.prod(shape)) * np.dtype(dtype).itemsize
            raise ConfigError(
                f"the GPU (device {self.device}) is out of memory allocating {size / 2**20:.0f} MiB "
                f"for {shape[0]:,} particles{have}: use a larger simulation.particle_radius, "
                f'simulation.precision = "float32", or a GPU with more memory'
            ) from None

    @staticmethod
    def _flat(a):
        return a.reshape(a.size)

    def _launch(self, kernel, n, *args):
        if n:
            self.P.launch(kernel, n, *args)

    def zeros(self, n, shape=(), dtype="float64"):
        a = self._new((n, *shape), self._dtype(dtype))
        self._launch(self.P.fill, a.size, self._flat(a), 0)
        return a

    def empty(self, n, shape=(), dtype="float64"):
        return self._new((n, *shape), self._dtype(dtype))

    def asarray(self, host, dtype="float64"):
        a = np.ascontiguousarray(host, dtype=self._dtype(dtype))
        return self._allocate(lambda: _cuda.cuda.to_device(a), a.shape, a.dtype)

    def to_host(self, a):
        return a.copy_to_host()

    def pair_buffer(self, n, k):
        return self._new((n, 3, k), self.real)

    def _wall_arrays(self, walls):
        """The walls' positions, masses and velocities on the device, copied again whenever the
        Boundary replaced its arrays: a re-sort into a new grid, a checkpoint restore, and every
        neighbour search after moving walls moved (`NeighbourSearch._resort_walls` reorders them
        into new arrays; the walls move in place only before that search, when no pass runs)."""
        have = self._walls.get(id(walls))
        if have is None or have[0] is not walls.x or have[1] is not walls.m or have[2] is not walls.v:
            have = (walls.x, walls.m, walls.v, self.asarray(walls.x), self.asarray(walls.m), self.asarray(walls.v))
            self._walls[id(walls)] = have
        return have[3:]

    # -- vector operations --------------------------------------------------------------------------
    def fill(self, a, value):
        self._launch(self.P.fill, a.size, self._flat(a), value)

    def copy(self, dst, src):
        self._launch(self.P.copy, dst.size, self._flat(dst), self._flat(src))

    def axpy(self, y, alpha, x):
        self._launch(self.P.axpy, y.size, self._flat(y), alpha, self._flat(x))

    def scale(self, a, c):
        self._launch(self.P.scale, a.size, self._flat(a), c)

    @staticmethod
    def _rows(a):
        n = a.shape[0]
        return a.reshape(n, a.size // n if n else 1)

    def take(self, a, perm):
        """new[i] = a[perm[i]] for the len(perm) <= len(a) rows of perm (a permutation, or the
        ascending indices a compaction keeps)."""
        out = self._new((perm.shape[0], *a.shape[1:]), a.dtype)
        self._launch(self.P.take_rows, out.shape[0], self._rows(a), perm, self._rows(out))
        return out

    def concat(self, a, b):
        out = self._new((a.shape[0] + b.shape[0], *a.shape[1:]), a.dtype)
        na = a.shape[0]
        for part, lo, hi in ((a, 0, na), (b, na, out.shape[0])):
            if hi > lo:
                self._launch(self.P.copy, part.size, self._flat(out[lo:hi]), self._flat(part))
        return out

    def head(self, a, n):
        return a[:n]  # a device array's leading rows: a view of the same memory

    def untake(self, a, perm):
        old = self._new(a.shape, a.dtype)
        self.copy(old, a)
        self._launch(self.P.untake_rows, a.shape[0], self._rows(old), perm, self._rows(a))

    def mean(self, a):
        return self.reducer.sum(a) / max(a.shape[0], 1)

    def mean_positive(self, a):
        return self.reducer.sum(a, True) / max(a.shape[0], 1)

    def max(self, a):
        return self.reducer.max(a)

    def speed_energy(self, v, m):
        return self.reducer.speed_energy(v, m)

    def first_unhealthy(self, x, v, lo, hi):
        return self.reducer.first_unhealthy(x, v, lo, hi) if x.shape[0] else -1

    def pf_pressure(self, out, lam, rho0, dt):
        self._launch(self.P.pf_pressure, out.shape[0], out, lam, rho0, dt)

    def stiffness_pressure(self, out, k, rho, add=False):
        self._launch(self.P.stiffness_pressure, out.shape[0], out, k, rho, add)

    # -- per-particle passes (the table's kernels, built in cuda_passes) -------------------------------
    def launch_pass(self, p, nl, args):
        kernel = self.P.passes(nl.fluid.shape[1], nl.boundary.shape[1])[p.name] if p.rows else getattr(self.P, p.name)
        self._launch(kernel, args[p.inputs.index(p.over)].shape[0], *args)

    def wall_arrays(self, walls):
        return self._wall_arrays(walls)

    def _cpu_only(self, *args, **kwargs):
        raise NotImplementedError("field walls run on the CPU backend only (boundary.field_walls refuses others)")

    wall_field = wall_pressure = wall_project = _cpu_only

    def advance(self, x, v, dt, g, x_old):
        self._launch(self.P.advance, x.shape[0], x, v, dt, g, x_old)

    def displacement_velocity(self, x, x_old, dt, v):
        self._launch(self.P.displacement_velocity, x.shape[0], x, x_old, dt, v)

    def accelerate(self, v, dt, g):
        self._launch(self.P.accelerate, v.shape[0], v, dt, g)

    def warm_stiffness(self, k_total, scale, rate, n_nbrs, min_nbrs, warm):
        self._launch(
            self.P.warm_stiffness,
            k_total.shape[0],
            k_total,
            scale,
            self._every_particle if rate is None else rate,
            n_nbrs,
            min_nbrs,
            warm,
        )

    def synchronize(self):
        _cuda.cuda.synchronize()

    # -- memory -------------------------------------------------------------------------------------
    def memory(self) -> tuple[int, int] | None:
        """(free, total) bytes of the device, None on the simulator."""
        if _cuda.SIMULATOR:
            return None
        free, total = _cuda.cuda.current_context().get_memory_info()
        return int(free), int(total)
