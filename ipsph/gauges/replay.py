"""`ipsph gauge OUT [--scene FILE]`: gauges measured on the frames of a finished (or running) run.

The run's scene comes from OUT/run.json; the [[gauge]] tables from FILE (only those: any other
table in FILE is left to the run's scene), or, without FILE, the run's own gauges. Each frame
listed in run.pvd is read back and handed to the same `Gauges.values` a run samples with, so at
frame times the two agree exactly (the run reads the fluid at the frames' float32 precision,
`kernels.FRAME_DTYPE`). Walls for force gauges: walls.FrameWalls. Bad gauge tables exit 2
before anything is written; the result is a CSV beside gauges.csv (OUT/gauges_frames.csv unless
`output` says otherwise) and its plot (OUT/plots/<name>.png).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .. import io
from ..errors import ConfigError, OutputError
from .log import GaugeCSV
from .placement import check_placement
from .sampler import Gauges

# the frame fields each kind of gauge reads (mass, when left out, is the scene's one fluid mass)
_NEEDS = {
    "pressure": ("pressure", "density"),
    "velocity": ("velocity", "density"),
    "density": ("density",),
    "level": ("density",),
    "level_max": ("density",),
    "flow": ("velocity", "density"),
    "force": ("pressure", "density"),
    "torque": ("pressure", "density"),
}


def gauge_scene(out: Path, gauges_file: Path | None):
    """The run's scene (run.json) with the [[gauge]] tables of `gauges_file` (or its own), validated."""
    from ..io.provenance import read_run_json
    from ..scene import read_toml, scene_from_dict

    info = read_run_json(out / io.RUN_JSON)
    data = dict(info.get("scene") or {})
    if not data:
        raise OutputError(f"{out / io.RUN_JSON} holds no scene: give the output folder of `ipsph run`")
    source = Path(data["source"]) if data.get("source") else None
    if gauges_file is not None:
        tables = read_toml(gauges_file)
        data["gauge"] = tables.get("gauge", [])
        source = Path(gauges_file)
    if not data.get("gauge"):
        where = gauges_file if gauges_file is not None else out / io.RUN_JSON
        raise ConfigError(f"{where}: no [[gauge]] tables to measure (docs/gauges.md)")
    data.pop("source", None)
    scene = scene_from_dict(data, Path.cwd(), source=source)
    check_placement(scene)
    return scene


def replay(out: str | Path, gauges_file: str | Path | None = None, output: str | Path | None = None) -> Path:
    """Measure the gauges on every frame of `out`; returns the CSV written."""
    from ..io import vtu
    from ..io.pvd import PvdSeries

    out = Path(out)
    if not (out / io.RUN_PVD).is_file():
        raise OutputError(f"{out} (resolved {out.resolve()}) holds no run.pvd: give the output folder of `ipsph run`")
    scene = gauge_scene(out, None if gauges_file is None else Path(gauges_file))
    frames = PvdSeries.load(out / io.RUN_PVD).frames
    if not frames:
        raise OutputError(f"{out / io.RUN_PVD} lists no frames yet")
    first = vtu.read_particles(out / frames[0][1])[1]
    for i, g in enumerate(scene.gauges):
        for q in g.quantities:
            missing = [f for f in _NEEDS[q] if f not in first]
            if missing:
                raise ConfigError(
                    f"gauge[{i}].quantities: {q!r} needs the frames' {', '.join(missing)} field, which this run did "
                    f"not write (output.fields)"
                )
    walls = _frame_walls(out, scene) if any(g.kind == "force" for g in scene.gauges) else None
    gauges = Gauges(scene, walls)
    target = Path(output) if output is not None else out / io.GAUGES_FRAMES_CSV
    csv = GaugeCSV(target, gauges.headers)
    try:
        for t, name in frames:
            x, fields, tv = vtu.read_particles(out / name)
            t = t if tv is None else tv  # the frame's own Float64 time: the run's clock exactly
            n = len(x)
            x = x.astype(np.float64)

            def field(key, shape=(), fields=fields, n=n):
                a = fields.get(key)
                return np.zeros((n, *shape)) if a is None else np.ascontiguousarray(a, dtype=np.float64)

            m = field("mass") if "mass" in fields else np.full(n, scene.fluid_mass)
            csv.write(t, gauges.values(t, x, field("velocity", (3,)), field("density"), field("pressure"), m))
    finally:
        csv.close()
    return target


def _frame_walls(out: Path, scene):
    from ..io import vtu
    from .walls import FrameWalls

    if not (out / io.BOUNDARY_VTU).is_file():
        raise OutputError(f"{out} lacks {io.BOUNDARY_VTU}: a force gauge needs the run's wall particles")
    bx, fields, _ = vtu.read_particles(out / io.BOUNDARY_VTU)
    bodies = None
    if any(b.dynamic for b in scene.boundaries):
        from ..io.bodies import read_bodies

        if not (out / io.BODIES_CSV).is_file():
            raise OutputError(f"{out} lacks {io.BODIES_CSV}: a force gauge on a rigid body needs its poses")
        bodies = read_bodies(out / io.BODIES_CSV)
    return FrameWalls(scene, bx, fields["volume"], bodies)


def main(out: Path, gauges_file: Path | None, output: Path | None) -> int:
    """The command: measure, write, plot, say where."""
    from .plot import plot_gauges

    path = replay(out, gauges_file, output)
    print(path)
    try:
        png = plot_gauges(
            path,
            Path(out) / io.PLOTS_DIR / f"{path.stem}.png",
            under=Path(out) / io.GAUGES_CSV,
            title=f"Gauges on the frames of {out} (grey: the run's own, every step)",
        )
        print(png)
    except Exception as exc:  # noqa: BLE001 - the numbers are written; a plot failure is a warning
        print(f"ipsph: warning: gauges not plotted: {' '.join(str(exc).split())}", file=sys.stderr)
    return 0
