"""The gauges' refusal that needs the walls' geometry: a gauge outside the domain (exit 2, before
anything is created; the rules between keys are `ipsph.scene.gauges`')."""

from __future__ import annotations

import numpy as np

from ..boundary.containers import container_boxes
from ..config import Scene
from ..errors import ConfigError


def _points(g) -> list[tuple[str, tuple]]:
    """(key, point) of each place a gauge must lie inside the domain."""
    if g.kind == "point":
        return [("position", g.position)]
    if g.kind == "level":
        x, _, z = g.position
        return [("position", g.position), ("top", (x, g.top, z))]
    if g.kind == "flow":
        return [("min", g.box_min), ("max", g.box_max)]
    return []  # force: on a wall; its torque point may lie anywhere


def check_placement(scene: Scene) -> None:
    """Every gauge inside a container's bounds or the [domain] box, when the scene has either
    (ConfigError naming the key); a scene with neither has no outside."""
    if not scene.gauges:
        return
    boxes = container_boxes(scene.boundaries)
    dom = scene.domain
    if dom.min is not None:
        boxes.append((np.asarray(dom.min), np.asarray(dom.max)))
    if not boxes:
        return
    for i, g in enumerate(scene.gauges):
        for key, p in _points(g):
            q = np.asarray(p, dtype=np.float64)
            if not any(np.all(q >= lo) and np.all(q <= hi) for lo, hi in boxes):
                where = "outside every container's bounds" + (" and the [domain] box" if dom.min is not None else "")
                raise ConfigError(
                    f"gauge[{i}].{key}: [{', '.join(f'{c:g}' for c in q)}] of gauge '{g.name}' lies {where}; "
                    f"move it inside the fluid's domain"
                )
