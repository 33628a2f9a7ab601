"""A closed mesh wall as a field grid: its signed distance φ and its solid's kernel integral I on a
regular grid in the body frame (design brief boundary-fields.md section 7; read at run time by
backends/field_grid.py, whose docstring gives the layout and the conventions).

Body frame: the mesh file's coordinates times the spec's scale (the solver applies the rotation
and translation at run time). Grid: the mesh's bounding box padded by H + 2 h_g on every side,
spacing h_g = H/8 by default, so the Catmull–Rom stencil of any point within H of the solid reads
only computed nodes and the outer two layers hold I = 0. φ from libigl's signed distance (sign by
the fast winding number; positive outside the solid), I exact (mesh_integral.py) where |φ| < H,
else 1 inside and 0 outside. Stored as float32 pairs (φ, I), 8 bytes a node, cached on disk
(geometry/cache.py's folder) keyed by the mesh (file bytes or arrays), scale, H, h_g and VERSION.

Refused with a one-line MeshError naming the mesh: an unreadable, open, non-manifold or
zero-volume mesh, NaN or infinite vertices, and a grid over MEMORY_FRACTION of the available
memory (checked before anything of the grid's size is allocated).
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numba as nb
import numpy as np

from ipsph import config as model
from ipsph.backends.field_grid import (
    HDR_INV_H,
    HDR_NX,
    HDR_NZ,
    HDR_OFFSET,
    HDR_OX,
    HDR_PAD,
    HEADER,
    grid_distance,
    grid_kernel_integral,
)
from ipsph.errors import MeshError
from ipsph.geometry import cache, meshes

from .mesh_integral import MeshIntegral

VERSION = "ipsph-meshfield-1"  # part of every cache key: change it when the grids change
NODES_PER_SUPPORT = 8  # h_g = H / 8: Catmull–Rom reads I to ≈5e-4 there (the brief's table, section 7)
BYTES_PER_NODE = 8  # (φ, I) as float32
MEMORY_FRACTION = 0.25  # of the available memory, the most one grid may take
CHUNK_NODES = 1 << 18  # nodes per build chunk: bounds the float64 temporaries (≈ 20 MB)


@dataclass(frozen=True)
class MeshField:
    """One mesh's grid: header row (1, HEADER) float64 and pool (2 n,) float32, as field_grid reads them."""

    name: str
    header: np.ndarray
    pool: np.ndarray
    support: float  # H (m)
    spacing: float  # h_g (m)
    band_nodes: int  # nodes where I was integrated (|φ| < H); 0 when read from the cache
    build_seconds: float  # wall time of the build, or of the cache read
    from_cache: bool

    @property
    def dims(self) -> tuple[int, int, int]:
        return tuple(int(v) for v in self.header[0, HDR_NX : HDR_NZ + 1])

    @property
    def origin(self) -> np.ndarray:
        return self.header[0, HDR_OX : HDR_OX + 3].copy()

    @property
    def nbytes(self) -> int:
        return int(self.pool.nbytes + self.header.nbytes)

    def _grid(self, slot: int) -> np.ndarray:
        nx, ny, nz = self.dims
        return self.pool[slot::2].reshape(nz, ny, nx)

    @property
    def phi(self) -> np.ndarray:
        """φ at the nodes, indexed [iz, iy, ix] (a view)."""
        return self._grid(0)

    @property
    def kernel_integral(self) -> np.ndarray:
        """I at the nodes, indexed [iz, iy, ix] (a view)."""
        return self._grid(1)

    def sample(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(I, ∇I, φ, ∇φ) at (n, 3) body-frame points, through the device functions."""
        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        out = np.empty((len(p), 8), dtype=np.float64)
        _sample(self.header, self.pool, p, out)
        return out[:, 0], out[:, 1:4], out[:, 4], out[:, 5:8]


@nb.njit(cache=True)
def _sample(hdr, pool, points, out):
    """The grid read point after point, as a pass would (serial: a host helper, compiled in seconds)."""
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = grid_kernel_integral(hdr, 0, pool, x, y, z)
        out[i, 4], out[i, 5], out[i, 6], out[i, 7] = grid_distance(hdr, 0, pool, x, y, z)


def field_for_spec(spec, support: float, spacing: float | None = None, *, use_cache: bool = True) -> MeshField:
    """The grid of a [[boundary]] mesh spec (its file and its transform's scale)."""
    if spec.mesh is None:
        raise MeshError(f"{spec.name}: a field grid needs a mesh file")
    path = Path(spec.mesh)
    return mesh_field(path, support, scale=spec.transform.scale, spacing=spacing, name=spec.name, use_cache=use_cache)


def mesh_field(
    source,
    support: float,
    *,
    scale=(1.0, 1.0, 1.0),
    spacing: float | None = None,
    name: str | None = None,
    use_cache: bool = True,
) -> MeshField:
    """The field grid of a closed mesh: a file path, a pyvista PolyData or (vertices, faces).

    support: H = 4r (m); spacing: h_g (default H / NODES_PER_SUPPORT); scale: per axis, applied to
    the vertices first (the body frame). Cached on disk unless use_cache is False.
    """
    t0 = time.perf_counter()
    is_file = isinstance(source, (str, Path))
    label = name or (str(source) if is_file else "<mesh>")
    h_big = float(support)
    h = h_big / NODES_PER_SUPPORT if spacing is None else float(spacing)
    if not (math.isfinite(h_big) and h_big > 0.0 and math.isfinite(h) and h > 0.0):
        raise MeshError(f"mesh {label}: support {support!r} and spacing {spacing!r} must be positive lengths")
    s = np.asarray(scale, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(s)) or np.any(s == 0.0):
        raise MeshError(f"mesh {label}: scale {tuple(s)} must be finite and non-zero on every axis")
    key = _key(source, is_file, s, h_big, h) if use_cache else None
    path = cache.cache_dir() / f"meshfield-{key}.npz" if key else None
    if path is not None:
        hit = _read(path, label, h_big, h, t0)
        if hit is not None:
            return hit
    verts, faces = _checked_mesh(source, is_file, s, label)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    pad = h_big + 2.0 * h
    dims = np.ceil((hi - lo + 2.0 * pad) / h).astype(np.int64) + 1
    _check_memory(dims, h, label)
    header = np.zeros((1, HEADER), dtype=np.float64)
    header[0, HDR_OX : HDR_OX + 3] = lo - pad
    header[0, HDR_INV_H] = 1.0 / h
    header[0, HDR_NX : HDR_NZ + 1] = dims
    header[0, HDR_OFFSET] = 0.0
    header[0, HDR_PAD] = pad
    pool, band = _build(verts, faces, header, h, h_big)
    field = MeshField(label, header, pool, h_big, h, band, time.perf_counter() - t0, False)
    if path is not None:
        _write(path, header, pool)
    return field


# ----------------------------------------------------------------------------- checks
def _checked_mesh(source, is_file: bool, s: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices × scale, faces) of a closed, manifold, outward-oriented surface, or MeshError."""
    if is_file:
        mesh = meshes.load_mesh(Path(source))
    elif isinstance(source, tuple) and len(source) == 2:
        v, f = (np.asarray(a) for a in source)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise MeshError(f"mesh {label}: give (vertices (n, 3), faces (m, 3)) with at least one triangle")
        mesh = meshes.tri_mesh(v.astype(np.float64), f.astype(np.int64))
    else:
        mesh = source
    bad = int(np.sum(~np.isfinite(np.asarray(mesh.points, dtype=np.float64)).all(axis=1)))
    if bad:
        raise MeshError(
            f"mesh {label}: NaN or infinite coordinates at {bad} of {len(mesh.points)} vertices; repair the mesh"
        )
    prepared, rep = meshes.prepare_mesh(mesh, model.Transform(scale=tuple(s)), need_closed=False, name=label)
    if rep.open_edges or rep.non_manifold_edges or rep.unpaired_edges:
        raise MeshError(
            f"mesh {label}: a field grid needs a closed manifold surface; this one has {rep.open_edges} open, "
            f"{rep.non_manifold_edges} non-manifold and {rep.unpaired_edges} unpaired edges: repair it"
        )
    return meshes.mesh_arrays(prepared)  # oriented outward, non-zero volume (prepare_mesh)


def _check_memory(dims: np.ndarray, h: float, label: str) -> None:
    import psutil

    nodes = float(np.prod(dims.astype(np.float64)))
    need = nodes * BYTES_PER_NODE
    avail = float(psutil.virtual_memory().available)
    if need > MEMORY_FRACTION * avail:
        raise MeshError(
            f"mesh {label}: its field grid ({dims[0]}×{dims[1]}×{dims[2]} nodes at {h:.3g} m, "
            f"{need / 2**20:.0f} MiB) exceeds {MEMORY_FRACTION:.0%} of the available memory "
            f"({avail / 2**20:.0f} MiB); use a larger particle radius or a smaller mesh"
        )


# ----------------------------------------------------------------------------- build
def _build(verts, faces, header, h: float, h_big: float) -> tuple[np.ndarray, int]:
    """The (φ, I) pool of the grid in `header`, z-slab chunk by chunk; and the band's node count."""
    import igl

    nx, ny, nz = (int(v) for v in header[0, HDR_NX : HDR_NZ + 1])
    origin = header[0, HDR_OX : HDR_OX + 3]
    pool = np.empty(2 * nx * ny * nz, dtype=np.float32)
    integral = MeshIntegral(verts, faces, h_big, origin, origin + h * (np.array([nx, ny, nz]) - 1))
    ix = origin[0] + h * np.arange(nx)
    iy = origin[1] + h * np.arange(ny)
    slabs = max(1, CHUNK_NODES // (nx * ny))
    band = 0
    for k0 in range(0, nz, slabs):
        iz = origin[2] + h * np.arange(k0, min(k0 + slabs, nz))
        zz, yy, xx = np.meshgrid(iz, iy, ix, indexing="ij")
        pts = np.column_stack([xx.ravel(), yy.ravel(), zz.ravel()])
        phi = igl.signed_distance(pts, verts, faces, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[0]
        ki = (phi < 0.0).astype(np.float64)
        near = np.flatnonzero(np.abs(phi) < h_big)
        if len(near):
            ki[near] = integral(pts[near], phi[near])
        band += len(near)
        a = 2 * k0 * nx * ny
        pool[a : a + 2 * len(pts) : 2] = phi
        pool[a + 1 : a + 2 * len(pts) : 2] = ki
    return pool, band


# ----------------------------------------------------------------------------- cache
def _key(source, is_file: bool, s: np.ndarray, h_big: float, h: float) -> str:
    """sha256 over VERSION, the mesh (file bytes, or the arrays given), scale, H and h_g."""
    d = hashlib.sha256()
    d.update(VERSION.encode())
    if is_file:
        p = Path(source).expanduser().resolve()
        try:
            d.update(p.suffix.lower().encode() + hashlib.sha256(p.read_bytes()).digest())
        except OSError:
            return ""  # unreadable: no cache, the loader raises the MeshError
    elif isinstance(source, tuple):
        for a in source:
            a = np.ascontiguousarray(a)
            d.update(str(a.dtype).encode() + repr(a.shape).encode() + a.tobytes())
    else:
        try:
            v, f = meshes.mesh_arrays(source)
        except Exception:  # noqa: BLE001 - not a triangle PolyData: no cache, the checks explain
            return ""
        d.update(v.tobytes() + f.tobytes())
    d.update(repr(tuple(float(x).hex() for x in (*s, h_big, h))).encode())
    return d.hexdigest()


def _read(path: Path, label: str, h_big: float, h: float, t0: float) -> MeshField | None:
    """The cached grid, or None when absent, unreadable or not sane (then it is rebuilt)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            header = z["header"]
            if header.shape != (1, HEADER) or header.dtype != np.float64 or not np.all(np.isfinite(header)):
                return None
            dims = header[0, HDR_NX : HDR_NZ + 1].astype(np.int64)
            _check_memory(dims, h, label)
            pool = z["pool"]
    except MeshError:
        raise
    except Exception:  # noqa: BLE001 - missing or unreadable: rebuild
        return None
    if pool.dtype != np.float32 or pool.shape != (2 * int(np.prod(dims)),) or not np.all(np.isfinite(pool)):
        return None
    return MeshField(label, header, pool, h_big, h, 0, time.perf_counter() - t0, True)


def _write(path: Path, header: np.ndarray, pool: np.ndarray) -> None:
    """Best effort, atomic (temp file + rename): a cache that cannot be written only costs time."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.stem, suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, header=header, pool=pool)
        os.replace(tmp, path)
        tmp = None
    except Exception:  # noqa: BLE001
        pass
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
