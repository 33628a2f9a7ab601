"""The sampled scene: a Scene's fluid and wall particles, built once per run from its bodies.

`sample(scene)` is the one place a run goes from a `Scene` to particles (the sampling itself is
`ipsph.sampling.fluid`'s); `ipsph run` samples before it creates its output folder, refuses what
only the particles show (`check_sampled`), and hands the same `SampledScene` to `Simulation`.
`sample_scene` is the same as a tuple; `wall_groups` says which moving wall each wall particle
belongs to.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..boundary import model_of
from ..config import Scene
from ..errors import ConfigError
from ..geometry.meshes import fmt_point


@dataclass
class SampledScene:
    """A scene's particles at t = 0: the fluid (after removing what overlaps a wall or lies
    outside every container), the walls in [[boundary]] order, and what sampling noticed."""

    fluid_x: np.ndarray
    fluid_v: np.ndarray
    boundary_x: np.ndarray
    notes: list[str]
    wall_counts: list[int]  # wall particles per [[boundary]] entry, in order
    fluid_sampled: int = 0  # fluid particles before the overlap removal
    seconds: float = field(default=0.0, compare=False)
    fluid_counts: list[int] = field(default_factory=list)  # fluid particles per [[fluid]] entry, in order


def sample(scene: Scene) -> SampledScene:
    """The scene's particles (see `sample_scene`), with the per-wall counts and timing."""
    t0 = time.perf_counter()
    fx, fv, bx, notes, counts, n0, fluid_counts = _sample(scene)
    return SampledScene(fx, fv, bx, notes, counts, n0, time.perf_counter() - t0, fluid_counts)


def check_sampled(scene: Scene, s: SampledScene) -> None:
    """Refuse a scene whose particles cannot run (ConfigError, exit 2): rigid bodies that overlap
    each other or reach through a wall, fluid bodies that overlap each other, no fluid at all, or
    all of it outside every container or inside walls (a scene with emitters may start empty)."""
    _check_bodies_apart(scene, s)
    _check_bodies_clear_of_walls(scene, s)
    _check_fluids_apart(scene, s)
    if len(s.fluid_x) or scene.emitters:
        return
    if s.fluid_sampled:
        raise ConfigError(
            f"all {s.fluid_sampled:,} fluid particles lie outside every container or inside a wall, so "
            f"none is left to simulate: move the [[fluid]] entries inside a container's [[boundary]]"
        )
    raise ConfigError(
        "the scene has no fluid particles after sampling (check [[fluid]] entries and "
        "that the fluid lies inside its container)"
    )


def _check_bodies_apart(scene: Scene, s: SampledScene) -> None:
    """Two rigid bodies must not start inside each other: one body's wall particles (sampled behind
    inside its surface) inside the other's surface would push both apart violently at t = 0."""
    bodies = [k for k, b in enumerate(scene.boundaries) if b.dynamic]
    if len(bodies) < 2:
        return
    from ..geometry.inside import inside_mesh
    from ..geometry.shapes import boundary_surface

    starts = np.concatenate([[0], np.cumsum(s.wall_counts)]).astype(int)
    surfaces = {k: boundary_surface(scene.boundaries[k]) for k in bodies}
    for k in bodies:
        pts = s.boundary_x[starts[k] : starts[k + 1]]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        for j in bodies:
            if j == k:
                continue
            b = np.asarray(surfaces[j].bounds).reshape(3, 2)
            if np.any(hi < b[:, 0]) or np.any(lo > b[:, 1]):
                continue  # the boxes around them do not meet
            n = int(inside_mesh(pts, surfaces[j], scene.spacing).sum())
            if n:
                a, o = scene.boundaries[k], scene.boundaries[j]
                raise ConfigError(
                    f"boundary[{k}] '{a.name}' and boundary[{j}] '{o.name}' are rigid bodies that overlap at "
                    f"t = 0 ({n} of '{a.name}''s wall particles lie inside '{o.name}'): move them apart"
                )


