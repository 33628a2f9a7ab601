"""run.json: what ran, with which versions, whether it completed (PySPH `.info` style)."""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import os
import platform
from pathlib import Path

import numpy as np

from ..errors import OutputError
from . import atomic_path

__all__ = ["write_run_json", "read_run_json", "versions", "to_jsonable"]


def to_jsonable(obj):
    """Dataclasses, enums, paths, tuples and numpy values -> plain JSON types (NaN/Inf -> None)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return to_jsonable(obj.value)
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def write_run_json(path: str | os.PathLike, info: dict) -> None:
    """Write `info` (plus `versions` if absent) to `path` atomically, pretty-printed."""
    data = to_jsonable(info)
    data.setdefault("versions", versions())
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    with atomic_path(path, "provenance file") as tmp:
        with open(tmp, "w") as f:
            f.write(text)


def read_run_json(path: str | os.PathLike) -> dict:
    path = Path(path)
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as exc:
        raise OutputError(
            f"cannot read provenance file {path} (resolved {path.resolve()}): {' '.join(str(exc).split())}"
        ) from exc


def versions() -> dict:
    """Versions of Python, ipsph and the libraries that shape the results, and the machine."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in ("ipsph", "numpy", "numba", "vtk", "pyvista", "meshio"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    if out["ipsph"] is None:
        from .._version import __version__

        out["ipsph"] = __version__
    out["platform"] = platform.platform()
    out["cpu_count"] = os.cpu_count()
    return out
