"""Surface meshes: loading, transforms, closedness/orientation checks (the inside test: `inside`).

Every mesh leaving this module is a triangle-only `pyvista.PolyData` with merged points.
"""

from __future__ import annotations

import logging
import math
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ipsph import config as model
from ipsph.errors import MeshError
from ipsph.geometry.mesh_checks import check_read

if TYPE_CHECKING:
    import pyvista as pv

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".vtk", ".vtu", ".vtp", ".off", ".msh")
# Volumes below this fraction of (largest bounding-box extent)³ count as zero (flat or degenerate).
ZERO_VOLUME_REL = 1e-9


# ----------------------------------------------------------------------------- loading
def load_mesh(path: Path | str) -> "pv.PolyData":
    """Read a surface mesh as triangles: pyvista first, meshio for formats VTK lacks (.off, .msh)."""
    import pyvista as pv

    given = Path(path)
    resolved = given.expanduser().resolve()
    where = f"{given}" if str(given) == str(resolved) else f"{given} (resolved: {resolved})"
    suffix = resolved.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshError(f"mesh {where}: unknown format {suffix!r}; use one of {', '.join(MESH_SUFFIXES)}")
    if not resolved.is_file():
        raise MeshError(f"mesh {where}: file not found; check the path (relative paths resolve against the scene file)")
    reasons = []
    data = None
    if suffix not in (".off", ".msh"):
        try:
            with _quiet_vtk():
                data = pv.read(resolved)
        except Exception as exc:  # noqa: BLE001 - any reader failure falls through to meshio
            reasons.append(f"pyvista: {_one_line(exc)}")
    if data is None or data.n_points == 0:
        try:
            import meshio

            with _quiet_vtk():
                data = pv.wrap(meshio.read(resolved))
        except Exception as exc:  # noqa: BLE001
            reasons.append(f"meshio: {_one_line(exc)}")
    if data is None:
        raise MeshError(f"mesh {where}: unreadable ({'; '.join(reasons)}); check the file is a valid {suffix} mesh")
    check_read(data, where, resolved)  # before any VTK filter: a bad index crashes them or reads garbage
    try:
        surface = _as_triangles(data)
    except Exception as exc:  # noqa: BLE001
        raise MeshError(f"mesh {where}: cannot extract a surface ({_one_line(exc)})") from exc
    if surface.n_cells == 0:
        raise MeshError(f"mesh {where}: no triangles after reading; the file is empty or holds no surface")
    return surface


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return (text[:160] + "...") if len(text) > 160 else (text or type(exc).__name__)


@contextmanager
def _quiet_vtk():
    """Silence a reader's warnings and the VTK errors pyvista logs (a refusal is one line of ours)."""
    was = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(was)


def _as_triangles(data) -> "pv.PolyData":
    import pyvista as pv

    if isinstance(data, pv.MultiBlock):
        data = data.combine()
    surf = data.extract_surface(algorithm="dataset_surface") if not isinstance(data, pv.PolyData) else data
    surf = surf.triangulate().clean()
    if surf.n_cells and not surf.is_all_triangles:  # stray lines / vertices: keep the triangles
        import pyvista as pv

        surf = surf.extract_cells_by_type(pv.CellType.TRIANGLE).extract_surface(algorithm="dataset_surface").clean()
    faces = surf.regular_faces if surf.n_cells else np.empty((0, 3), dtype=np.int64)
    return tri_mesh(np.asarray(surf.points, dtype=np.float64), faces)


def tri_mesh(points: np.ndarray, faces: np.ndarray) -> "pv.PolyData":
    """A triangle PolyData from (n,3) points and (m,3) vertex indices."""
    import pyvista as pv

    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    return pv.PolyData(np.ascontiguousarray(points, dtype=np.float64), cells)


def mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(points float64 (n,3), faces int64 (m,3)) of a triangle mesh."""
    pts = np.ascontiguousarray(mesh.points, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.regular_faces, dtype=np.int64) if mesh.n_cells else np.empty((0, 3), np.int64)
    return pts, faces


# ----------------------------------------------------------------------------- transforms
def rotation_matrix(axis: model.Vec3, angle_deg: float) -> np.ndarray:
    """Rodrigues: R = I + sin θ K + (1 − cos θ) K², K the cross-product matrix of the unit axis."""
    if angle_deg == 0.0:
        return np.eye(3)
    a = np.asarray(axis, dtype=np.float64)
    norm = np.linalg.norm(a)
    if not norm > 0.0:
        raise MeshError(f"transform: rotate_axis {tuple(axis)} has zero length; give a non-zero axis")
    kx, ky, kz = a / norm
    k = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    th = math.radians(angle_deg)
    return np.eye(3) + math.sin(th) * k + (1.0 - math.cos(th)) * (k @ k)


def transform_points(points: np.ndarray, t: model.Transform) -> np.ndarray:
    """x' = R (S x) + t (model.Transform)."""
    p = np.asarray(points, dtype=np.float64) * np.asarray(t.scale, dtype=np.float64)
    if t.rotate_deg != 0.0:
        p = p @ rotation_matrix(t.rotate_axis, t.rotate_deg).T
    return np.ascontiguousarray(p + np.asarray(t.translate, dtype=np.float64))


