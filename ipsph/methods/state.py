"""Particle state: one structure-of-arrays container for everything that lives across steps.

Positions, velocities, masses and ids, plus any per-particle array a method must keep from
one step to the next (warm-start stiffness, pressure). Keeping them all here means the
neighbour search can reorder particles for locality with one `permute`, and a checkpoint is
simply `arrays()`. Methods keep their per-step scratch arrays to themselves.
"""

from __future__ import annotations

import numpy as np


class ParticleState:
    """Named numpy arrays with a common first dimension (the fluid particles)."""

    def __init__(
        self,
        x: np.ndarray,
        v: np.ndarray,
        m: np.ndarray,
        ids: np.ndarray | None = None,
        backend=None,
        capacity: int | None = None,
    ):
        if backend is None:
            from ..backends import get_backend

            backend = get_backend()
        self.be = backend  # allocates the arrays and reorders them
        n = len(x)
        # the most particles this run can hold (emitters: ipsph.flow); the methods size their
        # scratch by it, the arrays here always have the active count n rows
        self.capacity = max(n, int(capacity or 0))
        self._names: list[str] = []
        self.add("x", backend.asarray(x))
        self.add("v", backend.asarray(v))
        self.add("m", backend.asarray(m))
        self.add("id", backend.asarray(np.arange(n) if ids is None else ids, dtype="int64"))

    # declared for type checkers; set through add()
    x: np.ndarray
    v: np.ndarray
    m: np.ndarray
    id: np.ndarray

    @property
    def n(self) -> int:
        return len(self.x)

    def add(self, name: str, array: np.ndarray) -> np.ndarray:
        """Register a per-particle array that must follow the particles when they are reordered."""
        if len(array) != (len(self.x) if self._names else len(array)):
            raise ValueError(f"array {name!r} has {len(array)} rows, the state has {len(self.x)}")
        if name not in self._names:
            self._names.append(name)
        setattr(self, name, array)
        return array

    def zeros(self, name: str, shape=(), dtype=np.float64) -> np.ndarray:
        return self.add(name, self.be.zeros(self.n, shape, dtype=dtype))

    def permute(self, perm: np.ndarray) -> None:
        """Reorder every registered array by `perm` (new[i] = old[perm[i]])."""
        for name in self._names:
            setattr(self, name, self.be.take(getattr(self, name), perm))

    def append(self, rows: dict[str, np.ndarray]) -> None:
        """Add particles at the end (an emitter's layer): `rows` gives x, v, m, id on the host;
        every other registered array (warm starts, pressure) starts at zero for them."""
        k = len(rows["x"])
        for name in self._names:
            a = getattr(self, name)
            new = rows[name] if name in rows else np.zeros((k, *a.shape[1:]), dtype=a.dtype)
            setattr(self, name, self.be.concat(a, self.be.asarray(new, dtype=a.dtype)))

    def keep(self, index: np.ndarray) -> None:
        """Keep only the particles at `index` (ascending), in that order: removal by compaction."""
        self.permute(self.be.asarray(index, dtype="int64"))

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in self._names}

    def state_dict(self) -> dict[str, np.ndarray]:
        """A copy of every registered array, on the host (a checkpoint's particle part)."""
        return {name: np.array(self.be.to_host(getattr(self, name))) for name in self._names}

    def load_state_dict(self, arrays: dict[str, np.ndarray]) -> None:
        """Replace the registered arrays (checkpoint restore); names must match exactly."""
        if set(arrays) != set(self._names):
            raise ValueError(f"state arrays differ: have {sorted(self._names)}, got {sorted(arrays)}")
        for name in self._names:
            a = arrays[name]
            setattr(self, name, self.be.asarray(a, dtype=a.dtype))

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, name).nbytes for name in self._names)
