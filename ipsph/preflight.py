"""Pre-flight checks of `ipsph run`: bad input exits 2 before any large allocation.

The particle budget (fluid count estimated before sampling), the radius against each fluid
body's extent, the render size against the available memory. Meshes come from the sampler's
in-process memo (`sampling.mesh_report`), so each mesh is read once per run: these checks, the
sampling and the boundary surface all share it.
"""

from __future__ import annotations

import numpy as np

from . import sampling
from .errors import ConfigError
from .model import Scene
from .params import BYTES_PER_PARTICLE

RENDER_BYTES_PER_PIXEL = 112  # render process peak: static layers, depth/owner/shade buffers, frame and
# PNG rows, VTK's and llvmpipe's framebuffers (measured 100 B/px at 3840x2160)


def available_memory() -> int:
    """Bytes of memory available to this run now (psutil; 8 GiB if it cannot tell)."""
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except Exception:  # pragma: no cover - psutil is a dependency
        return 8 << 30


def default_max_particles() -> int:
    """Half the available memory at BYTES_PER_PARTICLE per particle."""
    return int(available_memory() // 2 // BYTES_PER_PARTICLE)


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
    n = check_fluid_count(scene.fluids, scene.particle_radius, max_particles)
    if scene.emitters:
        from .emitters import check_capacity, check_placement

        check_placement(scene)
        n = check_capacity(scene, n, max_particles or default_max_particles())
    return n


def check_fluid_count(fluids, radius: float, max_particles: int | None) -> int:
    """The estimated fluid count of `fluids` at `radius`; ConfigError above the limit (default: memory)."""
    limit = max_particles or default_max_particles()
    total = 0
    for spec in fluids:
        n = sampling.estimate_fluid_count(spec, radius)
        total += n
        if total > limit:
            ext = _extent_hint(spec)
            raise ConfigError(
                f"fluid '{spec.name}' would need about {total:,} particles ({total * BYTES_PER_PARTICLE / 2**30:.1f} GiB) "
                f"at particle_radius {radius} m, over the limit of {limit:,} (--max-particles){ext}"
            )
    return total


def check_geometry(scene: Scene) -> None:
    """Refuse a particle radius too large for a fluid body: fewer than 2 particles across it (exit 2)."""
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


def _fluid_extent(spec) -> np.ndarray | None:
    """Extent (m) of a fluid body after its transform's scale, or None when its mesh cannot be read."""
    if spec.shape == "box" and spec.box_min is not None:
        return np.abs(np.subtract(spec.box_max, spec.box_min) * np.asarray(spec.transform.scale))
    try:
        b = np.asarray(sampling.mesh_report(spec).bounds).reshape(3, 2)
    except Exception:  # the sampler reports unreadable meshes with the full story
        return None
    return b[:, 1] - b[:, 0]


def _extent_hint(spec) -> str:
    ext = _fluid_extent(spec)
    if ext is None:
        return ""
    hint = f"; its {'mesh ' if spec.shape != 'box' else ''}extent is {ext[0]:.4g} x {ext[1]:.4g} x {ext[2]:.4g} m"
    if ext.max() > 100:
        hint += " (a mesh 1000x too large is probably in millimetres: scale it by 0.001)"
    return hint


def check_backend(scene: Scene) -> None:
    """simulation.backend can run here (for cuda: numba-cuda, a driver, the device); ConfigError
    naming what is missing, before anything is allocated. Both backends have both precisions."""
    if scene.backend == "cuda":
        from .backends._cuda import unavailable

        why = unavailable(scene.device)
        if why is not None:
            raise ConfigError(f'simulation.backend = "cuda": {why}')