def inverse_transform_points(points: np.ndarray, t: model.Transform) -> np.ndarray:
    """x = S⁻¹ Rᵀ (x' − t)."""
    p = np.asarray(points, dtype=np.float64) - np.asarray(t.translate, dtype=np.float64)
    if t.rotate_deg != 0.0:
        p = p @ rotation_matrix(t.rotate_axis, t.rotate_deg)
    return np.ascontiguousarray(p / np.asarray(t.scale, dtype=np.float64))


def transform_mesh(mesh, t: model.Transform) -> "pv.PolyData":
    """The mesh with x' = R (S x) + t applied; a mirroring scale (det S < 0) keeps normals outward."""
    pts, faces = mesh_arrays(mesh)
    if any(s == 0.0 for s in t.scale):
        raise MeshError(f"transform: scale {tuple(t.scale)} has a zero component; the mesh would be flat")
    if np.prod(np.sign(t.scale)) < 0:
        faces = faces[:, ::-1]
    return tri_mesh(transform_points(pts, t), faces)


def box_mesh(box_min: model.Vec3, box_max: model.Vec3) -> "pv.PolyData":
    """Closed axis-aligned box, 12 triangles, outward normals."""
    lo = np.asarray(box_min, dtype=np.float64)
    hi = np.asarray(box_max, dtype=np.float64)
    if not np.all(hi > lo):
        raise MeshError(f"box: box_max {tuple(box_max)} must exceed box_min {tuple(box_min)} on every axis")
    corners = np.array(
        [[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)]
    )
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return tri_mesh(corners, np.array(faces))


# ----------------------------------------------------------------------------- checks
def edge_counts(mesh) -> tuple[int, int, int]:
    """(open, non_manifold, unpaired) edge counts.

    open: edges used by an odd number of triangles (holes). non_manifold: used by more than two.
    unpaired: edges whose directed uses do not cancel (open, or neighbours wound inconsistently);
    zero exactly when the surface is a closed oriented 2-cycle, the condition under which the
    winding number is an integer (0 or ±1 for non-overlapping parts) everywhere off the surface.
    """
    _, cnt, balance = _edge_table(mesh)
    return int(np.count_nonzero(cnt % 2)), int(np.count_nonzero(cnt > 2)), int(np.count_nonzero(balance))


