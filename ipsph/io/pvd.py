"""The ParaView collection (.pvd) that strings the frames into one time series.

Per timestep one DataSet per part of `PARTS` (io/__init__.py) that the run has: the fluid frame,
its surface mesh once it has one (output.surface, `ipsph surface`), the boundary particles and the
wall surface (the same files at every timestep), each with the part's `name`, so ParaView shows the blocks as /Root/fluid, /Root/boundary, ... (pyvista's
PVDReader reads the same file as one multiblock series). Each per-frame part also gets its own
series beside run.pvd (`fluid.pvd`), which ParaView's SPH filters and Point Gaussian take
directly. File names inside are relative to the .pvd's folder. The files are rewritten
atomically after every frame, so a reader (ParaView, `ipsph render`) always sees a complete,
valid series.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path, PurePosixPath

from .. import io as _io  # PARTS, read when used
from ..errors import OutputError
from . import atomic_path

__all__ = ["PvdSeries"]

_FLUID = "fluid"


class PvdSeries:
    """Frames (time, fluid file) of one run, mirrored to `path` (and the per-part series) on every `add`.

    `static` maps parts written once (PARTS with a `file`) to their file; `boundary_file` is
    shorthand for static={"boundary": boundary_file}. Parts left out (or None) are not listed.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        boundary_file: str | os.PathLike | None = None,
        *,
        static: dict[str, str | os.PathLike | None] | None = None,
    ):
        self.path = Path(path)
        self.static: dict[str, str] = {}
        for name, file in {"boundary": boundary_file, **(static or {})}.items():
            if _io.part(name).file is None:
                raise ValueError(f"part {name!r} has a file per frame; give it to add()")
            if file is not None:
                self.static[name] = self._relative(file)
        self.frames: list[tuple[float, str]] = []
        self.frame_parts: list[dict[str, str]] = []  # per frame: the other per-frame parts' files

    @property
    def boundary_file(self) -> str | None:
        return self.static.get("boundary")

    def _relative(self, file: str | os.PathLike) -> str:
        p = Path(file)
        if p.is_absolute():
            p = Path(os.path.relpath(p, self.path.parent.resolve()))
        return PurePosixPath(*p.parts).as_posix()

    @property
    def times(self) -> list[float]:
        return [t for t, _ in self.frames]

    def add(self, time: float, fluid_file: str | os.PathLike, **parts: str | os.PathLike) -> None:
        """Append a frame (files relative to the .pvd's folder, or absolute) and rewrite the .pvd.

        `parts` gives the frame's files of other per-frame parts, by part name."""
        time = float(time)
        if self.frames and time <= self.frames[-1][0]:
            raise ValueError(f"frame time {time!r} is not after the last frame time {self.frames[-1][0]!r}")
        for name in parts:
            if _io.part(name).file is not None:
                raise ValueError(f"part {name!r} is written once; give it as `static`")
        self.frames.append((time, self._relative(fluid_file)))
        self.frame_parts.append({n: self._relative(f) for n, f in parts.items()})
        self.write()

    def add_surface(self, time: float, surface_file: str | os.PathLike) -> None:
        """List the surface mesh of the frame at `time` (surfaces arrive after their frame;
        call write() to rewrite the .pvd)."""
        i = self.times.index(float(time))
        self.frame_parts[i]["surface"] = self._relative(surface_file)

    @property
    def surfaces(self) -> dict[float, str]:
        """{frame time: surface file} of the frames that have a surface."""
        return {t: fp["surface"] for (t, _), fp in zip(self.frames, self.frame_parts) if "surface" in fp}

    def truncate_after(self, time: float) -> list[tuple[float, str]]:
        """Drop frames later than `time` (resume from a checkpoint), rewrite; return the dropped ones."""
        limit = float(time) + 1e-12 * max(1.0, abs(float(time)))  # frame times round-trip exactly via repr
        kept = [f for f in self.frames if f[0] <= limit]
        dropped = self.frames[len(kept) :]
        self.frames = kept
        self.frame_parts = self.frame_parts[: len(kept)]
        self.write()
        return dropped

    def _datasets(self, index: int) -> list[tuple[str, str]]:
        """(part name, file) of frame `index`, in PARTS order."""
        files = {_FLUID: self.frames[index][1], **self.frame_parts[index], **self.static}
        return [(p.name, files[p.name]) for p in _io.PARTS if p.name in files]

    def to_xml(self, only: str | None = None) -> str:
        """run.pvd's text; with `only`, the series of that one part."""
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
            "  <Collection>",
        ]
        for i, (t, _) in enumerate(self.frames):
            sets = [d for d in self._datasets(i) if only is None or d[0] == only]
            for k, (name, f) in enumerate(sets):
                lines.append(f'    <DataSet timestep="{t!r}" group="" part="{k}" name="{name}" file="{_attr(f)}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        return "\n".join(lines)

    def series_files(self) -> dict[str, Path]:
        """The per-part series written beside run.pvd: {part name: path}."""
        names = {_FLUID} | {n for fp in self.frame_parts for n in fp}
        return {p.name: self.path.with_name(p.series) for p in _io.PARTS if p.series and p.name in names}

    def write(self) -> None:
        """Atomically rewrite the .pvd and the per-part series (temporary file, fsync, rename)."""
        for name, path in [(None, self.path), *self.series_files().items()]:
            text = self.to_xml(name).encode()
            with atomic_path(path, "series file") as tmp:
                with open(tmp, "wb") as f:
                    f.write(text)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "PvdSeries":
        """Read an existing .pvd written by this class (for resume and rendering).

        Blocks are told apart by `name`; files without names (older runs) by
        `part`: 0 the fluid, 1 the boundary, 2 a surface."""
        path = Path(path)
        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            raise OutputError(
                f"cannot read series file {path} (resolved {path.resolve()}): {' '.join(str(exc).split())}"
            ) from exc
        coll = root.find("Collection")
        if root.tag != "VTKFile" or coll is None:
            raise OutputError(f"series file {path} (resolved {path.resolve()}) is not a VTK collection (.pvd)")
        declared = {p.name: p for p in _io.PARTS}
        per_frame: dict[float, dict[str, str]] = {}
        static: dict[str, str] = {}
        for ds in coll.iter("DataSet"):
            t = float(ds.get("timestep", "0"))
            name = ds.get("name") or {"0": _FLUID, "1": "boundary", "2": "surface"}.get(ds.get("part", "0"))
            if name not in declared:
                continue
            if declared[name].file is None:
                per_frame.setdefault(t, {})[name] = ds.get("file")
            else:
                static[name] = ds.get("file")
        series = cls(path)
        series.static = static
        for t, files in sorted(per_frame.items()):
            if _FLUID in files:
                series.frames.append((t, files.pop(_FLUID)))
                series.frame_parts.append(files)
        return series


def _attr(s: str) -> str:
    return s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")


def frame_index(file: str, position: int) -> int:
    """The frame number in a frame file's name (`frames/particles_0012.vtu` -> 12), else its position."""
    m = re.search(r"(\d+)\.vtu$", file)
    return int(m.group(1)) if m else position
