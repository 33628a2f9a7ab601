"""Surface meshes of the fluid: the one module that calls splashsurf (`pysplashsurf`).

splashsurf (Löschner et al., the SPlisHSPlasH group) reconstructs the iso-surface of an SPH
"colour field" on a marching-cubes grid, smooths it with weights that only move vertices near
the free surface, and interpolates particle attributes onto the vertices. Lengths it takes are
multiples of the particle radius r, as in our `[surface]` table (`ipsph.config.SurfaceConfig`).

    reconstruct(points, velocities, r, rho0, config)  -> Surface (vertices, triangles, normals, velocity)
    write_surface(path, surface, fmt, time)          -> .vtp (ParaView), .obj or .ply (Houdini, Blender)
    surface_output(OUT, fmt=...)                      -> `ipsph surface OUT`: every frame, skipping those done

A frame whose reconstruction fails (no particles, non-finite positions, splashsurf's own error,
no triangles) raises `SurfaceFailed` with a one-line reason; callers report it and carry on.
"""

from __future__ import annotations

import os
import sys
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import SurfaceConfig

__all__ = ["SurfaceFailed", "Surface", "reconstruct", "write_surface", "read_vtp", "surface_output", "FORMATS"]

FORMATS = ("vtp", "obj", "ply")


class SurfaceFailed(Exception):
    """One frame has no surface; the message is one line saying why."""


@dataclass
class Surface:
    vertices: np.ndarray  # (V, 3) float32, m
    triangles: np.ndarray  # (T, 3) int64, counter-clockwise seen from outside
    normals: np.ndarray  # (V, 3) float32, unit, outward
    velocity: np.ndarray | None  # (V, 3) float32, m/s, SPH-interpolated from the particles
    seconds: float = 0.0  # reconstruction wall time

    @property
    def speed(self) -> np.ndarray | None:
        return None if self.velocity is None else np.linalg.norm(self.velocity, axis=1).astype(np.float32)


def set_threads(n: int | None) -> None:
    """Threads splashsurf's (rayon) pool starts with; only effective before the first reconstruction."""
    if n:
        os.environ["RAYON_NUM_THREADS"] = str(int(n))


def reconstruct(
    points: np.ndarray,
    velocities: np.ndarray | None,
    particle_radius: float,
    rest_density: float,
    config: SurfaceConfig = SurfaceConfig(),  # noqa: B008 - a frozen dataclass, immutable
    clip_bounds=None,
) -> Surface:
    """The surface of one frame of fluid particles (positions in m); raises SurfaceFailed.

    clip_bounds [xmin, xmax, ymin, ymax, zmin, zmax] (m): the containers' box. Triangles outside it are
    dropped and vertices clamped into it: next to a wall the colour field lacks the wall's share, so
    the iso-surface closes between the last particles and the wall and can bulge a fraction of r
    through it where particles sit closer than r (a 0.04 m dam break: 0.0037 m below the floor).
    """
    x = np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 3))
    if len(x) == 0:
        raise SurfaceFailed("no fluid particles in the frame")
    if not np.isfinite(x).all():
        raise SurfaceFailed(f"{int((~np.isfinite(x).all(axis=1)).sum())} particles have non-finite positions")
    attrs = {}
    if velocities is not None and len(velocities) == len(x):
        attrs["velocity"] = np.ascontiguousarray(np.asarray(velocities, dtype=np.float32).reshape(-1, 3))
    import pysplashsurf

    c = config
    box = {}
    if clip_bounds is not None:
        b = np.asarray(clip_bounds, dtype=float).reshape(3, 2)
        box = dict(mesh_aabb_min=b[:, 0].tolist(), mesh_aabb_max=b[:, 1].tolist(), mesh_aabb_clamp_vertices=True)
    t0 = _time.perf_counter()
    try:
        mesh, _ = pysplashsurf.reconstruction_pipeline(
            x,
            attributes_to_interpolate=attrs,
            particle_radius=float(particle_radius),
            rest_density=float(rest_density),
            smoothing_length=float(c.smoothing_length),
            cube_size=float(c.cube_size),
            iso_surface_threshold=float(c.iso_threshold),
            mesh_smoothing_iters=int(c.mesh_smoothing_iterations) or None,
            mesh_smoothing_weights=True,
            normals_smoothing_iters=int(c.normal_smoothing_iterations) or None,
            compute_normals=True,
            decimate_barnacles=bool(c.decimate),
            mesh_cleanup=bool(c.decimate),
            multi_threading=True,
            **box,
        )
    except BaseException as exc:  # splashsurf raises its errors as plain exceptions (a Rust panic: PanicException)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        raise SurfaceFailed(f"splashsurf: {' '.join(str(exc).split()) or type(exc).__name__}") from None
    seconds = _time.perf_counter() - t0
    tris = np.asarray(mesh.mesh.triangles).astype(np.int64, copy=False).reshape(-1, 3)
    if len(tris) == 0:
        raise SurfaceFailed(
            f"no surface: {len(x)} particles too sparse for iso_threshold {c.iso_threshold} "
            f"(a spray or a few stray particles)"
        )
    pa = mesh.point_attributes
    vel = pa.get("velocity")
    return Surface(
        np.asarray(mesh.mesh.vertices, dtype=np.float32),
        tris,
        np.asarray(pa["normals"], np.float32),
        None if vel is None else np.asarray(vel, np.float32),
        seconds,
    )


