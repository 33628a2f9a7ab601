"""`Gauges`: a scene's [[gauge]] tables as columns, and their values for one state of the fluid.

The same object serves a run (`log.GaugeLog`, the Python API) and a finished run's frames
(`replay`): `values(t, x, v, rho, p, m, walls)` takes the fluid's arrays and a wall source
(`walls.RunWalls` or `walls.FrameWalls`) and returns one number per column. The numerics are in
`kernels` and run in `passes`; this module lays the gauges out once (the arrays the passes read and
write: a box, a kind and parameters per gauge, the outputs and their columns, units and notes) and
keeps the level gauges' highest level so far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import GaugeSpec, Scene
from ..neighbours.rows import grown_stride
from . import kernels as K
from . import passes as P
from .kernels import FRAME_DTYPE
from .walls import WallGrids


@dataclass(frozen=True)
class Column:
    """One gauges.csv column: `<gauge>.<quantity>`, its unit and what its values mean."""

    gauge: str
    quantity: str
    unit: str
    note: str = ""

    @property
    def name(self) -> str:
        return f"{self.gauge}.{self.quantity}" if self.gauge else self.quantity

    @property
    def header(self) -> str:
        return f"{self.name} [{self.unit}]" if self.unit else self.name


TIME = Column("", "time", "s", "simulated time of the sample (the end of a step)")
_EMPTY = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])  # a box (lo, hi) that holds nothing
_AXES = "xyz"
_KIND = {"point": P.POINT, "level": P.LEVEL, "flow": P.FLOW, "force": P.FORCE}


def point_columns(g: GaugeSpec, h: float) -> list[Column]:
    dry = (
        f"NaN where fewer than {K.MIN_NEIGHBOURS} fluid particles lie within H = {h:g} m of "
        f"{tuple(g.position)} (a dry point, or one at the edge of the fluid)"
    )
    out = []
    for q in g.quantities:
        if q == "pressure":
            out.append(Column(g.name, "pressure", "Pa", "Shepard-interpolated pressure; " + dry))
        elif q == "velocity":
            out += [Column(g.name, f"v{a}", "m/s", "Shepard-interpolated velocity; " + dry) for a in _AXES]
        elif q == "density":
            out.append(Column(g.name, "density", "kg/m^3", "Shepard-interpolated density; " + dry))
    return out


def level_columns(g: GaugeSpec) -> list[Column]:
    x, y, z = g.position
    line = f"on the line x = {x:g}, z = {z:g} m from y = {y:g} to {g.top:g} m"
    notes = {
        "level": f"free-surface height {line}: where the fluid fraction crosses 1/2 going up from "
        f"its lower end; NaN when no point of the line is wet, {g.top:g} when it is wet to the top",
        "level_max": "the highest level of this gauge's samples so far (NaN before the first wet sample)",
    }
    return [Column(g.name, q, "m", notes[q]) for q in g.quantities]


def force_columns(g: GaugeSpec, centre, viscous: bool) -> list[Column]:
    about = f"about ({', '.join(f'{c:.6g}' for c in centre)}) m"
    parts = [("pressure", "the pressure part: the reaction of the walls' pressure term")]
    if viscous:
        parts.append(("viscous", "the viscous part: the reaction of the implicit viscosity's wall friction"))
    out = []
    for part, what in parts:
        if "force" in g.quantities:
            out += [Column(g.name, f"f{a}_{part}", "N", f"force of the fluid on {g.wall!r}, {what}") for a in _AXES]
        if "torque" in g.quantities:
            out += [
                Column(g.name, f"t{a}_{part}", "N m", f"torque of the fluid on {g.wall!r} {about}, {what}")
                for a in _AXES
            ]
    return out


def flow_columns(g: GaugeSpec) -> list[Column]:
    axis = _flat_axis(g)
    return [
        Column(
            g.name,
            "flow",
            "m^3/s",
            f"volume flux through the rectangle {tuple(g.box_min)}..{tuple(g.box_max)} m, positive along +{_AXES[axis]}",
        )
    ]


def _flat_axis(g: GaugeSpec) -> int:
    return next(a for a in range(3) if g.box_min[a] == g.box_max[a])


def has_viscous_part(scene: Scene) -> bool:
    """Whether the walls exert a viscous force in this scene's method: the implicit viscosity with no-slip walls."""
    return (
        scene.viscosity_model == "implicit"
        and scene.kinematic_viscosity_m2s > 0.0
        and scene.viscosity_walls == "no-slip"
    )


