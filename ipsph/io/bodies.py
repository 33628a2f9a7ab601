"""Moving walls' outputs: OUT/bodies.csv (one row per moving wall per step) and their surface meshes
per frame, OUT/bodies/bodies_NNNNNN.vtp, the `bodies` part of run.pvd (docs/output-format.md).

A moving wall is a kinematic [[boundary]] (a `motion`) or a dynamic rigid body (a density or
mass). Its row: the centre (a body's centre of mass; a kinematic wall's pivot), the orientation
quaternion, the centre's velocity and the fluid's force and torque on it (about that centre) in
the step just finished (ipsph.boundary.rigid).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import BODIES_CSV, bodies_file

if TYPE_CHECKING:
    import pyvista as pv

# bodies.csv's columns, in order, with their units (declared once: the writer, the reader, the docs)
BODIES_COLUMNS = (
    ("time", "s"),
    ("body", ""),
    ("x", "m"),
    ("y", "m"),
    ("z", "m"),
    ("qw", ""),
    ("qx", ""),
    ("qy", ""),
    ("qz", ""),
    ("vx", "m/s"),
    ("vy", "m/s"),
    ("vz", "m/s"),
    ("fx", "N"),
    ("fy", "N"),
    ("fz", "N"),
    ("tx", "N m"),
    ("ty", "N m"),
    ("tz", "N m"),
)


def moving_surfaces(scene, walls) -> "pv.PolyData":
    """The moving walls' surfaces where they are now, merged (one mesh; `body` cell data = its index)."""
    import pyvista as pv

    from ..geometry.shapes import boundary_surface

    parts = []
    movers = {name: ("body", b) for name, b in ((b.name, b) for b in walls.bodies)}
    movers.update({name: ("kinematic", m) for _, name, m in walls.kinematic})
    for k, spec in enumerate(scene.boundaries):
        if spec.name not in movers:
            continue
        kind, obj = movers[spec.name]
        mesh = walls.surface_cache.get(spec.name)
        if mesh is None:
            mesh = walls.surface_cache[spec.name] = boundary_surface(spec).triangulate()
        pts = np.asarray(mesh.points, dtype=np.float64)
        if kind == "body":
            moved = (pts - obj.c0) @ obj.rotation().T + obj.c
        else:
            moved = obj.positions(pts, walls.t_walls)
        m = mesh.copy()
        m.points = moved
        m.cell_data["body"] = np.full(m.n_cells, k, dtype=np.int32)
        parts.append(m)
    return pv.merge(parts) if len(parts) > 1 else parts[0]


class BodiesLog:
    """bodies.csv (append per step, flushed) and the per-frame surfaces of the moving walls."""

    def __init__(self, out: Path, truncate_after_time: float | None = None):
        self.out = Path(out)
        path = self.out / BODIES_CSV
        if truncate_after_time is not None and path.is_file():  # a resumed run: drop rows after the checkpoint
            with open(path, newline="") as f:
                rows = list(csv.reader(f))
            keep = [rows[0]] + [r for r in rows[1:] if float(r[0]) <= truncate_after_time + 1e-12]
            with open(path, "w", newline="") as f:
                csv.writer(f).writerows(keep)
            self._file = open(path, "a", newline="")
        else:
            self._file = open(path, "w", newline="")
            self._file.write(",".join(name for name, _ in BODIES_COLUMNS) + "\n")
        self._csv = csv.writer(self._file)

    def step(self, sim) -> None:
        for row in sim.walls.rows(sim.time):
            self._csv.writerow([repr(float(row[0])), row[1], *(repr(float(v)) for v in row[2:])])
        self._file.flush()

    def frame(self, sim, index: int) -> str:
        """Write the moving walls' surfaces of this frame; returns the file name relative to OUT."""
        from . import vtu

        name = bodies_file(index)
        (self.out / name).parent.mkdir(parents=True, exist_ok=True)
        vtu.write_surface(self.out / name, moving_surfaces(sim.scene, sim.walls))
        return name

    def close(self) -> None:
        self._file.close()


def read_bodies(path: str | os.PathLike) -> dict[str, dict[str, np.ndarray]]:
    """bodies.csv as {body name: {column: array over its rows}}."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    out: dict[str, dict[str, list]] = {}
    for r in rows:
        d = out.setdefault(r["body"], {name: [] for name, _ in BODIES_COLUMNS if name != "body"})
        for name, _ in BODIES_COLUMNS:
            if name != "body":
                d[name].append(float(r[name]))
    return {k: {c: np.asarray(v) for c, v in d.items()} for k, d in out.items()}
