"""gauges.csv: one row per sample, appended and flushed as the run goes, like stats.csv.

The header is `time [s]` and then `<gauge>.<quantity> [unit]` per column (`sampler.Column`); a
row holds the values of the gauges due at that step (each gauge has its own `interval`; the
others' cells are empty, read as NaN) and `nan` where a gauge has no value (a dry point). Every
row is one write of one line, so a killed run leaves whole lines (a torn last line, if the disk
filled up mid-line, is skipped by `read_gauges` and cut by a resume). A resumed run keeps the rows
up to its checkpoint's time and carries on: nothing is repeated or lost (`GaugeCSV(resume_time=)`).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from ..errors import OutputError, WriteError
from ..io import GAUGES_CSV, atomic_path  # noqa: F401 - GAUGES_CSV: read from here too

_UNIT = re.compile(r"\s*\[[^\]]*\]\s*$")


def _fmt(v) -> str:
    """A cell: empty for None, else the float's repr (exact; `nan`, `inf` and `-inf` as they are)."""
    return "" if v is None else repr(float(v))


def column_name(header: str) -> str:
    """`mid.pressure [Pa]` -> `mid.pressure`."""
    return _UNIT.sub("", header)


class GaugeCSV:
    """Append-only gauges.csv: the header once, one flushed line per row.

    `resume_time=t` continues an existing file: its rows up to time t are kept (the file is
    rewritten atomically, a torn last line dropped) and later rows are appended."""

    def __init__(self, path: str | os.PathLike, headers: list[str], *, resume_time: float | None = None):
        self.path = Path(path)
        self.headers = list(headers)
        header = ",".join(self.headers) + "\n"
        kept = [header]
        if resume_time is not None:
            kept += self._kept_rows(header, resume_time)
        with atomic_path(self.path, "gauges file") as tmp:
            with open(tmp, "w", newline="") as f:
                f.write("".join(kept))
        try:
            self._file = open(self.path, "a", buffering=1, newline="")
        except OSError as exc:
            raise WriteError(
                f"cannot open gauges file {self.path}: {exc.strerror or exc}; check write permission"
            ) from exc

    def _kept_rows(self, header: str, last_time: float) -> list[str]:
        if not self.path.is_file():
            raise OutputError(
                f"cannot resume gauges file {self.path}: it does not exist; start afresh with --overwrite"
            )
        with open(self.path, newline="") as f:
            lines = f.read().splitlines(keepends=True)
        if not lines or lines[0] != header:
            raise OutputError(
                f"cannot resume gauges file {self.path}: its header does not match the scene's gauges; "
                f"resume with the scene of the original run or start afresh with --overwrite"
            )
        kept = []
        for line in lines[1:]:
            cells = line.rstrip("\r\n").split(",")
            if len(cells) != len(self.headers) or not line.endswith("\n"):
                break  # a torn last line
            try:
                if float(cells[0]) > last_time:
                    break
            except ValueError:
                break
            kept.append(line)
        return kept

    def write(self, t: float, values) -> None:
        line = ",".join([_fmt(t), *(_fmt(v) for v in values)]) + "\n"
        try:
            self._file.write(line)
        except OSError as exc:
            raise WriteError(
                f"cannot write gauges file {self.path}: {exc.strerror or exc}; check free disk space"
            ) from exc

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


def read_gauges(path: str | os.PathLike, *, units: bool = False) -> dict[str, np.ndarray]:
    """gauges.csv as {column: float64 array}, `time` first; names without their units (`mid.pressure`),
    or as in the header with `units=True`. Empty cells (a gauge not due at that row) read as NaN; a
    torn last line (a running or killed run) is skipped."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            header = f.readline().rstrip("\r\n")
            body = f.read()
    except OSError as exc:
        raise OutputError(f"cannot read gauges file {path} (resolved {path.resolve()}): {exc.strerror or exc}") from exc
    if not header:
        raise OutputError(f"gauges file {path} (resolved {path.resolve()}) has no header")
    names = header.split(",")
    if not units:
        names = [column_name(n) for n in names]
    if not body.endswith("\n"):
        body = body[: body.rfind("\n") + 1]
    rows = [ln for ln in body.splitlines() if ln.count(",") == len(names) - 1]
    if not rows:
        return {n: np.zeros(0) for n in names}
    data = np.genfromtxt(rows, delimiter=",", dtype=np.float64, ndmin=2, missing_values="", filling_values=np.nan)
    return {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(names)}


class Schedule:
    """Which gauges are due after a step: every step, or the first step at or after each multiple
    of the gauge's interval. Derived from the time alone, so a resumed run continues the schedule."""

    EPS = 1e-9  # of an interval: a step landing a rounding error short of a multiple samples it

    def __init__(self, intervals: list[float | None], t: float = 0.0, sampled: bool = False):
        """`sampled`: the gauges were sampled at t (a resumed run), so the next sample is after it."""
        self.intervals = intervals
        self.next = [self._after(i, t) if sampled else 0.0 for i in intervals]

    def _after(self, interval, t: float) -> float:
        return 0.0 if interval is None else (math.floor(t / interval + self.EPS) + 1) * interval

    def due(self, t: float) -> set[int]:
        out = set()
        for k, interval in enumerate(self.intervals):
            if interval is None or t >= self.next[k] - self.EPS * interval:
                out.add(k)
                self.next[k] = self._after(interval, t)
        return out