def _check_bodies_clear_of_walls(scene: Scene, s: SampledScene) -> None:
    """A rigid body must not start through a wall (its container's, an obstacle's, a moving wall's):
    the wall's particles inside the body would fling it at t = 0. Measured by the wall particles
    that lie inside the body's surface, and how deep the deepest lies."""
    bodies = [k for k, b in enumerate(scene.boundaries) if b.dynamic]
    if not bodies:
        return
    from ..geometry.inside import inside_mesh
    from ..geometry.shapes import boundary_surface

    starts = np.concatenate([[0], np.cumsum(s.wall_counts)]).astype(int)
    for j in bodies:
        surface = boundary_surface(scene.boundaries[j])
        b = np.asarray(surface.bounds).reshape(3, 2)
        for k, wall in enumerate(scene.boundaries):
            if wall.dynamic:
                continue  # two bodies: _check_bodies_apart
            pts = s.boundary_x[starts[k] : starts[k + 1]]
            pts = pts[np.all((pts >= b[:, 0]) & (pts <= b[:, 1]), axis=1)]
            if not len(pts):
                continue
            inside = pts[inside_mesh(pts, surface, scene.spacing)]
            if len(inside):
                _, nearest = surface.find_closest_cell(inside, return_closest_point=True)
                depth = np.linalg.norm(inside - nearest, axis=1)
                body, deep = scene.boundaries[j], int(np.argmax(depth))
                raise ConfigError(
                    f"boundary[{j}] '{body.name}' is a rigid body that starts through the wall of boundary[{k}] "
                    f"'{wall.name}': {len(inside)} of '{wall.name}''s wall particles lie inside it, up to "
                    f"{depth[deep]:.3g} m deep (near {fmt_point(inside[deep])}); move the body clear of the wall"
                )


def _check_fluids_apart(scene: Scene, s: SampledScene) -> None:
    """Two fluid bodies must not overlap: their particles would start on top of each other (closer
    than the spacing d, the lattice's own) and blow apart. Boxes that only touch pass (a box's
    lattice keeps d/2 or more from its faces, d from its min faces), and so do mesh fluids (one
    lattice for all of them)."""
    counts = s.fluid_counts
    if len(counts) < 2:
        return
    from ..geometry.points import nearest_distance

    d = scene.spacing
    near = (1.0 - 1e-6) * d
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    parts = [s.fluid_x[starts[i] : starts[i + 1]] for i in range(len(counts))]
    for i in range(len(parts)):
        for j in range(i + 1, len(parts)):
            a, b = parts[i], parts[j]
            if not len(a) or not len(b):
                continue
            lo = np.maximum(a.min(axis=0), b.min(axis=0)) - d
            hi = np.minimum(a.max(axis=0), b.max(axis=0)) + d
            if np.any(lo > hi):
                continue  # the boxes around them do not meet
            a = a[np.all((a >= lo) & (a <= hi), axis=1)]
            b = b[np.all((b >= lo) & (b <= hi), axis=1)]
            b_close = b[nearest_distance(b, a, d) < near]
            if not len(b_close):
                continue
            a_close = a[nearest_distance(a, b_close, d) < near]
            fi, fj = scene.fluids[i], scene.fluids[j]
            box = _box_overlap(fi, fj)
            if box is None:  # meshes: the box around the crowded particles
                both = np.concatenate([a_close, b_close])
                box = both.min(axis=0), both.max(axis=0)
            raise ConfigError(
                f"fluid[{i}] '{fi.name}' and fluid[{j}] '{fj.name}' overlap in the box min {fmt_point(box[0])}, "
                f"max {fmt_point(box[1])}: {len(a_close) + len(b_close)} of their particles start closer than "
                f"d = 2r = {d:.4g} m to the other's; move them apart or shrink one"
            )


def _box_overlap(a, b) -> tuple[np.ndarray, np.ndarray] | None:
    """Where two axis-aligned box fluids meet (their boxes' intersection), else None."""
    if a.shape != "box" or b.shape != "box" or a.transform.rotate_deg or b.transform.rotate_deg:
        return None
    from ..geometry.shapes import scaled_box

    (alo, ahi), (blo, bhi) = scaled_box(a), scaled_box(b)
    at, bt = np.asarray(a.transform.translate), np.asarray(b.transform.translate)
    lo, hi = np.maximum(alo + at, blo + bt), np.minimum(ahi + at, bhi + bt)
    return (lo, hi) if np.all(lo < hi) else None


