"""Wall particles on a boundary's surface: where a wall model puts its layer.

Conventions (r particle radius, d = 2r; the layer's distance behind the surface is the model's,
`ipsph.boundary.models`):
- Box (also a mesh that is an axis-aligned box after scaling, e.g. UnitBox.obj): a regular grid per
  face of the box moved `offset` behind its surface (grown for a container, shrunk for an obstacle
  or body), n = ceil(edge / 1.5r) intervals per edge, edge and corner nodes once.
- General mesh: candidates = feature-edge corners, then feature edges (30°) sampled every r/5, then
  face samples of vtkPolyDataPointSampler (Distance r/5); a greedy pass in that priority order keeps
  a candidate when no kept sample lies within r (the Poisson-disk rule of vtkPoissonDiskSampler,
  seeded with the edges, which that filter cannot take): nearest-neighbour spacing >= r, no
  candidate farther than r from a sample. A closed obstacle's samples then move `offset` inwards
  along the normal of their nearest triangle; a container's and an open mesh's stay on the surface.
"""

from __future__ import annotations

import numpy as np

from .. import config as model
from ..geometry import meshes
from ..geometry.points import nearest_distance, poisson_filter
from ..geometry.shapes import cached_samples, check_radius, mesh_path, prepared_mesh, rigid_part, scaled_box, shape_of

BOUNDARY_SPACING_FACTOR = 1.5  # box-grid spacing <= 1.5 r (method.md section 1)
# Fluid starts at least this many spacings d from a rigid body's particles (other walls: 1 d): where
# it rests against a single Akinci layer (models.REST_DISTANCE_D, 1.1 d). Closer, the full-mass lattice
# reads up to 1.145 rho0 and the pop launched a floating crate out of the water at t = 0; farther (an
# earlier 1.5 d), the water rushed into the gap and pressed particles into a body's edges.
BODY_GAP_D = 1.1
POISSON_RADIUS_FACTOR = 1.0  # general meshes: samples at least r apart, none missing beyond r
CANDIDATE_SPACING_FACTOR = 0.2  # candidate density r/5 (ecosystem.md)
FEATURE_ANGLE_DEG = 30.0


def _box_surface_grid(lo: np.ndarray, hi: np.ndarray, max_spacing: float, offset: float = 0.0) -> np.ndarray:
    """Nodes of a regular grid on the 6 faces: n = ceil(edge / max_spacing) intervals; shared nodes once.

    With `offset` the grid lies on the box grown by `offset` on every side (shrunk if negative). A
    box thinner than twice a negative offset along an axis (a paddle, a plate) collapses onto its
    mid-plane there: one layer, no duplicate nodes."""
    lo, hi = lo - offset, hi + offset
    flat = hi - lo <= 0.0
    lo, hi = np.where(flat, 0.5 * (lo + hi), lo), np.where(flat, 0.5 * (lo + hi), hi)
    ext = hi - lo
    n = np.maximum(np.ceil(ext / max_spacing - 1e-9).astype(np.int64), 1)
    ax = [lo[k] + ext[k] * (np.arange(n[k] + 1, dtype=np.float64) / n[k]) for k in range(3)]
    ax[0][-1], ax[1][-1], ax[2][-1] = hi  # exact far faces
    ax = [a[:1] if f else a for a, f in zip(ax, flat)]
    inner = [a[1:-1] for a in ax]
    ends = [a[[0, -1]] if len(a) > 1 else a for a in ax]

    def block(xs, ys, zs):
        gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
        return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)

    parts = [
        block(ends[0], ax[1], ax[2]),  # x faces, with all their edges
        block(inner[0], ends[1], ax[2]),  # y faces, x-interior
        block(inner[0], inner[1], ends[2]),  # z faces, x- and y-interior
    ]
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


def _offset_along_normals(mesh, points: np.ndarray, offset: float) -> np.ndarray:
    """The surface samples moved by `offset` along the outward normal of their nearest triangle."""
    import pyvista as pv

    surf = (
        pv.wrap(mesh)
        .triangulate()
        .compute_normals(cell_normals=True, point_normals=False, auto_orient_normals=True, consistent_normals=True)
    )
    cells = surf.find_closest_cell(points)
    return np.ascontiguousarray(points + offset * np.asarray(surf.cell_data["Normals"], dtype=np.float64)[cells])


def wall_samples(spec: model.BoundarySpec, r: float, offset: float) -> np.ndarray:
    """The layer of a box or mesh boundary, `offset` behind its surface (away from the fluid)."""
    step = BOUNDARY_SPACING_FACTOR * r
    signed = offset if spec.role == model.Role.CONTAINER else -offset  # along the outward normal
    if shape_of(spec) == "box":
        lo, hi = scaled_box(spec)
        return meshes.transform_points(_box_surface_grid(lo, hi, step, signed), rigid_part(spec.transform))
    scaled, _ = prepared_mesh(
        mesh_path(spec), model.Transform(scale=spec.transform.scale), need_closed=False, allow_open=True
    )
    box = meshes.aligned_box(scaled)
    if box is not None:
        return meshes.transform_points(_box_surface_grid(box[0], box[1], step, signed), rigid_part(spec.transform))
    mesh, report = prepared_mesh(mesh_path(spec), spec.transform, need_closed=False, allow_open=True)
    samples = _sample_general_surface(mesh, r)
    if spec.role == model.Role.CONTAINER or not report.closed:
        return samples
    return _offset_along_normals(mesh, samples, signed)


def boundary_positions(spec: model.BoundarySpec, radius: float, offset: float, *, cache: bool = True) -> np.ndarray:
    """(M,3) float64 wall particles of a box or mesh boundary, `offset` behind its surface."""
    r = check_radius(radius)
    return cached_samples("boundary", spec, r, cache, lambda: wall_samples(spec, r, offset), (round(offset / r, 12),))


def body_gap_mask(fluid_x: np.ndarray, scene: model.Scene, walls: list[np.ndarray], r: float) -> np.ndarray:
    """True for the fluid particles at least BODY_GAP_D d from every rigid body's wall particles
    (`walls`: the sampled particles of each scene boundary, in order)."""
    body = [w for spec, w in zip(scene.boundaries, walls) if spec.dynamic]
    gap = BODY_GAP_D * 2.0 * r
    pts = np.ascontiguousarray(np.concatenate(body))
    return nearest_distance(np.ascontiguousarray(fluid_x), pts, gap) >= gap