# -- files -----------------------------------------------------------------------------------------
def to_polydata(s: Surface, time: float | None = None):
    """A vtkPolyData: triangles, point normals ("Normals", active), "velocity", "speed", TimeValue."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    poly = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(s.vertices, np.float32), deep=True))
    poly.SetPoints(pts)
    cells = vtkCellArray()
    offsets = np.arange(0, 3 * len(s.triangles) + 1, 3, dtype=np.int64)
    cells.SetData(
        numpy_to_vtkIdTypeArray(offsets, deep=True),
        numpy_to_vtkIdTypeArray(np.ascontiguousarray(s.triangles.ravel(), np.int64), deep=True),
    )
    poly.SetPolys(cells)
    pd = poly.GetPointData()
    normals = numpy_to_vtk(np.ascontiguousarray(s.normals, np.float32), deep=True)
    normals.SetName("Normals")
    pd.SetNormals(normals)
    if s.velocity is not None:
        for name, a in (("velocity", s.velocity), ("speed", s.speed)):
            arr = numpy_to_vtk(np.ascontiguousarray(a, np.float32), deep=True)
            arr.SetName(name)
            pd.AddArray(arr)
        pd.SetActiveScalars("speed")
    if time is not None:
        tv = vtkDoubleArray()
        tv.SetName("TimeValue")
        tv.InsertNextValue(float(time))
        poly.GetFieldData().AddArray(tv)
    return poly


def from_polydata(poly) -> Surface:
    """The Surface of a .vtp this module wrote (to convert it to OBJ / PLY, or to render it)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    v = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float32) if poly.GetNumberOfPoints() else np.zeros((0, 3))
    conn = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).astype(np.int64).reshape(-1, 3)
    pd = poly.GetPointData()
    n = pd.GetArray("Normals")
    vel = pd.GetArray("velocity")
    return Surface(
        v,
        conn,
        vtk_to_numpy(n).astype(np.float32) if n is not None else np.zeros_like(v),
        vtk_to_numpy(vel).astype(np.float32) if vel is not None else None,
    )


def read_vtp(path) -> Surface:
    from ..io.vtu import read_surface

    poly = read_surface(path)
    if poly is None:
        raise SurfaceFailed(f"{path} does not exist")
    return from_polydata(poly)


def write_surface(path, s: Surface, fmt: str = "vtp", time: float | None = None) -> int:
    """Write one surface atomically as .vtp (VTK XML, every array), .ply (binary; x y z, nx ny nz,
    vx vy vz, speed: Houdini and Blender read them) or .obj (v, vn: positions and normals only)."""
    from ..io import atomic_path
    from ..io.vtu import write_surface as write_vtp

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if fmt == "vtp":
        return write_vtp(path, to_polydata(s, time))
    if fmt == "obj":  # by hand: meshio's faces do not reference the normals ("f a//a"), so importers drop them
        f = s.triangles + 1
        faces = np.stack([f, f], axis=2).reshape(-1, 6)
        with atomic_path(path, "surface") as tmp, open(tmp, "w") as out:
            out.write(
                f"# ipsph surface{'' if time is None else f' t = {time!r} s'}: {len(s.vertices)} vertices, "
                f"{len(s.triangles)} triangles, outward normals\n"
            )
            np.savetxt(out, s.vertices, fmt="v %.7g %.7g %.7g")
            np.savetxt(out, s.normals, fmt="vn %.6g %.6g %.6g")
            np.savetxt(out, faces, fmt="f %d//%d %d//%d %d//%d")
        return os.path.getsize(path)
    import meshio

    point_data = {}
    if fmt == "ply":
        for k, axis in enumerate("xyz"):
            point_data[f"n{axis}"] = s.normals[:, k]
        if s.velocity is not None:
            for k, axis in enumerate("xyz"):
                point_data[f"v{axis}"] = s.velocity[:, k]
            point_data["speed"] = s.speed
    else:
        raise ValueError(f"surface format {fmt!r} is not one of {', '.join(FORMATS)}")
    mesh = meshio.Mesh(s.vertices, [("triangle", s.triangles.astype(np.int32))], point_data=point_data)
    with atomic_path(path, "surface") as tmp:
        meshio.write(tmp, mesh, file_format=fmt, **({"binary": True} if fmt == "ply" else {}))
    return os.path.getsize(path)


