"""The wall particles a force gauge sums over, in one order for a run and for its frames.

A force gauge names a [[boundary]]; its particles are that entry's samples (`model.samples`, the
order the run sampled them in: the *canonical* order). The run's `Boundary` holds every wall's
particles in the neighbour search's sorted order and knows no names, so the canonical rows are
found in it by their placement: a static wall's particles never move and a moving wall's keep
their placement `x0`, both exact copies of the samples (`match_rows`, redone when the search
re-sorts the walls). `ipsph gauge` rebuilds the same rows from the scene: the volumes of static
walls from boundary.vtu (matched the same way), a moving wall's Akinci volumes from its samples
(as `Boundary` computes them, per wall) and its pose at a frame's time from bodies.csv (rigid
bodies) or its prescribed motion. Both sides then sum the same particles in the same order.
"""

from __future__ import annotations

import numpy as np

from ..boundary import model_of
from ..config import Scene
from ..errors import OutputError
from . import passes


def canonical_walls(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(x0, start): every [[boundary]]'s particles as sampled, concatenated; entry k is x0[start[k]:start[k+1]]."""
    model, r = model_of(scene), scene.particle_radius
    parts = [model.samples(spec, r) for spec in scene.boundaries]
    start = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
    return np.concatenate([np.zeros((0, 3))] + parts), start


def match_rows(ref: np.ndarray, pts: np.ndarray) -> np.ndarray | None:
    """where[c] = the row of `pts` equal to ref[c], when pts is a permutation of ref's rows; else None.
    (Two walls whose particles coincide exactly may swap those particles: they then sit at the same
    place and carry the same volume only if the walls are alike.)"""
    if ref.shape != pts.shape:
        return None
    a = np.lexsort(ref.T[::-1])
    b = np.lexsort(pts.T[::-1])
    if not np.array_equal(ref[a], pts[b]):
        return None
    where = np.empty(len(ref), dtype=np.int64)
    where[a] = b
    return where


def wall_index(scene: Scene, name: str) -> int:
    return next(k for k, b in enumerate(scene.boundaries) if b.name == name)


class RunWalls:
    """The named walls' particles in a running Simulation's Boundary, in canonical order."""

    def __init__(self, scene: Scene, boundary):
        self.scene, self.boundary = scene, boundary
        self.x0, self.start = canonical_walls(scene)
        self._key = None
        self._where = None
        self._static: dict[int, tuple] = {}  # wall -> (the placements it was gathered from, (x, m))

    def _placements(self):
        b = self.boundary
        return b.x0 if b.x0 is not None else b.x  # moving walls: their placement; static: where they are

    def rows(self, k: int) -> np.ndarray:
        key = self._placements()
        if key is not self._key:  # first use, or the search re-sorted the walls
            where = match_rows(self.x0, key)
            if where is None:
                raise OutputError(
                    "force gauges: the run's wall particles are not the scene's samples (sampled differently?)"
                )
            self._key, self._where = key, where
        return self._where[self.start[k] : self.start[k + 1]]

    def arrays(self, name: str, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(positions, masses) of the wall `name` now, canonical order; a static wall's are gathered
        once (and again only when the search re-sorts the walls), the same objects every sample."""
        k = wall_index(self.scene, name)
        rows = self.rows(k)
        spec, b = self.scene.boundaries[k], self.boundary
        static = not (spec.moving or spec.dynamic)
        if static and k in self._static and self._static[k][0] is self._key:
            return self._static[k][1]
        got = np.ascontiguousarray(b.x[rows]), np.ascontiguousarray(b.m[rows])
        if static:
            self._static[k] = (self._key, got)
        return got

    def velocities(self, name: str, t: float) -> np.ndarray:
        return np.ascontiguousarray(self.boundary.v[self.rows(wall_index(self.scene, name))])

    def everything(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(positions, masses) of every wall particle, in the run's order."""
        return self.boundary.x, self.boundary.m

    def centre(self, name: str) -> np.ndarray:
        k = wall_index(self.scene, name)
        return _box_centre(self.x0[self.start[k] : self.start[k + 1]])


def _box_centre(x: np.ndarray) -> np.ndarray:
    return 0.5 * (x.min(axis=0) + x.max(axis=0)) if len(x) else np.zeros(3)


class FrameWalls:
    """The same rows rebuilt for a finished run's frames (`ipsph gauge`): see the module docstring."""

    def __init__(self, scene: Scene, boundary_x: np.ndarray, boundary_psi: np.ndarray, bodies: dict | None):
        self.scene = scene
        self.x0, self.start = canonical_walls(scene)
        self.bodies = bodies or {}
        self._static_psi = None
        self._boundary = (np.asarray(boundary_x, dtype=np.float64), np.asarray(boundary_psi, dtype=np.float64))
        self._cache: dict[int, tuple] = {}

    def _wall(self, k: int):
        if k in self._cache:
            return self._cache[k]
        spec, x0 = self.scene.boundaries[k], self.x0[self.start[k] : self.start[k + 1]]
        rho0 = self.scene.density0
        if spec.moving:  # Akinci's volumes over the wall's own particles, as the run's Boundary
            from ..boundary.particles import Boundary

            m = rho0 * Boundary(x0, self.scene.support, rho0).psi
        else:
            m = rho0 * self._static_volumes()[self.start[k] : self.start[k + 1]]
        self._cache[k] = (spec, x0, m)
        return self._cache[k]

    def _static_volumes(self) -> np.ndarray:
        """Every static wall's volumes in canonical order, from boundary.vtu, whose static rows are
        exact copies of the samples (NaN for moving walls' rows: theirs are computed)."""
        if self._static_psi is None:
            bx, psi = self._boundary
            at = {row.tobytes(): i for i, row in enumerate(np.ascontiguousarray(bx))}
            out = np.full(len(self.x0), np.nan)
            for k, spec in enumerate(self.scene.boundaries):
                if spec.moving:
                    continue
                for c in range(self.start[k], self.start[k + 1]):
                    i = at.get(self.x0[c].tobytes())
                    if i is None:
                        raise OutputError(
                            f"boundary.vtu lacks particles of wall {spec.name!r} as the scene samples them (sampled "
                            f"by another ipsph version?): a force gauge on it needs them"
                        )
                    out[c] = psi[i]
            self._static_psi = out
        return self._static_psi

    def arrays(self, name: str, t: float) -> tuple[np.ndarray, np.ndarray]:
        k = wall_index(self.scene, name)
        spec, x0, m = self._wall(k)
        if not spec.moving:
            return x0, m
        if spec.dynamic:
            return self._body_positions(spec, x0, t), m
        from ..boundary.motion import Motion

        pivot = spec.motion.pivot if spec.motion.pivot is not None else 0.5 * (x0.min(axis=0) + x0.max(axis=0))
        return np.ascontiguousarray(Motion(spec.motion, pivot).positions(x0, t)), m

    def velocities(self, name: str, t: float) -> np.ndarray | None:
        """The wall's particles' velocities at t; None for a rigid body (bodies.csv lacks its spin)."""
        k = wall_index(self.scene, name)
        spec, x0, _ = self._wall(k)
        if not spec.moving:
            return np.zeros_like(x0)
        if spec.dynamic:
            return None
        from ..boundary.motion import Motion

        pivot = spec.motion.pivot if spec.motion.pivot is not None else 0.5 * (x0.min(axis=0) + x0.max(axis=0))
        return Motion(spec.motion, pivot).velocities(x0, t)

    def everything(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(positions, masses) of every wall particle at t, canonical order."""
        parts = [self.arrays(spec.name, t) for spec in self.scene.boundaries]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _body_positions(self, spec, x0: np.ndarray, t: float) -> np.ndarray:
        from ..boundary.motion import quat_matrix
        from ..boundary.rigid import mass_properties

        c0 = mass_properties(spec, 1.0)[1]
        c, q = c0, np.array([1.0, 0.0, 0.0, 0.0])
        rows = self.bodies.get(spec.name)
        if t > 0.0:
            at = np.flatnonzero(rows["time"] == t) if rows is not None else []
            if len(at) == 0:
                raise OutputError(
                    f"bodies.csv has no row of body {spec.name!r} at t = {t!r} s: a force gauge on it needs its pose"
                )
            i = at[-1]
            c = np.array([rows["x"][i], rows["y"][i], rows["z"][i]])
            q = np.array([rows["qw"][i], rows["qx"][i], rows["qy"][i], rows["qz"][i]])
        return np.ascontiguousarray((x0 - c0) @ quat_matrix(q).T + c)

    def centre(self, name: str) -> np.ndarray:
        k = wall_index(self.scene, name)
        return _box_centre(self.x0[self.start[k] : self.start[k + 1]])


class WallGrids:
    """The force gauges' walls as `passes.sample` reads them: every gauge's wall particles by cell
    (`passes.wall_cells`), joined into one set of arrays (see `passes`). A gauge's grid is rebuilt
    only when its wall's arrays are new objects (a moving wall, every sample; a static wall's come
    back the same from RunWalls and FrameWalls, so its grid is built once)."""

    _NONE = (np.zeros((0, 3)), np.zeros(0))  # a gauge not sampled yet: no wall particles

    def __init__(self, h: float):
        self.h, self.cell = h, passes.WALL_CELL_H * h
        self._grids: list = []  # per gauge: (xw, mw, origin, dims, start, cand)
        self.bounds: list = []  # per gauge: (lo, hi) of its wall plus H, or None for an empty wall
        self.update([])

    def update(self, walls: list) -> None:
        """walls[f]: (positions, masses) of force gauge f's wall now, or None (not due: kept as it was)."""
        changed = len(self._grids) != len(walls) or not walls
        if changed:
            self._grids, self.bounds = [self._grid(*self._NONE) for _ in walls], [None] * len(walls)
        for f, got in enumerate(walls):
            old = self._grids[f]
            if got is None or old[0] is got[0] and old[1] is got[1]:
                continue
            xw, mw = got
            self._grids[f] = self._grid(xw, mw)
            self.bounds[f] = np.concatenate([xw.min(axis=0) - self.h, xw.max(axis=0) + self.h]) if len(xw) else None
            changed = True
        if changed:
            self._join()

    def _grid(self, xw, mw) -> tuple:
        return (xw, mw, *passes.wall_cells(np.ascontiguousarray(xw, dtype=np.float64), self.h, self.cell))

    def _join(self) -> None:
        """One set of arrays: positions, masses, the grids' origins and sizes, their cell lists (each
        grid's `start` shifted to its place in `cand`, its candidates to their wall's place in x)."""
        g = self._grids or [self._grid(*self._NONE)]
        walls = np.cumsum([0] + [len(e[0]) for e in g])
        cands = np.cumsum([0] + [len(e[5]) for e in g])
        self.x = np.ascontiguousarray(np.concatenate([e[0] for e in g]), dtype=np.float64)
        self.m = np.ascontiguousarray(np.concatenate([e[1] for e in g]), dtype=np.float64)
        self.origin = np.array([e[2] for e in g])
        self.dims = np.array([e[3] for e in g], dtype=np.int64)
        self.offset = np.cumsum([0] + [len(e[4]) for e in g]).astype(np.int64)
        self.start = np.concatenate([e[4] + cands[f] for f, e in enumerate(g)])
        self.cand = np.concatenate([e[5] + walls[f] for f, e in enumerate(g)]).astype(np.int32)
        most = max(int(np.max(np.diff(e[4]), initial=0)) for e in g)  # the longest cell list
        self.buf = np.empty((passes.BLOCKS, 4, max(most, 1)))  # force_at's blocks, one per block of wall_forces
