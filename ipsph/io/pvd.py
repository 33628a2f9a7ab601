"""The ParaView collection (.pvd) that strings the frames into one time series.

Per timestep two DataSets: part="0" the fluid frame, part="1" the boundary file written once
(ecosystem.md: ParaView and pyvista's PVDReader show both as one series), and part="2" the
frame's surface mesh once it has one (output.surface, `ipsph surface`). File names inside
are relative to the .pvd's folder. The file is rewritten atomically after every frame, so a
reader (ParaView, `ipsph render`) always sees a complete, valid series.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path, PurePosixPath

from ..errors import OutputError
from . import atomic_path

__all__ = ["PvdSeries"]


class PvdSeries:
    """Frames (time, fluid file) of one run, mirrored to `path` on every `add`."""

    def __init__(self, path: str | os.PathLike, boundary_file: str | os.PathLike | None):
        self.path = Path(path)
        self.boundary_file = self._relative(boundary_file) if boundary_file is not None else None
        self.frames: list[tuple[float, str]] = []
        self.surfaces: dict[float, str] = {}  # frame time -> surface file, for frames that have one

    def _relative(self, file: str | os.PathLike) -> str:
        p = Path(file)
        if p.is_absolute():
            p = Path(os.path.relpath(p, self.path.parent.resolve()))
        return PurePosixPath(*p.parts).as_posix()

    @property
    def times(self) -> list[float]:
        return [t for t, _ in self.frames]

    def add(self, time: float, fluid_file: str | os.PathLike) -> None:
        """Append a frame (file relative to the .pvd's folder, or absolute) and rewrite the .pvd."""
        time = float(time)
        if self.frames and time <= self.frames[-1][0]:
            raise ValueError(f"frame time {time!r} is not after the last frame time {self.frames[-1][0]!r}")
        self.frames.append((time, self._relative(fluid_file)))
        self.write()

    def add_surface(self, time: float, surface_file: str | os.PathLike) -> None:
        """List the surface mesh of the frame at `time` (call write() to rewrite the .pvd)."""
        self.surfaces[float(time)] = self._relative(surface_file)

    def truncate_after(self, time: float) -> list[tuple[float, str]]:
        """Drop frames later than `time` (resume from a checkpoint), rewrite; return the dropped ones."""
        limit = float(time) + 1e-12 * max(1.0, abs(float(time)))  # frame times round-trip exactly via repr
        kept = [f for f in self.frames if f[0] <= limit]
        dropped = self.frames[len(kept):]
        self.frames = kept
        self.surfaces = {t: f for t, f in self.surfaces.items() if t <= limit}
        self.write()
        return dropped

    def to_xml(self) -> str:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 '  <Collection>']
        for t, f in self.frames:
            lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" file="{_attr(f)}"/>')
            if self.boundary_file is not None:
                lines.append(f'    <DataSet timestep="{t!r}" group="" part="1" file="{_attr(self.boundary_file)}"/>')
            if t in self.surfaces:
                lines.append(f'    <DataSet timestep="{t!r}" group="" part="2" file="{_attr(self.surfaces[t])}" '
                             f'name="surface"/>')
        lines += ['  </Collection>', '</VTKFile>', '']
        return "\n".join(lines)

    def write(self) -> None:
        """Atomically rewrite the .pvd (temporary file, fsync, rename)."""
        text = self.to_xml().encode()
        with atomic_path(self.path, "series file") as tmp:
            with open(tmp, "wb") as f:
                f.write(text)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "PvdSeries":
        """Read an existing .pvd written by this class (for resume and rendering)."""
        path = Path(path)
        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            raise OutputError(f"cannot read series file {path} (resolved {path.resolve()}): "
                              f"{' '.join(str(exc).split())}") from exc
        coll = root.find("Collection")
        if root.tag != "VTKFile" or coll is None:
            raise OutputError(f"series file {path} (resolved {path.resolve()}) is not a VTK collection (.pvd)")
        fluid: dict[float, str] = {}
        boundary = None
        surfaces: dict[float, str] = {}
        for ds in coll.iter("DataSet"):
            t = float(ds.get("timestep", "0"))
            part = ds.get("part", "0")
            if part == "0":
                fluid[t] = ds.get("file")
            elif part == "1":
                boundary = ds.get("file")
            elif part == "2":
                surfaces[t] = ds.get("file")
        series = cls(path, None)
        series.boundary_file = boundary
        series.frames = sorted(fluid.items())
        series.surfaces = surfaces
        return series


def _attr(s: str) -> str:
    return s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
