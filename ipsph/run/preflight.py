"""Pre-flight checks of `ipsph run`: bad input exits 2 before any large allocation.

The particle budget (fluid count estimated before sampling), the radius against each fluid
body's extent, every wall mesh (read, and closed where its inside matters: `check_walls`), the
render size against the available memory. Meshes come from the sampler's
in-process memo (`shapes.mesh_report`), so each mesh is read once per run: these checks, the
sampling and the boundary surface all share it.
"""

from __future__ import annotations

import numpy as np

from ..boundary import model_of
from ..config import Scene
from ..errors import ConfigError
from ..sampling.budget import _fluid_extent, available_memory, check_fluid_count, default_max_particles

RENDER_BYTES_PER_PIXEL = 112  # render process peak: static layers, depth/owner/shade buffers, frame and
# PNG rows, VTK's and llvmpipe's framebuffers (measured 100 B/px at 3840x2160)


def check_render_size(scene: Scene) -> None:
    """Refuse an image size whose render process would need over half the available memory (exit 2)."""
    px = int(scene.render.width) * int(scene.render.height)
    need = px * RENDER_BYTES_PER_PIXEL
    avail = available_memory()
    if need > avail // 2:
        raise ConfigError(
            f"render.width x render.height = {scene.render.width} x {scene.render.height} would need about "
            f"{need / 2**30:.1f} GiB in the render process, over half the available {avail / 2**30:.1f} GiB; "
            f"use a smaller image, or --no-render and `ipsph render OUT --size W H` on a larger machine"
        )


def check_size(scene: Scene, max_particles: int | None) -> int:
    """Estimate the fluid count before sampling and refuse what would not fit (exit 2); with
    emitters, the planned capacity (initial fluid + every layer they can emit) must fit too."""
    n = check_fluid_count(scene.fluids, scene.particle_radius, max_particles, model_of(scene).fluid_inset_d)
    if scene.emitters:
        from ..flow import check_capacity, check_placement

        check_placement(scene)
        n = check_capacity(scene, n, max_particles or default_max_particles())
    return n


def check_geometry(scene: Scene) -> None:
    """Refuse a particle radius too large for a fluid body: fewer than 2 particles across it, and a
    wall mesh whose inside is undefined (`check_walls`) (exit 2)."""
    check_walls(scene)
    d = scene.spacing
    for i, spec in enumerate(scene.fluids):
        ext = _fluid_extent(spec)
        if ext is None:
            continue
        # box fluids: SPlisHSPlasH's round(extent / d) - 1 per axis; meshes: the lattice across the bounds
        n = np.floor(ext / d + 0.5) - 1 if spec.shape == "box" else np.floor(ext / d)
        if n.min() < 2:
            a = int(np.argmin(n))
            need = ext[a] / (5.0 if spec.shape == "box" else 4.0)
            raise ConfigError(
                f"fluid[{i}] '{spec.name}': simulation.particle_radius {scene.particle_radius} m is too large for "
                f"its extent of {ext[a]:.4g} m along {'xyz'[a]} ({int(max(n[a], 0))} particle(s) across, at least 2 "
                f"needed); use particle_radius <= {need:.3g} m (a tenth of that or less for useful results)"
            )


def check_backend(scene: Scene) -> None:
    """simulation.backend can run here (for cuda: numba-cuda, a driver, the device); ConfigError
    naming what is missing, before anything is allocated. Both backends have both precisions."""
    if scene.backend == "cuda":
        from ..backends._cuda import unavailable

        why = unavailable(scene.device)
        if why is not None:
            raise ConfigError(f'simulation.backend = "cuda": {why}')


def check_walls(scene: Scene) -> None:
    """Read every wall mesh now, before sampling (an unreadable one is refused here), and refuse an
    obstacle or dynamic body whose mesh is not closed: its inside decides where fluid may start and
    where its particles lie, and an open surface has none. Containers may be open (the fluid lies
    inside the winding number's half); an obstacle with allow_open_mesh = true is a thin shell."""
    from ..config import Role
    from ..errors import MeshError
    from ..geometry.meshes import fmt_point
    from ..geometry.shapes import mesh_report

    for i, spec in enumerate(scene.boundaries):
        if spec.shape != "mesh":
            continue
        report = mesh_report(spec)
        if report.closed or spec.role == Role.CONTAINER or (spec.allow_open_mesh and not spec.dynamic):
            continue
        what = "a dynamic body" if spec.dynamic else "an obstacle"
        fix = (
            ""
            if spec.dynamic
            else f", or set allow_open_mesh = true (--set boundary.{i}.allow_open_mesh=true) for a thin shell"
        )
        raise MeshError(
            f"boundary[{i}] '{spec.name}' is {what}, but its mesh {spec.mesh} has no inside: not closed and "
            f"consistently oriented ({report.open_edges} open edges, {report.unpaired_edges} unpaired, one at "
            f"{fmt_point(report.open_at)}); repair the mesh{fix}"
        )