def sample_scene(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Fluid positions and velocities, wall particles, and notes on what was removed."""
    return _sample(scene)[:4]


def _sample(scene: Scene):
    """(fluid_x, fluid_v, boundary_x, notes, wall counts, fluid count before removal, fluid
    particles per [[fluid]] after it).

    Fluid particles inside an obstacle, outside every container, or closer than d = 2r to a
    wall particle are removed and counted (the lattice would otherwise start inside a wall).
    """
    from ..geometry.shapes import mesh_notes
    from . import fluid as sampling

    r = scene.particle_radius
    xs, vs = [np.zeros((0, 3))], [np.zeros((0, 3))]
    inset = model_of(scene).fluid_inset_d
    frame = sampling.lattice_frame(scene, inset)  # mesh fluids share the walls' rest lattice
    for spec in scene.fluids:
        x = sampling.fluid_positions(spec, r, frame=frame, inset_d=inset)
        xs.append(x)
        vs.append(np.tile(np.asarray(spec.velocity, dtype=np.float64), (len(x), 1)))
    fluid_x, fluid_v = np.concatenate(xs), np.concatenate(vs)
    n_sampled = len(fluid_x)
    fluid_counts = [len(x) for x in xs[1:]]
    walls = [model_of(scene).samples(spec, r) for spec in scene.boundaries]
    boundary_x = np.concatenate([np.zeros((0, 3))] + walls)
    notes = [n for spec in (*scene.fluids, *scene.boundaries) for n in mesh_notes(spec)]
    if len(scene.boundaries) and len(fluid_x):
        kept, removed = sampling.remove_overlaps(
            fluid_x, boundary_x, sampling.default_overlap_distance(r), boundaries=scene.boundaries, radius=r
        )
        kept &= model_of(scene).keep_fluid(fluid_x, scene)  # field walls: d/2 from every surface
        removed = int(len(fluid_x) - kept.sum())
        if any(spec.dynamic for spec in scene.boundaries):  # a wider gap around bodies (BODY_GAP_D)
            from ..boundary.sampling import body_gap_mask

            kept &= body_gap_mask(fluid_x, scene, walls, r)
            removed = int(len(fluid_x) - kept.sum())
        if removed:
            notes.append(
                f"{removed} of {len(fluid_x)} fluid particles overlapped a wall or lay outside the "
                f"containers and were removed"
            )
            fluid_x, fluid_v = fluid_x[kept], fluid_v[kept]
            ends = np.cumsum(fluid_counts)
            fluid_counts = [int(kept[e - n : e].sum()) for n, e in zip(fluid_counts, ends)]
    if scene.emitters:
        from ..flow import wall_notes

        notes += wall_notes(scene, boundary_x)
    fluid_x, fluid_v, boundary_x = (np.ascontiguousarray(a) for a in (fluid_x, fluid_v, boundary_x))
    return fluid_x, fluid_v, boundary_x, notes, [len(w) for w in walls], n_sampled, fluid_counts


def wall_groups(
    scene: Scene, n_walls: int, counts: list[int] | None = None
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Per wall particle, which moving wall it belongs to (rigid.boundary_groups) and how deep its
    layer lies behind its surface (contacts act on surfaces); (None, None) when every wall is static.
    `counts`: the wall particles per [[boundary]] entry, when the caller sampled them
    (`SampledScene.wall_counts`); else they are sampled again."""
    if not any(b.moving for b in scene.boundaries):
        return None, None
    from ..boundary.rigid import boundary_groups

    walls, r = model_of(scene), scene.particle_radius
    if counts is None:
        counts = [len(walls.samples(spec, r)) for spec in scene.boundaries]
    if sum(counts) != n_walls:
        raise ValueError(f"{n_walls} wall particles given, the scene's walls sample {sum(counts)}")
    return boundary_groups(scene, counts), walls.depths(scene.boundaries, counts, r)
