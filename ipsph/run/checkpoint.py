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

from ..config import Scene
from ..errors import OutputError
from ..io import CHECKPOINT_FILE  # noqa: F401 - where a run folder keeps it

FORMAT = 2
_EXCLUDED = ("output", "render", "name", "source")  # do not change the physics


def scene_fingerprint_dict(scene: Scene) -> dict:
    """The scene dict that decides the physics: output/render settings, name, source, end_time left out,
    and where it runs (simulation.backend, .device: a CPU run may continue on a GPU; precision stays)."""
    from ..scene import scene_to_dict

    d = {k: v for k, v in scene_to_dict(scene).items() if k not in _EXCLUDED}
    sim = dict(d.get("simulation", {}))
    for key in ("end_time", "backend", "device"):
        sim.pop(key, None)
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


def save(path: Path, sim, *, frames: int, last_frame_time: float | None, solver_maxed: int, threads: int) -> None:
    """Write `sim.state_dict()` (between two steps) to `path` atomically (WriteError on failure)."""
    from .._version import __version__
    from ..io import atomic_path

    sd = sim.state_dict()
    data = {f"state.{k}": v for k, v in sd["particles"].items()}
    data.update({f"boundary.{k}": v for k, v in sd["boundary"].items()})
    data.update({f"walls.{k}": v for k, v in sd.get("walls", {}).items()})  # moving walls (ipsph.boundary.rigid)
    search, clock = sd["search"], sd["clock"]
    if search["grid"] is not None:
        data.update({f"grid.{k}": v for k, v in search["grid"].items()})
    scalars = {
        "format": FORMAT,
        "time": clock["time"],
        "steps": clock["steps"],
        "dt_next": clock["dt_next"],
        "dt_prev": sd["method"]["dt_prev"],
        "clamped_steps": clock["clamped_steps"],
        "next_clamped": clock["next_clamped"],
        "solver_maxed": int(solver_maxed),
        "frames": int(frames),
        "last_frame_time": last_frame_time,
        "threads": int(threads),
        "k_fluid": search["k_fluid"],
        "k_boundary": search["k_boundary"],
        "method": sim.scene.method.value,
        "flow": sd.get("flow"),
    }
    # floats go through repr in JSON: exact round trip
    data["scalars"] = np.array(json.dumps(scalars))
    data["fingerprint"] = np.array(scene_fingerprint(sim.scene))
    data["scene_json"] = np.array(json.dumps(scene_fingerprint_dict(sim.scene), sort_keys=True))
    data["version"] = np.array(__version__)
    with atomic_path(path, "checkpoint") as tmp:
        with open(tmp, "wb") as f:  # a file object: np.savez would append ".npz" to a name
            np.savez(f, **data)


def load(path: Path) -> Checkpoint:
    """Read a checkpoint; an unreadable or foreign file is an OutputError (exit 2)."""
    path = Path(path)
    if not path.is_file():
        raise OutputError(
            f"no checkpoint to resume from: {path} (resolved {path.resolve()}) does not exist; "
            f"set output.checkpoint_interval, or start afresh with --overwrite"
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        scalars = json.loads(str(arrays.pop("scalars")))
        fp = str(arrays.pop("fingerprint"))
        scene = json.loads(str(arrays.pop("scene_json")))
        version = str(arrays.pop("version"))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise OutputError(
            f"cannot read checkpoint {path} (resolved {path.resolve()}): "
            f"{' '.join(str(exc).split()) or type(exc).__name__}; start afresh with --overwrite"
        ) from exc
    if scalars.get("format") != FORMAT:
        raise OutputError(
            f"checkpoint {path} has format {scalars.get('format')}, this ipsph reads format "
            f"{FORMAT}; start afresh with --overwrite"
        )
    return Checkpoint(path, arrays, scalars, fp, scene, version)


def check_compatible(ck: Checkpoint, scene: Scene) -> None:
    """Refuse a checkpoint written by another ipsph version or for a different scene (exit 2)."""
    from .._version import __version__

    if ck.version != __version__:
        raise OutputError(
            f"checkpoint {ck.path} was written by ipsph {ck.version}, this is {__version__}; "
            f"resume with that version or start afresh with --overwrite"
        )
    if ck.fingerprint != scene_fingerprint(scene):
        diff = _differences(ck.scene, scene_fingerprint_dict(scene))
        shown = ", ".join(diff[:5]) + (f" and {len(diff) - 5} more" if len(diff) > 5 else "")
        raise OutputError(
            f"checkpoint {ck.path} belongs to a different scene (differs in {shown or 'its settings'}); "
            f"resume with the scene and --set options of the original run, or start afresh "
            f"with --overwrite"
        )


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


def state_dict(ck: Checkpoint) -> dict:
    """The checkpoint as `Simulation.state_dict()` wrote it."""
    a, s = ck.arrays, ck.scalars

    def part(prefix):
        return {k[len(prefix) :]: v for k, v in a.items() if k.startswith(prefix)}

    grid = part("grid.")
    return {
        "particles": part("state."),
        "boundary": part("boundary."),
        "search": {"k_fluid": s["k_fluid"], "k_boundary": s["k_boundary"], "grid": grid or None},
        "method": {"dt_prev": s["dt_prev"]},
        "clock": {
            "time": s["time"],
            "steps": s["steps"],
            "clamped_steps": s["clamped_steps"],
            "dt_next": s["dt_next"],
            "next_clamped": s.get("next_clamped", False),
        },
        **({"flow": s["flow"]} if s.get("flow") else {}),
        **({"walls": part("walls.")} if part("walls.") else {}),
    }


def restore(scene: Scene, ck: Checkpoint):
    """A Simulation in exactly the checkpointed state (no sampling)."""
    from ..simulation import Simulation

    sd = state_dict(ck)
    p = sd["particles"]
    capacity = None
    if scene.emitters:  # what it holds plus what is still to come by this run's end_time
        from ..flow import resumed_capacity

        capacity = resumed_capacity(scene, len(p["x"]), sd.get("flow"))
    sim = Simulation(scene, p["x"], p["v"], sd["boundary"]["x"], fluid_ids=p["id"], capacity=capacity, settle=False)
    try:
        sim.load_state_dict(sd)
    except (ValueError, KeyError) as exc:
        raise OutputError(f"checkpoint {ck.path} is inconsistent ({exc}); start afresh with --overwrite") from exc
    return sim
