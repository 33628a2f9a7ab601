"""stats.csv: one row per simulation step, appended and flushed as the run goes.

The columns are declared once, in `STEP_COLUMNS` (each with how it is read from a step's
`StepStats`) and `ipsph.params.PHASES` (the `ms_<phase>` timings); `STATS_COLUMNS` and
`step_row` are generated from them, and the plots and docs/output-format.md read those names.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..errors import OutputError, WriteError
from ..params import PHASES
from . import atomic_path

__all__ = ["StatsWriter", "read_stats", "STATS_COLUMNS", "STEP_COLUMNS", "step_row"]

# column -> (its value for one step s, a StepStats, and the fluid particle count n; what it is)
STEP_COLUMNS = {
    "step": (lambda s, n: s.step, "step number, from 1"),
    "time": (lambda s, n: s.time, "simulated time at the end of the step [s]"),
    "dt": (lambda s, n: s.dt, "the step's time step [s]"),
    "particles": (lambda s, n: n, "fluid particles (after the step's emission and removal)"),
    "emitted": (lambda s, n: s.emitted, "particles emitted at the end of the step ([[emitter]])"),
    "removed": (lambda s, n: s.removed, "particles removed at the end of the step ([[sink]], [domain])"),
    "density_error_mean_pct": (
        lambda s, n: 100 * s.density_error_mean,
        "mean positive density error at the end-of-step positions [%]",
    ),
    "density_error_max_pct": (lambda s, n: 100 * s.density_error_max, "largest density error [%]"),
    "divergence_error_pct": (lambda s, n: 100 * s.divergence_error, "dt mean(D rho/Dt) / rho0 after the solve [%]"),
    "pd_passes": (lambda s, n: s.pd_passes, "PF local/global passes (PF, IPSPH)"),
    "divergence_iterations": (lambda s, n: s.divergence_iterations, "divergence-solve iterations"),
    "density_iterations": (lambda s, n: s.density_iterations, "DFSPH density-solve iterations"),
    "viscosity_iterations": (lambda s, n: s.viscosity_iterations, "implicit viscosity CG iterations"),
    "max_speed": (lambda s, n: s.max_speed, "largest particle speed [m/s]"),
    "kinetic_energy": (lambda s, n: s.kinetic_energy, "kinetic energy [J]"),
    "dt_clamped": (lambda s, n: s.dt_clamped, "1 when the CFL step fell below time_step.dt_min"),
    "solver_maxed": (lambda s, n: s.solver_maxed, "solves that stopped at their iteration cap"),
    "wall_projections": (lambda s, n: s.wall_projections, "particles moved back outside a field wall"),
    "ms_step": (lambda s, n: 1000 * s.timings.get("step", 0.0), "wall time of the whole step [ms]"),
    # empty for a phase this method does not have (not a timing of 0 ms)
    **{
        f"ms_{p}": ((lambda s, n, p=p: 1000 * s.timings[p] if p in s.timings else None), f"wall time: {what} [ms]")
        for p, (_, what) in PHASES.items()
    },
}
STATS_COLUMNS = tuple(STEP_COLUMNS)


def step_row(s, n_fluid: int) -> dict:
    """One stats.csv row from a step's StepStats."""
    return {name: value(s, n_fluid) for name, (value, _) in STEP_COLUMNS.items()}


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return "1" if v else "0"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))


class StatsWriter:
    """Append-only CSV writer: header once, one flushed line per `write` (no fsync per row).

    `truncate_after_step=k` resumes an existing file: rows with step <= k are kept (the file is
    rewritten atomically) and later rows are appended; without it the file is started afresh.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        columns: list[str] | tuple[str, ...] = STATS_COLUMNS,
        *,
        truncate_after_step: int | None = None,
    ):
        self.path = Path(path)
        self.columns = list(columns)
        header = ",".join(self.columns) + "\n"
        if truncate_after_step is None:
            self._rewrite(header)
        else:
            self._truncate(header, truncate_after_step)
        try:
            self._file = open(self.path, "a", buffering=1, newline="")
        except OSError as exc:
            raise WriteError(
                f"cannot open stats file {self.path} (resolved {self.path.resolve()}): "
                f"{exc.strerror or exc}; check write permission"
            ) from exc

    def _rewrite(self, text: str) -> None:
        with atomic_path(self.path, "stats file") as tmp:
            with open(tmp, "w", newline="") as f:
                f.write(text)

    def _truncate(self, header: str, last_step: int) -> None:
        if not self.path.is_file():
            raise OutputError(
                f"cannot resume stats file {self.path} (resolved {self.path.resolve()}): it does not exist"
            )
        with open(self.path, newline="") as f:
            lines = f.read().splitlines(keepends=True)
        if not lines or lines[0].strip() != header.strip():
            raise OutputError(
                f"cannot resume stats file {self.path}: its header does not match the "
                f"columns {','.join(self.columns)}; start a new output folder"
            )
        i_step = self.columns.index("step")
        kept = [header]
        for line in lines[1:]:
            cells = line.rstrip("\r\n").split(",")
            if len(cells) != len(self.columns) or not line.endswith("\n"):
                break  # a torn last line from an interrupted run
            try:
                if float(cells[i_step]) > last_step:
                    break
            except ValueError:
                break
            kept.append(line)
        self._rewrite("".join(kept))

    def write(self, row: dict) -> None:
        """Append one row; unknown keys are an error, missing ones are left empty (read as NaN)."""
        extra = set(row) - set(self.columns)
        if extra:
            raise KeyError(f"stats row has columns not in the header: {sorted(extra)}")
        line = ",".join(_fmt(row.get(c)) for c in self.columns) + "\n"
        try:
            self._file.write(line)
        except OSError as exc:
            raise WriteError(
                f"cannot write stats file {self.path} (resolved {self.path.resolve()}): "
                f"{exc.strerror or exc}; check free disk space"
            ) from exc

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read_stats(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read stats.csv into {column: float64 array}; a torn last line (running run) is skipped."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            header = f.readline().strip()
            body = f.read()
    except OSError as exc:
        raise OutputError(f"cannot read stats file {path} (resolved {path.resolve()}): {exc.strerror or exc}") from exc
    if not header:
        raise OutputError(f"stats file {path} (resolved {path.resolve()}) has no header")
    names = header.split(",")
    if not body.endswith("\n"):  # the writer may be half-way through a line
        body = body[: body.rfind("\n") + 1]
    rows = [ln for ln in body.splitlines() if ln.count(",") == len(names) - 1]
    if not rows:
        return {n: np.zeros(0) for n in names}
    data = np.genfromtxt(rows, delimiter=",", dtype=np.float64, ndmin=2, missing_values="", filling_values=np.nan)
    return {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(names)}