def _edge_table(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(edges (k, 2) as sorted vertex pairs, uses per edge, sum of the directed uses' signs)."""
    _, faces = mesh_arrays(mesh)
    if len(faces) == 0:
        return np.empty((0, 2), np.int64), np.empty(0, np.int64), np.empty(0)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    sign = np.where(e[:, 0] < e[:, 1], 1, -1)
    key = np.sort(e, axis=1)
    edges, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    balance = np.bincount(inv.ravel(), weights=sign, minlength=len(cnt))
    return edges, cnt, balance


def fmt_point(p) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in p) + ")"


def unpaired_edge_at(mesh) -> tuple[float, float, float] | None:
    """The midpoint of one edge where the surface is not closed and oriented (an open edge first),
    to point a user at the hole; None when the surface is closed."""
    edges, cnt, balance = _edge_table(mesh)
    bad = np.flatnonzero(cnt % 2)
    if len(bad) == 0:
        bad = np.flatnonzero(balance)
    if len(bad) == 0:
        return None
    pts = np.asarray(mesh.points, dtype=np.float64)
    return tuple(float(v) for v in 0.5 * (pts[edges[bad[0], 0]] + pts[edges[bad[0], 1]]))


def check_closed(mesh) -> int:
    """Number of edges at which the surface is not closed and consistently oriented (0: closed)."""
    return edge_counts(mesh)[2]


def signed_volume(mesh) -> float:
    """V = Σ_t p0 · (p1 × p2) / 6 (divergence theorem; positive for outward normals)."""
    pts, faces = mesh_arrays(mesh)
    if len(faces) == 0:
        return 0.0
    p0, p1, p2 = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
    return float(np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0)


@dataclass(frozen=True)
class MeshReport:
    """What prepare_mesh found: open/unpaired edge counts, volume after any flip, bounds, notes."""

    source: str
    n_points: int
    n_triangles: int
    open_edges: int  # edges used by an odd number of triangles
    non_manifold_edges: int  # edges used by more than two triangles (allowed when paired)
    unpaired_edges: int  # 0 <=> closed oriented surface
    volume: float  # signed volume after orientation fix (m^3)
    flipped: bool  # triangles were reversed (the file's normals pointed inward)
    bounds: tuple[float, float, float, float, float, float]
    notes: tuple[str, ...] = ()
    open_at: tuple[float, float, float] | None = None  # one unpaired edge's midpoint (None: closed)

    @property
    def closed(self) -> bool:
        return self.unpaired_edges == 0


def prepare_mesh(
    source,
    transform: model.Transform = model.Transform(),  # noqa: B008 - a frozen dataclass, immutable
    *,
    need_closed: bool = True,
    allow_open: bool = False,
    name: str | None = None,
) -> tuple["pv.PolyData", MeshReport]:
    """Load (path) or take (PolyData) a mesh, transform it, check closedness, fix inverted normals.

    need_closed and not allow_open: a mesh with unpaired edges raises MeshError naming the count.
    A closed mesh with (near) zero volume raises MeshError; a negative volume is flipped (noted).
    """
    if isinstance(source, (str, Path)):
        label = str(source)
        mesh = load_mesh(Path(source))
    else:
        label = name or "<mesh>"
        check_read(source, label)
        mesh = _as_triangles(source)
        if mesh.n_cells == 0:
            raise MeshError(f"mesh {label}: no triangles; give a non-empty surface")
    mesh = transform_mesh(mesh, transform)
    n_open, n_nonman, n_unpaired = edge_counts(mesh)
    notes: list[str] = []
    if n_unpaired and not n_open:
        fixed = _make_consistent(mesh)
        if fixed is not None and edge_counts(fixed)[2] == 0:
            mesh, n_unpaired = fixed, 0
            notes.append(f"mesh {label}: triangle orientation made consistent")
    if n_unpaired and need_closed and not allow_open:
        raise MeshError(
            f"mesh {label}: not closed ({n_open} open edges, {n_unpaired} unpaired edges, one at "
            f"{fmt_point(unpaired_edge_at(mesh))}); repair it, or allow an open mesh explicitly (allow_open_mesh = true)"
        )
    vol = signed_volume(mesh)
    b = mesh.bounds
    ext = np.array([b[1] - b[0], b[3] - b[2], b[5] - b[4]])
    cube = float(ext.max()) ** 3
    flipped = False
    if n_unpaired == 0:
        if not abs(vol) > ZERO_VOLUME_REL * cube:
            raise MeshError(
                f"mesh {label}: encloses zero volume (bounds {tuple(round(float(v), 6) for v in b)}); "
                "a fluid or wall needs a solid shape"
            )
        if vol < 0.0:
            pts, faces = mesh_arrays(mesh)
            mesh = tri_mesh(pts, faces[:, ::-1])
            vol, flipped = -vol, True
            notes.append(f"mesh {label}: normals pointed inward (volume {-vol:.6g} m^3); triangles flipped")
    elif need_closed:
        notes.append(f"mesh {label}: open surface ({n_open} open edges) used as allowed; inside test by winding number")
    report = MeshReport(
        source=label,
        n_points=int(mesh.n_points),
        n_triangles=int(mesh.n_cells),
        open_edges=n_open,
        non_manifold_edges=n_nonman,
        unpaired_edges=n_unpaired,
        volume=float(vol),
        flipped=flipped,
        bounds=tuple(float(v) for v in b),
        notes=tuple(notes),
        open_at=unpaired_edge_at(mesh) if n_unpaired else None,
    )
    return mesh, report


def _make_consistent(mesh):
    """vtkPolyDataNormals' consistency pass, or None when VTK cannot do it."""
    try:
        fixed = mesh.compute_normals(
            consistent_normals=True,
            auto_orient_normals=False,
            split_vertices=False,
            non_manifold_traversal=False,
            cell_normals=False,
            point_normals=False,
        )
        return tri_mesh(*mesh_arrays(fixed))
    except Exception:  # noqa: BLE001 - the caller reports the mesh as open instead
        return None


def aligned_box(mesh, rel_tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray] | None:
    """(box_min, box_max) when the closed mesh is exactly an axis-aligned box surface, else None.

    Test: every triangle lies in one face plane of the bounding box and the enclosed volume equals
    the box volume (then the faces are fully covered).
    """
    pts, faces = mesh_arrays(mesh)
    if len(faces) == 0:
        return None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    ext = hi - lo
    if not np.all(ext > 0):
        return None
    tol = rel_tol * float(ext.max())
    tri = pts[faces]  # (m,3,3)
    on_plane = np.zeros(len(faces), dtype=bool)
    for ax in range(3):
        for val in (lo[ax], hi[ax]):
            on_plane |= np.all(np.abs(tri[:, :, ax] - val) <= tol, axis=1)
    if not on_plane.all():
        return None
    if check_closed(mesh) != 0 or abs(abs(signed_volume(mesh)) - float(np.prod(ext))) > 1e-6 * float(np.prod(ext)):
        return None
    return lo, hi
