"""The containers' boxes: the bounds of every `role = "container"` boundary's surface, once.

Emitters check their nozzles against them, the surface reconstruction clips to them, the output
folder stores them for `ipsph surface`.
"""

from __future__ import annotations

import numpy as np

from ..config import Role


def container_boxes(boundaries) -> list[tuple[np.ndarray, np.ndarray]]:
    """(lo, hi) of each container boundary's surface (m)."""
    from ..geometry.shapes import boundary_surface

    out = []
    for b in boundaries:
        if b.role == Role.CONTAINER:
            bb = np.asarray(boundary_surface(b).bounds, dtype=np.float64).reshape(3, 2)
            out.append((bb[:, 0], bb[:, 1]))
    return out


def container_bounds(boundaries) -> list[float] | None:
    """[xmin, xmax, ymin, ymax, zmin, zmax] around the container walls (m), or None without one."""
    boxes = container_boxes(boundaries)
    if not boxes:
        return None
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    return [float(v) for pair in zip(lo, hi) for v in pair]
