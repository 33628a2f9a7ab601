"""The output folder before a run: `check_output_folder` refuses an unusable one and creates
nothing; `prepare_output_folder` creates it (and with --overwrite clears the earlier run) once
every check has passed.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from .. import io
from ..errors import OutputError


def check_output_folder(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse an unwritable folder, or one holding an earlier run (unless overwrite/resume).
    Creates and deletes nothing: a refused run leaves no trace (`prepare_output_folder` does that
    once every check has passed)."""
    out = out.expanduser()
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is a file; choose another -o")
    if (out / io.RUN_JSON).exists() and not (overwrite or resume):
        raise OutputError(
            f"output folder {out} holds an earlier run; pass --overwrite to replace it or --resume to continue it"
        )
    if resume and not (out / io.RUN_JSON).exists():
        raise OutputError(
            f"--resume: output folder {out} (resolved {out.resolve()}) holds no earlier run "
            f"to continue; run without --resume"
        )
    existing = out.resolve()
    while not existing.exists():  # the deepest folder that exists must let us create the rest
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(
            f"output folder {out} (resolved {out.resolve()}) is not writable: "
            f"{existing} is {'not a folder' if not existing.is_dir() else 'read-only'}"
        )


# Everything a run (and `ipsph render` / `ipsph plot` into it) writes: --overwrite removes all of it.
WRITTEN_DIRS = (io.FRAMES_DIR, io.RENDERS_DIR, io.PLOTS_DIR, io.SURFACES_DIR, io.BODIES_DIR)
WRITTEN_FILES = (
    io.RUN_PVD,
    io.BOUNDARY_VTU,
    io.BOUNDARY_SURFACE,
    io.STATS_CSV,
    io.GAUGES_CSV,
    io.GAUGES_FRAMES_CSV,
    io.RUN_JSON,
    io.CHECKPOINT_FILE,
    io.BODIES_CSV,
    io.video_file("mp4"),
    io.video_file("gif"),
    io.PARAVIEW_SCRIPT,
    *(p.series for p in io.PARTS if p.series),
)


def prepare_output_folder(out: Path, overwrite: bool, resume: bool) -> None:
    """Create the folder, prove it writable, and with --overwrite remove the earlier run's files."""
    out = out.expanduser()
    io.check_writable(out)
    if overwrite and not resume:
        for name in WRITTEN_DIRS:
            shutil.rmtree(out / name, ignore_errors=True)
        for name in WRITTEN_FILES:
            (out / name).unlink(missing_ok=True)