class Gauges:
    """The scene's gauges: `columns` (after the time) and `values(...)` for one state of the fluid."""

    def __init__(self, scene: Scene, walls=None):
        self.scene = scene
        self.specs: tuple[GaugeSpec, ...] = scene.gauges
        self.h = scene.support
        self.step = K.LEVEL_STEP_R * scene.particle_radius
        self.walls = walls  # a wall source (walls.RunWalls / FrameWalls) when a force gauge needs one
        self.viscous = has_viscous_part(scene)
        self.centres = {}
        self.columns: list[Column] = []
        self.spans: list[tuple[int, int]] = []  # each gauge's columns
        for g in self.specs:
            first = len(self.columns)
            if g.kind == "point":
                self.columns += point_columns(g, self.h)
            elif g.kind == "level":
                self.columns += level_columns(g)
            elif g.kind == "flow":
                self.columns += flow_columns(g)
            else:
                if walls is None:
                    raise ValueError(f"gauge {g.name!r} measures the force on {g.wall!r}: pass a wall source")
                c = np.asarray(g.point if g.point is not None else walls.centre(g.wall), dtype=np.float64)
                self.centres[g.name] = c
                self.columns += force_columns(g, c, self.viscous)
            self.spans.append((first, len(self.columns)))
        self.level_max = {g.name: math.nan for g in self.specs if g.kind == "level"}
        self._layout()

    @property
    def headers(self) -> list[str]:
        return [TIME.header] + [c.header for c in self.columns]

    def _box(self, g: GaugeSpec) -> np.ndarray:
        """The box around a gauge holding every fluid particle that can contribute to it."""
        h = self.h
        if g.kind == "point":
            lo = hi = np.asarray(g.position, dtype=np.float64)
        elif g.kind == "level":
            lo = np.asarray(g.position, dtype=np.float64)
            hi = np.array([lo[0], g.top, lo[2]])
        else:
            lo, hi = np.asarray(g.box_min, dtype=np.float64), np.asarray(g.box_max, dtype=np.float64)
            pad = np.zeros(3)
            pad[_flat_axis(g)] = h
            return np.concatenate([lo - pad, hi + pad])
        return np.concatenate([lo - h, hi + h])

    def _layout(self) -> None:
        """The arrays `passes.sample` reads and writes, laid out once: each gauge's kind, box,
        parameters and slot (a level gauge's row of the level lists, a force gauge's wall grid),
        the outputs `acc`, and where each column reads acc (`_source`)."""
        n_g = len(self.specs)
        self._kinds = np.array([_KIND[g.kind] for g in self.specs], dtype=np.int64)
        self._boxes = np.tile(_EMPTY, (n_g, 1))  # a force gauge's box: its wall's, when due
        self._par = np.zeros((n_g, 8))
        self._slot = np.zeros(n_g, dtype=np.int64)
        self._levels = [k for k, g in enumerate(self.specs) if g.kind == "level"]
        self._forces = [k for k, g in enumerate(self.specs) if g.kind == "force"]
        source = []
        for k, g in enumerate(self.specs):
            if g.kind != "force":
                self._boxes[k] = self._box(g)
            if g.kind == "point":
                self._par[k, :3] = g.position
                picks = {"pressure": [0], "velocity": [1, 2, 3], "density": [4]}
                source += [k * P.ACC + c for q in g.quantities for c in picks[q]]
            elif g.kind == "level":
                self._par[k, :4] = (*g.position, g.top)
                self._slot[k] = self._levels.index(k)
                source += [k * P.ACC + {"level": 0, "level_max": 1}[q] for q in g.quantities]
            elif g.kind == "flow":
                self._par[k, :7] = (*g.box_min, *g.box_max, _flat_axis(g))
                source.append(k * P.ACC)
            else:
                self._par[k, :3] = self.centres[g.name]
                self._slot[k] = self._forces.index(k)
                parts = (0, 6) if self.viscous else (0,)
                picks = {"force": [0, 1, 2], "torque": [3, 4, 5]}
                source += [k * P.ACC + part + c for part in parts for q in picks if q in g.quantities for c in picks[q]]
        self._source = np.array(source, dtype=np.int64)
        self._picked = np.empty(len(source))
        self._acc = np.zeros((n_g, P.ACC))
        self._due = np.ones(n_g, dtype=np.bool_)
        self._level_lists(256)
        self._walls = WallGrids(self.h)
        self._fi = np.zeros((0, max(len(self._forces), 1), 3))  # wall_forces' F_i per particle and force gauge

    def _level_lists(self, width: int) -> None:
        """The level gauges' particle lists (one row each, `width` wide) and the scratch of their walk."""
        self._lvl_idx = np.zeros((len(self._levels), width), dtype=np.int64)
        self._lvl_count = np.zeros(len(self._levels), dtype=np.int64)
        self._lvl_real = np.zeros((3, width))
        self._lvl_int = np.zeros((2, width), dtype=np.int64)

    def values(self, t: float, x, v, rho, p, m, due=None) -> list[float | None]:
        """One value per column for the fluid's arrays at time t (None for gauges not in `due`, a
        set of gauge indices; all when None). Updates the level gauges' highest level so far."""
        self._due[:] = due is None
        if due is not None:
            self._due[list(due)] = True
        acc, w = self._acc, self._walls
        if self._forces:
            self._force_walls(t)
            if self._fi.shape[0] != len(x):
                self._fi = np.zeros((len(x), len(self._forces), 3))  # a changed particle count (emitters, sinks)
            P.wall_forces(
                x, rho, p, m, self._boxes, self._kinds, self._slot, self._due, self.h,
                w.x, w.m, w.origin, w.dims, w.start, w.offset, w.cand, w.cell, w.buf, self._fi,
            )  # fmt: skip
        while True:
            most = P.sample(
                x, v, rho, p, m, self._boxes, self._kinds, self._par, self._slot, self._due, self.h, self.step,
                self._fi, self._lvl_idx, self._lvl_count, self._lvl_real, self._lvl_int, acc,
            )  # fmt: skip
            if most <= self._lvl_idx.shape[1]:
                break
            self._level_lists(grown_stride(self._lvl_idx.shape[1], most))  # rare: a longer line of fluid
        for k in self._levels:
            level, name = acc[k, 0], self.specs[k].name
            if self._due[k] and not math.isnan(level) and not level <= self.level_max[name]:
                self.level_max[name] = float(level)
            acc[k, 1] = self.level_max[name]
        if self.viscous:
            for k in self._forces:
                if self._due[k]:
                    acc[k, 6:] = self._viscous(
                        self.specs[k], t, x, v, rho, m, *self.walls.arrays(self.specs[k].wall, t)
                    )
        out: list[float | None] = np.take(acc, self._source, out=self._picked).tolist()
        if due is not None and len(due) < len(self.specs):
            for k, (first, last) in enumerate(self.spans):
                if k not in due:
                    out[first:last] = [None] * (last - first)
        return out

    def _force_walls(self, t: float) -> None:
        """The force gauges' walls now: their grids (`WallGrids`: kept while a wall's arrays are the same
        objects, as a static wall's are) and their boxes, the wall's bounds plus H (nothing when not due)."""
        walls = [self.walls.arrays(self.specs[k].wall, t) if self._due[k] else None for k in self._forces]
        self._walls.update(walls)
        for k, f in zip(self._forces, range(len(self._forces))):
            got = self._walls.bounds[f]
            self._boxes[k] = _EMPTY if got is None or walls[f] is None else got

    def _viscous(self, g: GaugeSpec, t: float, x, v, rho, m, xw, mw) -> np.ndarray:
        """(F, T) of the implicit viscosity's wall friction on the wall of `g` (NaN where the wall's
        velocities are unknown: a rigid body's after the run, bodies.csv has no angular velocity)."""
        from ..methods.viscosity import full_trace
        from .viscous import wall_viscous_force

        out = np.full(6, np.nan)
        vw = self.walls.velocities(g.wall, t)
        if vw is None or not len(xw):
            return out
        xa, ma = self.walls.everything(t)
        reach = 2.0 * self.h  # the fluid within 2H of the wall: complete neighbourhoods for those within H
        xq = x.astype(FRAME_DTYPE).astype(np.float64)
        cand = np.flatnonzero(np.all((xq >= xw.min(axis=0) - reach) & (xq <= xw.max(axis=0) + reach), axis=1))
        reach = 3.0 * self.h  # the walls near the fluid within 2H of this wall
        near = np.all((xa >= xw.min(axis=0) - reach) & (xa <= xw.max(axis=0) + reach), axis=1)
        sc = self.scene
        wall_viscous_force(
            x, v, rho, m, cand, xw, mw, np.ascontiguousarray(vw, dtype=np.float64),
            np.ascontiguousarray(xa[near]), np.ascontiguousarray(ma[near]), self.h, sc.kinematic_viscosity_m2s,
            full_trace(sc.spacing, self.h), sc.density0, self.centres[g.name], out,
        )  # fmt: skip
        return out

    def restore_level_max(self, columns: dict[str, np.ndarray]) -> None:
        """After a resume: the highest levels in the kept rows of gauges.csv (`columns` by name)."""
        for name in self.level_max:
            seen = [a[np.isfinite(a)] for q in ("level", "level_max") if (a := columns.get(f"{name}.{q}")) is not None]
            seen = np.concatenate([np.zeros(0)] + seen)
            self.level_max[name] = float(seen.max()) if len(seen) else math.nan
