"""`GaugeLog`: the gauges of a running Simulation, sampled after its steps into gauges.csv (the run
folder) or into memory (the Python API: `log.arrays()`)."""

from __future__ import annotations

import numpy as np

from .kernels import FRAME_DTYPE
from .log import GAUGES_CSV, GaugeCSV, Schedule, read_gauges  # noqa: F401 - GAUGES_CSV: read from here too
from .sampler import TIME, Gauges
from .walls import RunWalls


class GaugeLog:
    """Samples `sim`'s gauges (scene.gauges) at t = 0 and after each step when due.

        log = GaugeLog(sim)                      # in memory; or GaugeLog(sim, "out/gauges.csv")
        sim.run(on_step=log.on_step)
        log.arrays()["mid.pressure"]             # {column: array}, `time` first

    `resume_time`: continue the gauges.csv of a run resumed from a checkpoint at that time (its
    rows up to then are kept, the level gauges' maxima read back from them; no sample at the start).
    """

    def __init__(self, sim, path=None, *, resume_time: float | None = None):
        self.sim = sim
        scene = sim.scene
        needs_walls = any(g.kind == "force" for g in scene.gauges)
        self.gauges = Gauges(scene, RunWalls(scene, sim.boundary) if needs_walls else None)
        self.schedule = Schedule(
            [g.interval for g in scene.gauges],
            0.0 if resume_time is None else resume_time,
            sampled=resume_time is not None,
        )
        self.csv = None if path is None else GaugeCSV(path, self.gauges.headers, resume_time=resume_time)
        self.rows: list[list] = []
        if resume_time is not None and path is not None:
            self.gauges.restore_level_max(read_gauges(path))
        if resume_time is None:
            self.sample()

    @property
    def columns(self):
        return [TIME, *self.gauges.columns]

    def sample(self) -> None:
        """Sample the gauges due at the simulation's current time."""
        sim = self.sim
        due = self.schedule.due(sim.time)
        if not due:
            return
        values = self.gauges.values(
            sim.time, sim.positions, sim.velocities, sim.densities, sim.pressures, sim.masses, due
        )
        if self.csv is not None:
            self.csv.write(sim.time, values)
        else:
            self.rows.append([sim.time, *values])

    def on_step(self, stats=None) -> None:
        """For `Simulation.run(on_step=...)`."""
        self.sample()

    def arrays(self) -> dict[str, np.ndarray]:
        """The samples so far as {column name: float64 array} (NaN: no value, or not due)."""
        if self.csv is not None:
            return read_gauges(self.csv.path)
        data = np.array([[np.nan if v is None else v for v in row] for row in self.rows], dtype=np.float64)
        data = data.reshape(len(self.rows), len(self.columns))
        return {c.name: data[:, k].copy() for k, c in enumerate(self.columns)}

    def close(self) -> None:
        if self.csv is not None:
            self.csv.close()


def listing(log: GaugeLog) -> dict:
    """run.json's `gauges`: the file, every column with its unit and note, each gauge's interval."""
    return {
        "file": GAUGES_CSV,
        "columns": [{"name": c.name, "unit": c.unit, "note": c.note} for c in log.columns],
        "intervals": {g.name: g.interval for g in log.gauges.specs},
        "precision": f"the fluid read as frames store it ({np.dtype(FRAME_DTYPE).name})",
    }
