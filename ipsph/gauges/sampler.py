"""`Gauges`: a scene's [[gauge]] tables as columns, and their values for one state of the fluid.

The same object serves a run (`log.GaugeLog`, the Python API) and a finished run's frames
(`replay`): `values(t, x, v, rho, p, m, walls)` takes the fluid's arrays and a wall source
(`walls.RunWalls` or `walls.FrameWalls`) and returns one number per column. The numerics are in
`kernels`; this module only lays the gauges out (one box per gauge for the one pass over the
fluid, the columns, their units and notes) and keeps the level gauges' highest level so far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import GaugeSpec, Scene
from . import kernels as K


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
        self._boxes = np.tile(_EMPTY, (len(self.specs), 1))  # a force gauge's box: its wall's, when due
        for k, g in enumerate(self.specs):
            if g.kind != "force":
                self._boxes[k] = self._box(g)
        # laid out once: the point gauges (one kernel call for all), their columns of point_values'
        # (p, vx, vy, vz, rho, n), the flow rectangles, the force gauges
        self._points = np.array([k for k, g in enumerate(self.specs) if g.kind == "point"], dtype=np.int64)
        self._point_xyz = np.array([self.specs[k].position for k in self._points], dtype=np.float64).reshape(-1, 3)
        self._point_out = np.empty((len(self._points), 6))
        picks = {"pressure": [0], "velocity": [1, 2, 3], "density": [4]}
        self._point_picks = [[c for q in self.specs[k].quantities for c in picks[q]] for k in self._points]
        self._rects = {
            k: (np.asarray(g.box_min, dtype=np.float64), np.asarray(g.box_max, dtype=np.float64), _flat_axis(g))
            for k, g in enumerate(self.specs)
            if g.kind == "flow"
        }
        self._forces = [k for k, g in enumerate(self.specs) if g.kind == "force"]
        self._wall_boxes: dict[int, tuple] = {}  # force gauge -> (its wall's positions, their bounding box)

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

    def values(self, t: float, x, v, rho, p, m, due=None) -> list[float | None]:
        """One value per column for the fluid's arrays at time t (None for gauges not in `due`, a
        set of gauge indices; all when None). Updates the level gauges' highest level so far."""
        boxes = self._boxes
        force_walls = {}
        for k in self._forces:
            boxes[k] = _EMPTY
            if due is None or k in due:
                g = self.specs[k]
                xw, mw = self.walls.arrays(g.wall, t)
                force_walls[k] = (xw, mw)
                reach = (2.0 if self.viscous else 1.0) * self.h  # the viscous part: i's own neighbours too
                if len(xw):
                    seen = self._wall_boxes.get(k)
                    if seen is None or seen[0] is not xw:  # a static wall's arrays come back the same
                        seen = self._wall_boxes[k] = (xw, np.concatenate([xw.min(axis=0), xw.max(axis=0)]))
                    boxes[k, :3], boxes[k, 3:] = seen[1][:3] - reach, seen[1][3:] + reach
        start, idx = K.select(x, boxes)
        out: list[float | None] = [None] * len(self.columns)
        if len(self._points):
            K.point_values(x, v, rho, p, m, start, idx, self._points, self._point_xyz, self.h, self._point_out)
            for k, (g, picks) in enumerate(zip(self._points, self._point_picks)):
                if due is None or g in due:
                    first = self.spans[g][0]
                    out[first : first + len(picks)] = self._point_out[k, picks].tolist()
        for k, g in enumerate(self.specs):
            if g.kind == "point" or due is not None and k not in due:
                continue
            cand = idx[start[k] : start[k + 1]]
            first, _ = self.spans[k]
            if g.kind == "level":
                x0, y0, z0 = g.position
                level = float(K.level_value(x, rho, m, cand, x0, z0, y0, g.top, self.step, self.h))
                if not math.isnan(level) and not level <= self.level_max[g.name]:
                    self.level_max[g.name] = level
                got = {"level": level, "level_max": self.level_max[g.name]}
                vals = [got[q] for q in g.quantities]
            elif g.kind == "flow":
                lo, hi, axis = self._rects[k]
                vals = [float(K.flow_value(x, v, rho, m, cand, lo, hi, axis, self.h))]
            else:
                xw, mw = force_walls[k]
                buf = np.empty(6)
                K.wall_force(x, rho, p, m, cand, xw, mw, self.centres[g.name], self.h, buf)
                vals = _force_values(g, buf)
                if self.viscous:
                    vals += _force_values(g, self._viscous(g, t, x, v, rho, m, cand, xw, mw))
            out[first : first + len(vals)] = vals
        return out

    def _viscous(self, g: GaugeSpec, t: float, x, v, rho, m, cand, xw, mw) -> np.ndarray:
        """(F, T) of the implicit viscosity's wall friction on the wall of `g` (NaN where the wall's
        velocities are unknown: a rigid body's after the run, bodies.csv has no angular velocity)."""
        from ..methods.viscosity import full_trace
        from .viscous import wall_viscous_force

        out = np.full(6, np.nan)
        vw = self.walls.velocities(g.wall, t)
        if vw is None or not len(xw):
            return out
        xa, ma = self.walls.everything(t)
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


def _force_values(g: GaugeSpec, buf: np.ndarray) -> list[float]:
    vals = []
    if "force" in g.quantities:
        vals += [float(c) for c in buf[:3]]
    if "torque" in g.quantities:
        vals += [float(c) for c in buf[3:]]
    return vals
