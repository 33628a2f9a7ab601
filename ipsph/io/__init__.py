"""Output folder writers: VTU frames, the PVD series, stats.csv and run.json provenance.

Layout of an output folder OUT (fixed; the runner fills it, `ipsph render` reads it):

    OUT/run.pvd                   per timestep one named DataSet per part of PARTS (fluid, boundary, ...)
    OUT/fluid.pvd                 the fluid frames alone (one series per per-frame part)
    OUT/frames/fluid_000000.vtu   one per frame, binary raw appended (zlib level 1 on request)
    OUT/boundary.vtu              boundary particles, written once (fields `volume`, `id`)
    OUT/boundary_surface.vtp      the transformed boundary meshes, for renders
    OUT/surfaces/surface_000000.vtp   the fluid's surface mesh per frame (output.surface, `ipsph surface`)
    OUT/bodies/bodies_000000.vtp  the moving walls' and rigid bodies' surfaces per frame (io.bodies)
    OUT/bodies.csv                one row per moving wall per step (io.bodies.BODIES_COLUMNS)
    OUT/stats.csv                 one row per step
    OUT/gauges.csv                one row per gauge sample ([[gauge]], ipsph.gauges)
    OUT/gauges_frames.csv         `ipsph gauge OUT`: the gauges measured on the frames
    OUT/run.json                  provenance
    OUT/paraview_view.py          a ParaView script that opens the run with its settings (ipsph.post.paraview)
    OUT/renders/frame_000000.png, OUT/plots/*.png, OUT/video.mp4|gif

Every file that a reader may open while the run goes on is replaced atomically
(temporary name in the same folder, fsync, os.replace), so a crash or a full disk
leaves the previous version intact and never a partial file under the final name.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..errors import WriteError

__all__ = [
    "FRAMES_DIR",
    "RUN_PVD",
    "BOUNDARY_VTU",
    "BOUNDARY_SURFACE",
    "STATS_CSV",
    "RUN_JSON",
    "RENDERS_DIR",
    "PLOTS_DIR",
    "SURFACES_DIR",
    "PARAVIEW_SCRIPT",
    "Part",
    "PARTS",
    "part",
    "frame_file",
    "surface_file",
    "atomic_path",
    "check_writable",
    "BODIES_DIR",
    "BODIES_CSV",
    "CHECKPOINT_FILE",
    "bodies_file",
    "render_file",
    "video_file",
    "GAUGES_CSV",
    "GAUGES_FRAMES_CSV",
]

RUN_PVD = "run.pvd"
FRAMES_DIR = "frames"
BOUNDARY_VTU = "boundary.vtu"
BOUNDARY_SURFACE = "boundary_surface.vtp"
STATS_CSV = "stats.csv"
RUN_JSON = "run.json"
RENDERS_DIR = "renders"
PLOTS_DIR = "plots"
SURFACES_DIR = "surfaces"
PARAVIEW_SCRIPT = "paraview_view.py"
BODIES_DIR = "bodies"
BODIES_CSV = "bodies.csv"
CHECKPOINT_FILE = "checkpoint.npz"
GAUGES_CSV = "gauges.csv"
GAUGES_FRAMES_CSV = "gauges_frames.csv"  # `ipsph gauge OUT`: the gauges measured on the frames


@dataclass(frozen=True)
class Part:
    """One part of run.pvd: a named block of every timestep."""

    name: str
    file: str | None = None  # the one file of a part written once; None: a file per frame

    @property
    def series(self) -> str | None:
        """File name of the part's own series beside run.pvd (per-frame parts), else None."""
        return f"{self.name}.pvd" if self.file is None else None


# The parts of run.pvd in block order, each declared here once: run.pvd names its blocks after
# them (ParaView shows /Root/fluid, ...), and each per-frame part also gets its own series
# OUT/<name>.pvd, which ParaView's SPH filters and Point Gaussian take without ExtractBlock.
PARTS = (
    Part("fluid"),
    Part("surface"),
    Part("boundary", BOUNDARY_VTU),
    Part("boundary_surface", BOUNDARY_SURFACE),
    Part("bodies"),  # moving walls and rigid bodies: their surfaces, a file per frame
)


def part(name: str) -> Part:
    """The declared part called `name` (ValueError for an undeclared one)."""
    for p in PARTS:
        if p.name == name:
            return p
    raise ValueError(f"{name!r} is not a part of run.pvd; declared: {', '.join(p.name for p in PARTS)}")


def check_writable(out: Path) -> None:
    """Create the folder `out` and prove it writable (a probe file), else a one-line OutputError."""
    from ..errors import OutputError

    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".ipsph-write-test-{os.getpid()}"
        probe.write_bytes(b"ok")
        probe.unlink()
    except OSError as exc:
        raise OutputError(
            f"output folder {out} (resolved {out.resolve()}) is not writable: {exc.strerror or exc}"
        ) from exc


def frame_file(index: int) -> str:
    """Relative path of fluid frame `index` inside an output folder."""
    return f"{FRAMES_DIR}/fluid_{index:06d}.vtu"


def bodies_file(index: int) -> str:
    """Relative path of the moving walls' surfaces of frame `index`."""
    return f"{BODIES_DIR}/bodies_{index:06d}.vtp"


def render_file(index: int) -> str:
    """Relative path of the PNG render of frame `index`."""
    return f"{RENDERS_DIR}/frame_{index:06d}.png"


def video_file(fmt: str) -> str:
    """File name of the video of the renders (fmt: mp4 | gif)."""
    return f"video.{fmt}"


def surface_file(index: int, fmt: str = "vtp") -> str:
    """Relative path of the surface mesh of frame `index` (fmt: vtp | obj | ply)."""
    return f"{SURFACES_DIR}/surface_{index:06d}.{fmt}"


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # some filesystems / platforms cannot open a directory
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | os.PathLike, what: str = "file"):
    """Yield a temporary path beside `path`; on success fsync it and rename it over `path`.

    On any exception the temporary file is removed, `path` keeps its previous content, and
    the error is raised as a one-line `WriteError` naming the file (WriteError passes through).
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except BaseException as exc:
        try:
            tmp.unlink()
        except OSError:
            pass
        if isinstance(exc, WriteError) or not isinstance(exc, Exception):
            raise
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise WriteError(
            f"cannot write {what} {path} (resolved {path.resolve()}): {reason}; "
            f"check free disk space and write permission"
        ) from exc
