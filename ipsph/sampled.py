"""The sampled scene: a Scene's fluid and wall particles, built once per run from its bodies.

`sample_scene` is the one place a run goes from a `Scene` to particles (the sampling itself is
`ipsph.sampling`'s); `wall_groups` says which moving wall each wall particle belongs to.
"""

from __future__ import annotations

import numpy as np

from .model import Scene


def sample_scene(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Fluid positions and velocities, wall particles, and notes on what was removed.

    Fluid particles inside an obstacle, outside every container, or closer than d = 2r to a
    wall particle are removed and counted (the lattice would otherwise start inside a wall).
    """
    from . import sampling

    r = scene.particle_radius
    xs, vs = [np.zeros((0, 3))], [np.zeros((0, 3))]
    frame = sampling.lattice_frame(scene)  # mesh fluids share the walls' rest lattice
    for spec in scene.fluids:
        x = sampling.fluid_positions(spec, r, frame=frame)
        xs.append(x)
        vs.append(np.tile(np.asarray(spec.velocity, dtype=np.float64), (len(x), 1)))
    fluid_x, fluid_v = np.concatenate(xs), np.concatenate(vs)
    walls = [sampling.boundary_positions(spec, r) for spec in scene.boundaries]
    boundary_x = np.concatenate([np.zeros((0, 3))] + walls)
    notes = [n for spec in (*scene.fluids, *scene.boundaries) for n in sampling.mesh_notes(spec)]
    if len(scene.boundaries) and len(fluid_x):
        kept, removed = sampling.remove_overlaps(
            fluid_x, boundary_x, sampling.default_overlap_distance(r), boundaries=scene.boundaries, radius=r
        )
        if any(spec.dynamic for spec in scene.boundaries):  # a wider gap around rigid bodies (rigid.BODY_GAP_D)
            from .rigid import body_gap_mask

            kept &= body_gap_mask(fluid_x, scene, walls, r)
            removed = int(len(fluid_x) - kept.sum())
        if removed:
            notes.append(
                f"{removed} of {len(fluid_x)} fluid particles overlapped a wall or lay outside the "
                f"containers and were removed"
            )
            fluid_x, fluid_v = fluid_x[kept], fluid_v[kept]
    if scene.emitters:
        from .emitters import wall_notes

        notes += wall_notes(scene, boundary_x)
    return np.ascontiguousarray(fluid_x), np.ascontiguousarray(fluid_v), np.ascontiguousarray(boundary_x), notes


def wall_groups(scene: Scene, n_walls: int) -> np.ndarray | None:
    """Per wall particle, which moving wall it belongs to (rigid.boundary_groups; None: all static)."""
    if not any(b.moving for b in scene.boundaries):
        return None
    from .rigid import boundary_groups
    from .sampling import boundary_positions

    counts = [len(boundary_positions(spec, scene.particle_radius)) for spec in scene.boundaries]
    if sum(counts) != n_walls:
        raise ValueError(f"{n_walls} wall particles given, the scene's walls sample {sum(counts)}")
    return boundary_groups(scene, counts)
