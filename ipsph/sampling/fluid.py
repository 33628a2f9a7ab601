"""Scene -> fluid particles: lattices for boxes and meshes, the shared rest lattice, overlap removal.

The shapes themselves (box corners, meshes, surfaces, inside tests) are `geometry.shapes`.

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

from collections.abc import Sequence

import numpy as np

from ipsph import config as model
from ipsph.errors import ConfigError
from ipsph.geometry import meshes
from ipsph.geometry.inside import inside_mesh
from ipsph.geometry.points import nearest_distance
from ipsph.geometry.shapes import (
    cached_samples,
    check_radius,
    mesh_path,
    prepared_mesh,
    rigid_part,
    scaled_box,
    shape_of,
    solid_mask,
)
from ipsph.params import spacing

# Fluid particles closer than d = 2r to a wall particle are removed: the first lattice layer sits
# d from the walls (method.md: particles at r from a wall make DFSPH/IPSPH blow up). The factor
# slightly below 1 keeps a layer that is exactly d away despite rounding.
OVERLAP_DISTANCE_FACTOR = 2.0 * (1.0 - 1e-6)


def default_overlap_distance(radius: float) -> float:
    """min_dist for remove_overlaps: d = 2r (less a rounding tolerance)."""
    return OVERLAP_DISTANCE_FACTOR * radius


# ----------------------------------------------------------------------------- fluid
def _fluid_box_counts(lo: np.ndarray, hi: np.ndarray, d: float, inset_d: float = 1.0) -> np.ndarray:
    """Layers of a box fluid whose first and last layers sit inset_d * d inside its faces."""
    # floor(x + 0.5 + eps): round half up, robust to 19.999999 and 13.5 alike
    return np.maximum(np.floor((hi - lo) / d - 2.0 * inset_d + 1.5 + 1e-9).astype(np.int64), 0)


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


def _sample_fluid(spec: model.FluidSpec, r: float, frame=None, inset_d: float = 1.0) -> np.ndarray:
    d = spacing(r)
    if shape_of(spec) == "box":
        lo, hi = scaled_box(spec)
        counts = _fluid_box_counts(lo, hi, d, inset_d)
        if np.any(counts == 0):
            return np.empty((0, 3), dtype=np.float64)
        return meshes.transform_points(_grid(lo + inset_d * d, counts, d), rigid_part(spec.transform))
    mesh, report = prepared_mesh(mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
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


def lattice_frame(scene: model.Scene, inset_d: float = 1.0):
    """(origin, rotation rows) of the scene's rest lattice, or None (no fluid).

    The first box-shaped container's (a box, or a mesh that is an axis-aligned box after scaling):
    its first layer sits inset_d * d inside the walls, where a box fluid filling it puts its first
    layer (the boundary model's `fluid_inset_d`: d for wall particles, SPlisHSPlasH's FluidBlocks
    rule; d/2 for field walls). Without one, the first fluid body's own lattice. Mesh fluids
    are sampled on this lattice, so a mesh fluid and a box fluid filling the same tank are the same
    particles; `rest_lattice` continues it to fit the walls to.
    """
    r = check_radius(scene.particle_radius)
    d = spacing(r)
    for spec in scene.boundaries:
        if spec.role != model.Role.CONTAINER:
            continue
        if shape_of(spec) == "box":
            lo, _ = scaled_box(spec)
        else:
            scaled, _ = prepared_mesh(
                mesh_path(spec), model.Transform(scale=spec.transform.scale), need_closed=False, allow_open=True
            )
            box = meshes.aligned_box(scaled)
            if box is None:
                continue
            lo = np.asarray(box[0], dtype=np.float64)
        return _rigid_frame(lo + inset_d * d, rigid_part(spec.transform))
    if not scene.fluids:
        return None
    spec = scene.fluids[0]
    if shape_of(spec) == "box":
        lo, _ = scaled_box(spec)
        return _rigid_frame(lo + inset_d * d, rigid_part(spec.transform))
    _, report = prepared_mesh(mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
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
    r = check_radius(scene.particle_radius)
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


def fluid_positions(
    spec: model.FluidSpec, radius: float, *, cache: bool = True, frame=None, inset_d: float = 1.0
) -> np.ndarray:
    """(N,3) float64 fluid particle positions for a box or mesh fluid body (module docstring);
    a mesh fluid on the lattice `frame` (`lattice_frame`) when given, else on its own centred one;
    a box fluid's first layer inset_d * d inside its faces."""
    r = check_radius(radius)
    box = shape_of(spec) == "box"
    extra = () if frame is None or box else (frame[0].tolist(), frame[1].tolist())
    if box and inset_d != 1.0:
        extra = (inset_d,)
    sample = (lambda: _sample_fluid(spec, r, frame, inset_d)) if extra else (lambda: _sample_fluid(spec, r))
    return cached_samples("fluid", spec, r, cache, sample, extra)


def estimate_fluid_count(spec: model.FluidSpec, radius: float, inset_d: float = 1.0) -> int:
    """Particle count before sampling: exact for boxes; volume / d³ for closed meshes (the lattice
    count estimates the volume to a few percent); the bounding-box lattice (an upper bound) for open ones."""
    r = check_radius(radius)
    d = spacing(r)
    if shape_of(spec) == "box":
        lo, hi = scaled_box(spec)
        return int(np.prod(_fluid_box_counts(lo, hi, d, inset_d)))
    _, report = prepared_mesh(mesh_path(spec), spec.transform, need_closed=True, allow_open=spec.allow_open_mesh)
    if report.closed:
        return int(round(report.volume / d**3))
    return int(np.prod(_mesh_lattice(report.bounds, d)[1]))


# ----------------------------------------------------------------------------- overlaps
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