def container_bounds_of(scene_dict: dict) -> list[float] | None:
    """container_bounds of a stored scene's box containers (run.json without surface.clip_bounds)."""
    boxes = [
        b["box"]
        for b in scene_dict.get("boundary", [])
        if b.get("role", "container") == "container" and isinstance(b.get("box"), dict)
    ]
    if not boxes:
        return None
    lo = np.min([b["min"] for b in boxes], axis=0)
    hi = np.max([b["max"] for b in boxes], axis=0)
    return [float(v) for pair in zip(lo, hi) for v in pair]


# -- `ipsph surface OUT` ---------------------------------------------------------------------------
def surface_output(out_dir, *, fmt: str = "vtp", overrides=(), threads: int | None = None, log=None) -> dict:
    """Reconstruct every frame of a finished or running output folder that has no surface in `fmt` yet.

    Settings: the run's `[surface]` table (run.json), changed by `overrides` (`surface.cube_size=0.5`).
    An OBJ/PLY of a frame whose .vtp exists is converted from it rather than reconstructed again.
    .vtp surfaces are added to run.pvd. Returns {"written": [...], "skipped": n, "failed": {index: why}}.
    """
    from .. import io as out_io
    from ..errors import OutputError
    from ..io.provenance import read_run_json
    from ..io.pvd import PvdSeries, frame_index
    from ..io.vtu import read_particles
    from ..scene import surface_config

    log = log or (lambda msg: print(msg, file=sys.stderr))
    out = Path(out_dir)
    if fmt not in FORMATS:
        raise OutputError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
    if not (out / out_io.RUN_PVD).is_file():
        raise OutputError(
            f"{out} (resolved {out.resolve()}) holds no {out_io.RUN_PVD}: give the output folder of `ipsph run`"
        )
    run = read_run_json(out / out_io.RUN_JSON) if (out / out_io.RUN_JSON).is_file() else {}
    scene = run.get("scene") or {}
    config = surface_config(scene, overrides, where="ipsph surface")
    radius = run.get("particle_radius") or (scene.get("simulation") or {}).get("particle_radius")
    if radius is None:
        raise OutputError(f"{out}: run.json gives no particle_radius; the surface needs it")
    rho0 = float((scene.get("simulation") or {}).get("density0", 1000.0))
    running = run.get("status") == "running"
    clip = (run.get("surface") or {}).get("clip_bounds") or container_bounds_of(scene)
    set_threads(threads)
    series = PvdSeries.load(out / out_io.RUN_PVD)
    written, failed, skipped = [], {}, 0
    listed = _time.perf_counter()
    for k, (t, f) in enumerate(series.frames):
        i = frame_index(f, k)
        target = out / out_io.surface_file(i, fmt)
        vtp = out / out_io.surface_file(i, "vtp")
        if target.is_file():
            skipped += 1
            if fmt == "vtp" and t not in series.surfaces:  # written by a run that ended before listing it
                series.add_surface(t, out_io.surface_file(i, "vtp"))
            continue
        try:
            if vtp.is_file() and not overrides:  # the same settings: convert, do not reconstruct again
                surf = read_vtp(vtp)
            else:
                pts, fields, _ = read_particles(out / f)
                surf = reconstruct(pts, fields.get("velocity"), radius, rho0, config, clip)
            write_surface(target, surf, fmt, time=t)
        except SurfaceFailed as exc:
            failed[i] = str(exc)
            log(f"ipsph: warning: frame {i} (t = {t:.4g} s) has no surface: {exc}")
            continue
        written.append(target)
        if fmt == "vtp":
            series.add_surface(t, out_io.surface_file(i, "vtp"))
            if _time.perf_counter() - listed > 2.0:  # a reader sees progress; no rewrite per surface
                series.write()
                listed = _time.perf_counter()
    if fmt == "vtp":
        series.write()
        if running and written:
            log(
                f"ipsph: note: {out} is still running; its run.pvd is rewritten at every frame without these "
                f"surfaces: run `ipsph surface {out}` again when it has finished to list them (it skips the "
                f"surfaces already written)"
            )
    return {"written": written, "skipped": skipped, "failed": failed, "config": config}
