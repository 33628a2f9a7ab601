"""Geometry -> particles: fluid lattices, boundary surface samples, overlap removal, a disk cache.

Conventions (r particle radius, d = 2r):
- Fluid box (SPlisHSPlasH FluidBlocks, denseMode 0): the scale S is applied to the corners, per axis
  n = round(extent / d) - 1 particles at min + d + i d, then x' = R p + t for every lattice point p.
- Fluid mesh: a cubic lattice of spacing d centred on the transformed mesh's bounding box,
  n = round(extent / d) points per axis (so the outer layers sit about d/2 inside the box faces and
  a flat face aligned with the box is not over-counted), kept where `inside.inside_mesh` says
  inside. Count · d³ then estimates the mesh volume without bias.
- Boundary box (also a mesh that is an axis-aligned box after scaling, e.g. UnitBox.obj): a regular
  grid per face of the box moved 0.1 d behind its surface (grown for a container, shrunk for an
  obstacle: BOX_WALL_OFFSET_FACTOR), n = ceil(edge / 1.5r) intervals per edge, edge and corner
  nodes once.
- Boundary mesh: candidates = feature-edge corners, then feature edges (30°) sampled every r/5,
  then face samples of vtkPolyDataPointSampler (Distance r/5); a greedy pass in that priority order
  keeps a candidate when no kept sample lies within r (the Poisson-disk rule of
  vtkPoissonDiskSampler, seeded with the edges, which that filter cannot take). The result has
  nearest-neighbour spacing >= r and leaves no candidate farther than r from a sample.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ipsph import meshes, model, sample_cache
from ipsph.inside import inside_mesh
from ipsph.params import spacing
from ipsph.point_kernels import nearest_distance, poisson_filter  # noqa: F401 (sampling's API)
from ipsph.errors import ConfigError

if TYPE_CHECKING:
    import pyvista as pv

SAMPLER_VERSION = "ipsph-sampling-3"
BOUNDARY_SPACING_FACTOR = 1.5  # box-grid spacing <= 1.5 r (method.md section 1)
# Box walls: the grid sits this fraction of d = 2r behind the wall surface (outside a container,
# inside an obstacle). With Akinci's volumes a layer on the surface makes the first fluid layer,
# d away, read 1.064 rho0; 0.1 d back it reads rho0 to 1e-4 (method.md section 1, "Walls").
BOX_WALL_OFFSET_FACTOR = 0.1
POISSON_RADIUS_FACTOR = 1.0  # general meshes: samples at least r apart, none missing beyond r
CANDIDATE_SPACING_FACTOR = 0.2  # candidate density r/5 (ecosystem.md)
FEATURE_ANGLE_DEG = 30.0
# Fluid particles closer than d = 2r to a wall particle are removed: the first lattice layer sits
# d from the walls (method.md: particles at r from a wall make DFSPH/IPSPH blow up). The factor
# slightly below 1 keeps a layer that is exactly d away despite rounding.
OVERLAP_DISTANCE_FACTOR = 2.0 * (1.0 - 1e-6)


def default_overlap_distance(radius: float) -> float:
    """min_dist for remove_overlaps: d = 2r (less a rounding tolerance)."""
    return OVERLAP_DISTANCE_FACTOR * radius


# ----------------------------------------------------------------------------- spec helpers
def _check_radius(radius: float) -> float:
    r = float(radius)
    if not (math.isfinite(r) and r > 0.0):
        raise ConfigError(f"particle_radius = {radius!r}: must be a positive finite length in metres")
    return r


def _scaled_box(spec) -> tuple[np.ndarray, np.ndarray]:
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


def _rigid(t: model.Transform) -> model.Transform:
    """The rotation and translation of t, without its scale."""
    return model.Transform(translate=t.translate, rotate_axis=t.rotate_axis, rotate_deg=t.rotate_deg)


def _mesh_path(spec) -> Path:
    if spec.mesh is None:
        raise ConfigError(f"{spec.name}: shape 'mesh' needs a mesh file")
    return Path(spec.mesh)


def _shape(spec) -> str:
    if spec.shape not in ("box", "mesh"):
        raise ConfigError(f"{spec.name}: shape = {spec.shape!r}; use 'box' or 'mesh'")
    return spec.shape


_PREPARED: dict = {}


def _prepared(path: Path, transform: model.Transform, *, need_closed: bool, allow_open: bool):
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
        return _prepared(_mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)[1]
    return _prepared(_mesh_path(spec), spec.transform, need_closed=False, allow_open=True)[1]


def mesh_notes(spec) -> list[str]:
    """What the mesh checks did to a mesh fluid or wall (e.g. inverted normals flipped), one line each."""
    if _shape(spec) != "mesh":
        return []
    return [f"{spec.name}: {note}" for note in mesh_report(spec).notes]


# ----------------------------------------------------------------------------- fluid
def _fluid_box_counts(lo: np.ndarray, hi: np.ndarray, d: float) -> np.ndarray:
    # floor(x + 0.5 + eps): round half up, robust to 19.999999 and 13.5 alike
    return np.maximum(np.floor((hi - lo) / d + 0.5 + 1e-9).astype(np.int64) - 1, 0)


def _grid(origin: np.ndarray, counts: np.ndarray, d: float) -> np.ndarray:
    axes = [origin[k] + d * np.arange(counts[k], dtype=np.float64) for k in range(3)]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    return np.ascontiguousarray(np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1))


def _mesh_lattice(bounds, d: float) -> tuple[np.ndarray, np.ndarray]:
    lo = np.array(bounds[0::2], dtype=np.float64)
    hi = np.array(bounds[1::2], dtype=np.float64)
    counts = np.maximum(np.floor((hi - lo) / d + 0.5 + 1e-9).astype(np.int64), 1)
    origin = 0.5 * (lo + hi) - 0.5 * d * (counts - 1)
    return origin, counts


def _sample_fluid(spec: model.FluidSpec, r: float, frame=None) -> np.ndarray:
    d = spacing(r)
    if _shape(spec) == "box":
        lo, hi = _scaled_box(spec)
        counts = _fluid_box_counts(lo, hi, d)
        if np.any(counts == 0):
            return np.empty((0, 3), dtype=np.float64)
        return meshes.transform_points(_grid(lo + d, counts, d), _rigid(spec.transform))
    mesh, report = _prepared(_mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
    if frame is None:
        origin, counts = _mesh_lattice(report.bounds, d)
        lattice = _grid(origin, counts, d)
    else:
        b = np.asarray(report.bounds, dtype=np.float64)
        corners = np.array([[b[i], b[2 + j], b[4 + k]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        lattice = _frame_points(frame, corners, d)
    inside = inside_mesh(lattice, mesh, d, closed=report.closed)
    return np.ascontiguousarray(lattice[inside])


def _frame_points(frame, points: np.ndarray, d: float) -> np.ndarray:
    """The points of the lattice `frame` = (origin, rotation rows) in the box that `points` span
    (in lattice coordinates)."""
    origin, rot = frame
    local = (np.asarray(points, dtype=np.float64) - origin) @ rot.T / d
    lo = np.floor(local.min(axis=0) - 1e-9).astype(np.int64)
    hi = np.ceil(local.max(axis=0) + 1e-9).astype(np.int64)
    axes = [np.arange(lo[k], hi[k] + 1, dtype=np.float64) for k in range(3)]
    ijk = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return np.ascontiguousarray(origin + d * (ijk @ rot))


def lattice_frame(scene: model.Scene):
    """(origin, rotation rows) of the scene's rest lattice, or None (no fluid).

    The first box-shaped container's (a box, or a mesh that is an axis-aligned box after scaling):
    its first layer sits d inside the walls, where a box fluid filling it puts its first layer
    (SPlisHSPlasH's FluidBlocks rule). Without one, the first fluid body's own lattice. Mesh fluids
    are sampled on this lattice, so a mesh fluid and a box fluid filling the same tank are the same
    particles; `rest_lattice` continues it to fit the walls to.
    """
    r = _check_radius(scene.particle_radius)
    d = spacing(r)
    for spec in scene.boundaries:
        if spec.role != model.Role.CONTAINER:
            continue
        if _shape(spec) == "box":
            lo, _ = _scaled_box(spec)
        else:
            scaled, _ = _prepared(
                _mesh_path(spec), model.Transform(scale=spec.transform.scale), need_closed=False, allow_open=True
            )
            box = meshes.aligned_box(scaled)
            if box is None:
                continue
            lo = np.asarray(box[0], dtype=np.float64)
        return _rigid_frame(lo + d, _rigid(spec.transform))
    if not scene.fluids:
        return None
    spec = scene.fluids[0]
    if _shape(spec) == "box":
        lo, _ = _scaled_box(spec)
        return _rigid_frame(lo + d, _rigid(spec.transform))
    _, report = _prepared(_mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
    origin, _ = _mesh_lattice(report.bounds, d)
    return origin, np.eye(3)


def _rigid_frame(local_origin: np.ndarray, rigid: model.Transform):
    origin = meshes.transform_points(local_origin.reshape(1, 3), rigid)[0]
    rot = meshes.transform_points(np.eye(3), rigid) - meshes.transform_points(np.zeros((1, 3)), rigid)
    return origin, rot


def rest_lattice(scene: model.Scene, boundary_x: np.ndarray) -> np.ndarray:
    """The scene's rest lattice (`lattice_frame`) over the free space within 2H = 8r of the walls.

    Lattice points that a fluid filling every container would keep under the same rules as the
    real fluid (`sample_scene`: at least d from every wall particle, inside no obstacle, inside a
    container when there are any), restricted to those within 2H of a wall particle.
    `boundary.Boundary` fits the wall volumes to it so that walls and fluid at rest together read
    rho0 (method.md section 1). Empty without fluid or walls.
    """
    r = _check_radius(scene.particle_radius)
    d, reach = spacing(r), 8.0 * r
    xb = np.ascontiguousarray(np.asarray(boundary_x, dtype=np.float64).reshape(-1, 3))
    frame = lattice_frame(scene)
    if frame is None or len(xb) == 0:
        return np.empty((0, 3))
    origin, rot = frame
    local = (xb - origin) @ rot.T / d
    lo = np.floor(local.min(axis=0) - reach / d).astype(np.int64)
    hi = np.ceil(local.max(axis=0) + reach / d).astype(np.int64)
    gy, gz = np.meshgrid(np.arange(lo[1], hi[1] + 1), np.arange(lo[2], hi[2] + 1), indexing="ij")
    plane = np.stack([gy.ravel(), gz.ravel()], axis=1).astype(np.float64)
    kept = []
    step = max(1, 2_000_000 // max(len(plane), 1))  # lattice slabs of ~2M points
    for x0 in range(lo[0], hi[0] + 1, step):
        xs = np.arange(x0, min(x0 + step, hi[0] + 1), dtype=np.float64)
        ijk = np.column_stack([np.repeat(xs, len(plane)), np.tile(plane, (len(xs), 1))])
        pts = np.ascontiguousarray(origin + d * (ijk @ rot))
        pts = pts[nearest_distance(pts, xb, reach) < reach]
        if len(pts):
            ok, _ = remove_overlaps(pts, xb, default_overlap_distance(r), boundaries=scene.boundaries, radius=r)
            kept.append(pts[ok])
    return np.ascontiguousarray(np.concatenate(kept)) if kept else np.empty((0, 3))


def fluid_positions(spec: model.FluidSpec, radius: float, *, cache: bool = True, frame=None) -> np.ndarray:
    """(N,3) float64 fluid particle positions for a box or mesh fluid body (module docstring);
    a mesh fluid on the lattice `frame` (`lattice_frame`) when given, else on its own centred one."""
    r = _check_radius(radius)
    extra = () if frame is None or _shape(spec) == "box" else (frame[0].tolist(), frame[1].tolist())
    sample = (lambda: _sample_fluid(spec, r, frame)) if extra else (lambda: _sample_fluid(spec, r))
    return _cached("fluid", spec, r, cache, sample, extra)


def estimate_fluid_count(spec: model.FluidSpec, radius: float) -> int:
    """Particle count before sampling: exact for boxes; volume / d³ for closed meshes (the lattice
    count estimates the volume to a few percent); the bounding-box lattice (an upper bound) for open ones."""
    r = _check_radius(radius)
    d = spacing(r)
    if _shape(spec) == "box":
        lo, hi = _scaled_box(spec)
        return int(np.prod(_fluid_box_counts(lo, hi, d)))
    _, report = _prepared(_mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
    if report.closed:
        return int(round(report.volume / d**3))
    return int(np.prod(_mesh_lattice(report.bounds, d)[1]))


# ----------------------------------------------------------------------------- boundary
def _box_surface_grid(lo: np.ndarray, hi: np.ndarray, max_spacing: float, offset: float = 0.0) -> np.ndarray:
    """Nodes of a regular grid on the 6 faces: n = ceil(edge / max_spacing) intervals; shared nodes once.

    With `offset` the grid lies on the box grown by `offset` on every side (shrunk if negative)."""
    lo, hi = lo - offset, hi + offset
    ext = hi - lo
    n = np.maximum(np.ceil(ext / max_spacing - 1e-9).astype(np.int64), 1)
    ax = [lo[k] + ext[k] * (np.arange(n[k] + 1, dtype=np.float64) / n[k]) for k in range(3)]
    ax[0][-1], ax[1][-1], ax[2][-1] = hi  # exact far faces
    inner = [a[1:-1] for a in ax]

    def block(xs, ys, zs):
        gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
        return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)

    parts = [
        block(ax[0][[0, -1]], ax[1], ax[2]),  # x faces, with all their edges
        block(inner[0], ax[1][[0, -1]], ax[2]),  # y faces, x-interior
        block(inner[0], inner[1], ax[2][[0, -1]]),
    ]  # z faces, x- and y-interior
    return np.ascontiguousarray(np.concatenate(parts))


def _feature_candidates(mesh, r: float) -> tuple[np.ndarray, np.ndarray]:
    """(corners, dense edge samples) of the feature edges (30°, boundary and non-manifold edges)."""
    fe = mesh.extract_feature_edges(
        feature_angle=FEATURE_ANGLE_DEG,
        boundary_edges=True,
        non_manifold_edges=True,
        feature_edges=True,
        manifold_edges=False,
    )
    if fe.n_cells == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    pts = np.asarray(fe.points, dtype=np.float64)
    seg = np.asarray(fe.lines).reshape(-1, 3)[:, 1:]
    degree = np.bincount(seg.ravel(), minlength=len(pts))
    corners = pts[(degree != 2) & (degree > 0)]
    a, b = pts[seg[:, 0]], pts[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    k = np.maximum(np.ceil(length / (CANDIDATE_SPACING_FACTOR * r)).astype(np.int64), 1)
    owner = np.repeat(np.arange(len(seg)), k)
    step = np.arange(len(owner)) - np.repeat(np.cumsum(k) - k, k)  # 0..k-1 within a segment
    frac = (step / np.repeat(k, k))[:, None]
    dense = a[owner] + frac * (b - a)[owner]  # includes each start vertex
    return np.ascontiguousarray(corners), np.ascontiguousarray(dense)


def _face_candidates(mesh, r: float) -> np.ndarray:
    from vtkmodules.vtkFiltersModeling import vtkPolyDataPointSampler

    sampler = vtkPolyDataPointSampler()
    sampler.SetInputData(mesh)
    sampler.SetDistance(CANDIDATE_SPACING_FACTOR * r)
    sampler.SetPointGenerationModeToRegular()
    sampler.GenerateVertexPointsOn()
    sampler.GenerateEdgePointsOn()
    sampler.GenerateInteriorPointsOn()
    sampler.Update()
    import pyvista as pv

    return np.ascontiguousarray(pv.wrap(sampler.GetOutput()).points, dtype=np.float64)


def _sample_general_surface(mesh, r: float) -> np.ndarray:
    corners, edges = _feature_candidates(mesh, r)
    faces = _face_candidates(mesh, r)
    cand = np.concatenate([corners, edges, faces])
    return np.ascontiguousarray(cand[poisson_filter(cand, POISSON_RADIUS_FACTOR * r)])


def _sample_boundary(spec: model.BoundarySpec, r: float) -> np.ndarray:
    step = BOUNDARY_SPACING_FACTOR * r
    # behind the surface, away from the fluid: outwards for a container, inwards for an obstacle
    offset = BOX_WALL_OFFSET_FACTOR * spacing(r) * (1.0 if spec.role == model.Role.CONTAINER else -1.0)
    if _shape(spec) == "box":
        lo, hi = _scaled_box(spec)
        return meshes.transform_points(_box_surface_grid(lo, hi, step, offset), _rigid(spec.transform))
    scaled, _ = _prepared(
        _mesh_path(spec), model.Transform(scale=spec.transform.scale), need_closed=False, allow_open=True
    )
    box = meshes.aligned_box(scaled)
    if box is not None:
        return meshes.transform_points(_box_surface_grid(box[0], box[1], step, offset), _rigid(spec.transform))
    mesh, _ = _prepared(_mesh_path(spec), spec.transform, need_closed=False, allow_open=True)
    return _sample_general_surface(mesh, r)


def boundary_positions(spec: model.BoundarySpec, radius: float, *, cache: bool = True) -> np.ndarray:
    """(M,3) float64 wall particles on the surface of a box or mesh boundary (module docstring)."""
    r = _check_radius(radius)
    return _cached("boundary", spec, r, cache, lambda: _sample_boundary(spec, r))


def boundary_surface(spec: model.BoundarySpec) -> "pv.PolyData":
    """The transformed wall surface as triangles (for rendering)."""
    if _shape(spec) == "box":
        lo, hi = _scaled_box(spec)
        return meshes.transform_mesh(meshes.box_mesh(tuple(lo), tuple(hi)), _rigid(spec.transform))
    return _prepared(_mesh_path(spec), spec.transform, need_closed=False, allow_open=True)[0].copy()


# ----------------------------------------------------------------------------- overlaps
def _inside_boundary(points: np.ndarray, spec: model.BoundarySpec, r: float) -> np.ndarray:
    if _shape(spec) == "box":
        lo, hi = _scaled_box(spec)
        local = meshes.inverse_transform_points(points, _rigid(spec.transform))
        return np.all((local > lo) & (local < hi), axis=1)
    mesh, report = _prepared(_mesh_path(spec), spec.transform, need_closed=False, allow_open=True)
    return inside_mesh(points, mesh, spacing(r), closed=report.closed)


def solid_mask(points: np.ndarray, boundaries: Sequence[model.BoundarySpec], radius: float) -> np.ndarray:
    """True where a point is inside no obstacle and, when there are containers, inside at least one."""
    r = _check_radius(radius)
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


def remove_overlaps(
    fluid: np.ndarray,
    boundary_points: np.ndarray,
    min_dist: float,
    *,
    boundaries: Sequence[model.BoundarySpec] = (),
    radius: float | None = None,
) -> tuple[np.ndarray, int]:
    """(kept mask, removed count): drop fluid particles closer than min_dist to a wall particle
    (use default_overlap_distance(r) = d) and, given boundaries and radius, those solid_mask rejects."""
    f = np.ascontiguousarray(np.asarray(fluid, dtype=np.float64).reshape(-1, 3))
    kept = nearest_distance(f, boundary_points, min_dist) >= min_dist
    if boundaries:
        if radius is None:
            raise ConfigError("remove_overlaps: radius is needed with boundaries")
        kept &= solid_mask(f, boundaries, radius)
    return kept, int(len(f) - np.count_nonzero(kept))


def cache_key(kind: str, spec, radius: float) -> str:
    """The disk-cache key of a fluid's or wall's samples (sample_cache.cache_key)."""
    return sample_cache.cache_key(
        kind, spec, radius, SAMPLER_VERSION, _mesh_path(spec) if spec.shape != "box" else None
    )


def _cached(kind: str, spec, r: float, use_cache: bool, sample, extra=()) -> np.ndarray:
    _shape(spec)
    if not use_cache:
        return sample()
    key = cache_key(kind, spec, r)
    if extra:
        key = hashlib.sha256((key + repr(extra)).encode()).hexdigest()
    return sample_cache.cached(f"{kind}-{key}", sample)
