"""Checkpoints: the complete between-steps state of a Simulation, for a bit-identical `--resume`.

A checkpoint is one .npz written atomically (temporary file, fsync, rename) holding

    state.<name>      every per-particle array of ParticleState (x, v, m, id, warm starts, pressure)
    boundary.*        boundary x, psi, m in their current (cell-sorted) order
    grid.*            the neighbour grid (origin, cell, dims) and the list strides
    scalars           time, steps, dt_next (and whether it was clamped), dt_prev, clamped_steps,
                      solver_maxed, frames, threads
    fingerprint       sha256 of the scene without output/render settings, name, source, end_time
    scene_json        that scene dict (to name what changed when a fingerprint differs)
    version           ipsph.__version__

Restoring puts the grid and the boundary order back BEFORE any neighbour search, so the cell
sort of the (already sorted) fluid is the identity and every later pass sees the same
neighbour order as the uninterrupted run; then `method.prepare()` recomputes what a method
derives from positions (DFSPH: densities and factors). With the same thread count the
continuation is bit-identical.
"""
from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import OutputError
from .model import Scene

CHECKPOINT_FILE = "checkpoint.npz"
FORMAT = 2
_EXCLUDED = ("output", "render", "name", "source")  # do not change the physics


def scene_fingerprint_dict(scene: Scene) -> dict:
    """The scene dict that decides the physics: output/render settings, name, source, end_time left out."""
    from .scene import scene_to_dict
    d = {k: v for k, v in scene_to_dict(scene).items() if k not in _EXCLUDED}
    sim = dict(d.get("simulation", {}))
    sim.pop("end_time", None)
    d["simulation"] = sim
    return d


