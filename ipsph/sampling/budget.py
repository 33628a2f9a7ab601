"""The particle budget before sampling: how many fluid particles a scene's fluids will make, and
whether they fit in the memory available (exit 2 before any large allocation)."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..geometry import shapes
from ..params import BYTES_PER_PARTICLE
from . import fluid as sampling


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


def check_fluid_count(fluids, radius: float, max_particles: int | None, inset_d: float = 1.0) -> int:
    """The estimated fluid count of `fluids` at `radius` (box fluids' first layers inset_d * d inside
    their faces, the boundary model's `fluid_inset_d`); ConfigError above the limit (default: memory)."""
    limit = max_particles or default_max_particles()
    total = 0
    for spec in fluids:
        n = sampling.estimate_fluid_count(spec, radius, inset_d)
        total += n
        if total > limit:
            ext = _extent_hint(spec)
            raise ConfigError(
                f"fluid '{spec.name}' would need about {total:,} particles ({total * BYTES_PER_PARTICLE / 2**30:.1f} GiB) "
                f"at particle_radius {radius} m, over the limit of {limit:,} (--max-particles){ext}"
            )
    return total


def _fluid_extent(spec) -> np.ndarray | None:
    """Extent (m) of a fluid body after its transform's scale, or None when its mesh cannot be read."""
    if spec.shape == "box" and spec.box_min is not None:
        return np.abs(np.subtract(spec.box_max, spec.box_min) * np.asarray(spec.transform.scale))
    try:
        b = np.asarray(shapes.mesh_report(spec).bounds).reshape(3, 2)
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
