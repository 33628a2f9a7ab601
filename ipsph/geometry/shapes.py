"""A scene entity's shape as geometry: box corners, its mesh (read and checked once per process),
its surface, what lies inside it, and the disk-cache key of its samples. No SPH here.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ipsph import config as model
from ipsph.errors import ConfigError
from ipsph.geometry import cache as sample_cache
from ipsph.geometry import meshes
from ipsph.geometry.inside import inside_mesh
from ipsph.params import spacing

if TYPE_CHECKING:
    import pyvista as pv

SAMPLER_VERSION = "ipsph-sampling-5"  # part of every sample-cache key: change it when samples change


def check_radius(radius: float) -> float:
    r = float(radius)
    if not (math.isfinite(r) and r > 0.0):
        raise ConfigError(f"particle_radius = {radius!r}: must be a positive finite length in metres")
    return r


def scaled_box(spec) -> tuple[np.ndarray, np.ndarray]:
    """The box corners with the spec's scale applied (before rotation and translation)."""
    if spec.box_min is None or spec.box_max is None:
        raise ConfigError(f"{spec.name}: shape 'box' needs box_min and box_max")
    s = np.asarray(spec.transform.scale, dtype=np.float64)
    a = np.asarray(spec.box_min, dtype=np.float64) * s
    b = np.asarray(spec.box_max, dtype=np.float64) * s
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    if not np.all(hi > lo):
        raise ConfigError(
            f"{spec.name}: box_min {tuple(spec.box_min)} and box_max {tuple(spec.box_max)} "
            f"(scale {tuple(spec.transform.scale)}) enclose no volume; box_max must exceed box_min"
        )
    return lo, hi


def rigid_part(t: model.Transform) -> model.Transform:
    """The rotation and translation of t, without its scale."""
    return model.Transform(translate=t.translate, rotate_axis=t.rotate_axis, rotate_deg=t.rotate_deg)


def mesh_path(spec) -> Path:
    if spec.mesh is None:
        raise ConfigError(f"{spec.name}: shape 'mesh' needs a mesh file")
    return Path(spec.mesh)


def shape_of(spec) -> str:
    if spec.shape not in ("box", "mesh"):
        raise ConfigError(f"{spec.name}: shape = {spec.shape!r}; use 'box' or 'mesh'")
    return spec.shape


_PREPARED: dict = {}


def prepared_mesh(path: Path, transform: model.Transform, *, need_closed: bool, allow_open: bool):
    """meshes.prepare_mesh, memoised in-process on (file identity, transform, flags)."""
    p = path.expanduser().resolve()
    try:
        st = p.stat()
        ident = (str(p), st.st_mtime_ns, st.st_size)
    except OSError:
        ident = (str(p), None, None)
    key = (ident, transform, need_closed, allow_open)
    if key not in _PREPARED:
        if len(_PREPARED) > 16:
            _PREPARED.clear()
        _PREPARED[key] = meshes.prepare_mesh(path, transform, need_closed=need_closed, allow_open=allow_open)
    return _PREPARED[key]


def mesh_report(spec) -> "meshes.MeshReport":
    """The mesh checks' report (bounds, volume, closedness, notes) of a mesh fluid or wall, from the
    in-process memo that sampling uses too: the pre-flight checks read no mesh a second time."""
    if isinstance(spec, model.FluidSpec):
        return prepared_mesh(mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)[1]
    return prepared_mesh(mesh_path(spec), spec.transform, need_closed=False, allow_open=True)[1]


def mesh_notes(spec) -> list[str]:
    """What the mesh checks did to a mesh fluid or wall (e.g. inverted normals flipped), one line each."""
    if shape_of(spec) != "mesh":
        return []
    return [f"{spec.name}: {note}" for note in mesh_report(spec).notes]


def boundary_surface(spec: model.BoundarySpec) -> "pv.PolyData":
    """The transformed wall surface as triangles (for rendering)."""
    if shape_of(spec) == "box":
        lo, hi = scaled_box(spec)
        return meshes.transform_mesh(meshes.box_mesh(tuple(lo), tuple(hi)), rigid_part(spec.transform))
    return prepared_mesh(mesh_path(spec), spec.transform, need_closed=False, allow_open=True)[0].copy()


# ----------------------------------------------------------------------------- inside
def _inside_boundary(points: np.ndarray, spec: model.BoundarySpec, r: float) -> np.ndarray:
    if shape_of(spec) == "box":
        lo, hi = scaled_box(spec)
        local = meshes.inverse_transform_points(points, rigid_part(spec.transform))
        return np.all((local > lo) & (local < hi), axis=1)
    mesh, report = prepared_mesh(mesh_path(spec), spec.transform, need_closed=False, allow_open=True)
    return inside_mesh(points, mesh, spacing(r), closed=report.closed)


def solid_mask(points: np.ndarray, boundaries: Sequence[model.BoundarySpec], radius: float) -> np.ndarray:
    """True where a point is inside no obstacle and, when there are containers, inside at least one."""
    r = check_radius(radius)
    p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    keep = np.ones(len(p), dtype=bool)
    in_container = np.zeros(len(p), dtype=bool)
    has_container = False
    for spec in boundaries:
        inside = _inside_boundary(p, spec, r)
        if spec.role == model.Role.OBSTACLE:
            keep &= ~inside
        else:
            has_container = True
            in_container |= inside
    return keep & in_container if has_container else keep


# ----------------------------------------------------------------------------- cache
def cache_key(kind: str, spec, radius: float) -> str:
    """The disk-cache key of a fluid's or wall's samples (sample_cache.cache_key)."""
    return sample_cache.cache_key(kind, spec, radius, SAMPLER_VERSION, mesh_path(spec) if spec.shape != "box" else None)


def cached_samples(kind: str, spec, r: float, use_cache: bool, sample, extra=()) -> np.ndarray:
    shape_of(spec)
    if not use_cache:
        return sample()
    key = cache_key(kind, spec, r)
    if extra:
        key = hashlib.sha256((key + repr(extra)).encode()).hexdigest()
    return sample_cache.cached(f"{kind}-{key}", sample)