def scene_fingerprint(scene: Scene) -> str:
    text = json.dumps(scene_fingerprint_dict(scene), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass
class Checkpoint:
    """A loaded checkpoint file."""
    path: Path
    arrays: dict[str, np.ndarray]
    scalars: dict
    fingerprint: str
    scene: dict
    version: str

    @property
    def time(self) -> float:
        return float(self.scalars["time"])

    @property
    def steps(self) -> int:
        return int(self.scalars["steps"])


def save(path: Path, sim, *, frames: int, last_frame_time: float | None, solver_maxed: int,
         threads: int) -> None:
    """Write the state of `sim` (between two steps) to `path` atomically (WriteError on failure)."""
    from . import __version__
    from .io import atomic_path
    g = sim.search.grid
    b = sim.boundary
    data = {f"state.{k}": v for k, v in sim.state.arrays().items()}
    data.update({"boundary.x": b.x, "boundary.psi": b.psi, "boundary.m": b.m})
    if g is not None:
        data.update({"grid.origin": g.origin, "grid.cell": g.cell, "grid.dims": g.dims})
    scalars = {"format": FORMAT, "time": sim.time, "steps": sim.steps, "dt_next": sim.dt_next,
               "dt_prev": sim.method.dt_prev, "clamped_steps": int(sim.clamped_steps),
               "next_clamped": bool(sim._clamped),
               "solver_maxed": int(solver_maxed), "frames": int(frames), "last_frame_time": last_frame_time,
               "threads": int(threads), "k_fluid": sim.search.k_fluid, "k_boundary": sim.search.k_boundary,
               "method": sim.scene.method.value}
    # floats go through repr in JSON: exact round trip
    data["scalars"] = np.array(json.dumps(scalars))
    data["fingerprint"] = np.array(scene_fingerprint(sim.scene))
    data["scene_json"] = np.array(json.dumps(scene_fingerprint_dict(sim.scene), sort_keys=True))
    data["version"] = np.array(__version__)
    with atomic_path(path, "checkpoint") as tmp:
        with open(tmp, "wb") as f:   # a file object: np.savez would append ".npz" to a name
            np.savez(f, **data)


def load(path: Path) -> Checkpoint:
    """Read a checkpoint; an unreadable or foreign file is an OutputError (exit 2)."""
    path = Path(path)
    if not path.is_file():
        raise OutputError(f"no checkpoint to resume from: {path} (resolved {path.resolve()}) does not exist; "
                          f"set output.checkpoint_interval, or start afresh with --overwrite")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        scalars = json.loads(str(arrays.pop("scalars")))
        fp = str(arrays.pop("fingerprint"))
        scene = json.loads(str(arrays.pop("scene_json")))
        version = str(arrays.pop("version"))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise OutputError(f"cannot read checkpoint {path} (resolved {path.resolve()}): "
                          f"{' '.join(str(exc).split()) or type(exc).__name__}; start afresh with --overwrite") from exc
    if scalars.get("format") != FORMAT:
        raise OutputError(f"checkpoint {path} has format {scalars.get('format')}, this ipsph reads format "
                          f"{FORMAT}; start afresh with --overwrite")
    return Checkpoint(path, arrays, scalars, fp, scene, version)


def check_compatible(ck: Checkpoint, scene: Scene) -> None:
    """Refuse a checkpoint written by another ipsph version or for a different scene (exit 2)."""
    from . import __version__
    if ck.version != __version__:
        raise OutputError(f"checkpoint {ck.path} was written by ipsph {ck.version}, this is {__version__}; "
                          f"resume with that version or start afresh with --overwrite")
    if ck.fingerprint != scene_fingerprint(scene):
        diff = _differences(ck.scene, scene_fingerprint_dict(scene))
        shown = ", ".join(diff[:5]) + (f" and {len(diff) - 5} more" if len(diff) > 5 else "")
        raise OutputError(f"checkpoint {ck.path} belongs to a different scene (differs in {shown or 'its settings'}); "
                          f"resume with the scene and --set options of the original run, or start afresh "
                          f"with --overwrite")
    if ck.scalars["method"] != scene.method.value:  # covered by the fingerprint; kept explicit
        raise OutputError(f"checkpoint {ck.path} is for method {ck.scalars['method']}")


def _differences(a, b, prefix: str = "") -> list[str]:
    """Dotted key paths where two scene dicts differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _differences(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else str(k))
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += _differences(x, y, f"{prefix}.{i}")
        return out
    return [] if a == b else [prefix or "(root)"]


def restore(scene: Scene, ck: Checkpoint):
    """A Simulation in exactly the checkpointed state (no sampling)."""
    from .neighbours import Grid, cell_ids, counting_sort
    from .simulation import Simulation
    a = ck.arrays
    state = {k[len("state."):]: v for k, v in a.items() if k.startswith("state.")}
    sim = Simulation(scene, state["x"], state["v"], a["boundary.x"], fluid_ids=state["id"])
    # the walls exactly as they were (their volumes were summed in the original order)
    b = sim.boundary
    b.x = np.ascontiguousarray(a["boundary.x"])
    b.psi = np.ascontiguousarray(a["boundary.psi"])
    b.m = np.ascontiguousarray(a["boundary.m"])
    search = sim.search
    s = ck.scalars
    search.k_fluid, search.k_boundary = int(s["k_fluid"]), int(s["k_boundary"])
    search.lists = None
    if "grid.origin" in a:
        g = Grid.__new__(Grid)
        g.origin = np.ascontiguousarray(a["grid.origin"], dtype=np.float64)
        g.cell = np.ascontiguousarray(a["grid.cell"], dtype=np.float64)
        g.dims = np.ascontiguousarray(a["grid.dims"], dtype=np.int64)
        search.grid = g
        # the boundary is already sorted into this grid: the stable sort is the identity
        cells = np.empty(b.n, dtype=np.int64)
        cell_ids(b.x, g.origin, g.inv_cell, g.dims, cells)
        order = np.empty(b.n, dtype=np.int64)
        search.use_boundary_sort(counting_sort(cells, g.n_cells, order))
        if not np.array_equal(order, np.arange(b.n)):
            raise OutputError(f"checkpoint {ck.path} is inconsistent (boundary not sorted into its grid); "
                              f"start afresh with --overwrite")
    else:
        search.grid = None
    sim.state.load(state)
    sim.time = float(s["time"])
    sim.steps = int(s["steps"])
    sim.clamped_steps = int(s["clamped_steps"])
    sim.dt_next = float(s["dt_next"])
    sim._clamped = bool(s.get("next_clamped", False))
    dt_prev = s["dt_prev"]
    sim.method.dt_prev = None if dt_prev is None else float(dt_prev)
    sim.method.prepare()
    return sim

