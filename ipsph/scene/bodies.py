"""Validation of a [[boundary]]'s motion and rigid-body keys (config.MotionSpec, BoundarySpec's
density / mass): the rules PARAMS' ranges cannot say. Every error is one line naming the key
(exit 2), raised while the scene is read, before anything is sampled or allocated. `applies`:
which [[fluid]] / [[boundary]] keys belong in which body's table."""

from __future__ import annotations

from typing import Any

from ..config import Keyframe, MotionSpec, Role
from ..params import MOTION_KEYS, PARAM_BY_PATH
from ..params.body_keys import DYNAMIC_ONLY, MESH_ONLY
from .text import _fmt, _show

_KEYFRAME_KEYS = ("time", "translate", "rotate_axis", "rotate_deg")


def convert_keyframes(ctx, value: Any, shown: str) -> tuple[Keyframe, ...]:
    """boundary.motion.keyframes: an array of {time, translate, rotate_axis, rotate_deg} tables,
    times strictly increasing."""
    if not isinstance(value, (list, tuple)) or not all(isinstance(k, dict) for k in value):
        raise ctx.fail(
            shown,
            f"expected an array of tables {{time = t, translate = [x, y, z], "
            f"rotate_axis = [x, y, z], rotate_deg = a}}, got {_show(value)}",
        )
    out = []
    for i, k in enumerate(value):
        where = f"{shown}[{i}]"
        for key in k:
            if key not in _KEYFRAME_KEYS:
                raise ctx.fail(f"{where}.{key}", f"unknown key (allowed: {', '.join(_KEYFRAME_KEYS)})")
        if "time" not in k:
            raise ctx.fail(f"{where}", "missing time = t (s)")
        t = _num(ctx, k["time"], f"{where}.time")
        if t < 0.0:
            raise ctx.fail(f"{where}.time", f"{_fmt(t)} s is negative")
        if out and not t > out[-1].time:
            raise ctx.fail(
                f"{where}.time",
                f"{_fmt(t)} s is not after keyframe {i - 1}'s "
                f"{_fmt(out[-1].time)} s: keyframes must be in strictly increasing time order",
            )
        tr = _vec(ctx, k.get("translate", (0.0, 0.0, 0.0)), f"{where}.translate")
        ax = _vec(ctx, k.get("rotate_axis", (0.0, 1.0, 0.0)), f"{where}.rotate_axis")
        deg = _num(ctx, k.get("rotate_deg", 0.0), f"{where}.rotate_deg")
        if not any(ax):
            raise ctx.fail(f"{where}.rotate_axis", "must not be the zero vector")
        if abs(deg) > 360.0:
            raise ctx.fail(f"{where}.rotate_deg", f"{_fmt(deg)} deg is out of range: allowed [-360, 360]")
        out.append(Keyframe(t, tr, ax, deg))
    return tuple(out)


def _num(ctx, v, shown) -> float:
    import math

    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise ctx.fail(shown, f"expected a finite number, got {_show(v)}")
    return float(v)


def _vec(ctx, v, shown) -> tuple[float, float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ctx.fail(shown, f"expected 3 numbers [x, y, z], got {_show(v)}")
    return tuple(_num(ctx, c, f"{shown}[{i}]") for i, c in enumerate(v))


def boundary_motion(ctx, prefix: str, vals: dict, shape: str, mesh):
    """A wall's MotionSpec from the validated values `vals` (PARAMS paths -> values), after the rules
    between its motion and rigid-body keys (density, mass and the initial velocities land on the
    BoundarySpec by their targets, like every other key)."""
    g = lambda key: vals.get(f"boundary.{key}", PARAM_BY_PATH[f"boundary.{key}"].default)  # noqa
    given = {k.split(".", 2)[2] for k in vals if k.startswith("boundary.motion.")}
    mt = g("motion.type")
    motion = MotionSpec(**{k.split(".", 2)[2]: v for k, v in vals.items() if k.startswith("boundary.motion.")})
    mp = f"{prefix}.motion"
    if given and mt == "static" and given != {"type"}:
        raise ctx.fail(
            f"{mp}.type",
            f"is static (the default) but {', '.join(sorted(given - {'type'}))} "
            f'given: set type = "constant", "sinusoid" or "keyframes"',
        )
    allowed = {"type", *MOTION_KEYS[mt]}
    for key in sorted(given - allowed):
        raise ctx.fail(
            f"{mp}.{key}", f"does not apply to motion type {mt!r} (it takes: {', '.join(sorted(allowed - {'type'}))})"
        )
    if mt == "sinusoid":
        if motion.period is None:
            raise ctx.fail(f"{mp}.period", "a sinusoid needs a period > 0 (s)")
        if not any(motion.axis):
            raise ctx.fail(f"{mp}.axis", "must not be the zero vector")
        if motion.amplitude == 0.0 and motion.angle_amplitude == 0.0:
            raise ctx.fail(f"{mp}.amplitude", "a sinusoid needs amplitude > 0 (m) or angle_amplitude > 0 (deg)")
    if mt == "keyframes" and len(motion.keyframes) < 2:
        raise ctx.fail(f"{mp}.keyframes", f"needs at least 2 keyframes, got {len(motion.keyframes)}")
    density, mass = g("density"), g("mass")
    dynamic = density is not None or mass is not None
    role = getattr(g("role"), "value", g("role"))  # "container" or "obstacle"
    if g("allow_open_mesh") and (shape != "mesh" or role != Role.OBSTACLE.value or dynamic):
        why = (
            "a dynamic body needs a closed surface" if dynamic and shape == "mesh" else "applies to mesh obstacles only"
        )
        if role == Role.CONTAINER.value and shape == "mesh":
            why += " (a container's mesh may be open already)"
        raise ctx.fail(f"{prefix}.allow_open_mesh", why)
    for path in DYNAMIC_ONLY:
        if path in vals and not dynamic:
            raise ctx.fail(
                f"{prefix}.{path.split('.', 1)[1]}", "is a dynamic body's initial velocity: give density or mass too"
            )
    if dynamic:
        if density is not None and mass is not None:
            raise ctx.fail(f"{prefix}.mass", "give density or mass, not both")
        if mt != "static":
            raise ctx.fail(
                f"{mp}.type",
                f"{mt!r}: a dynamic body (density or mass given) moves as the "
                f"forces say; a prescribed motion is for kinematic walls",
            )
        if g("role") != Role.OBSTACLE:
            raise ctx.fail(
                f"{prefix}.role",
                'a dynamic body must be an obstacle (the fluid flows around it): set role = "obstacle"',
            )
        if shape == "mesh":
            from ..geometry.meshes import check_closed, fmt_point, load_mesh, unpaired_edge_at

            surface = load_mesh(mesh)
            open_edges = check_closed(surface)
            if open_edges:
                raise ctx.fail(
                    f"{prefix}.mesh",
                    f"a dynamic body needs a closed surface (its mass and inertia are its volume's): "
                    f"{open_edges} open or unpaired edges in {mesh}, one at {fmt_point(unpaired_edge_at(surface))} "
                    f"(the file's coordinates); repair the mesh",
                )
    return motion


def applies(path: str, spec) -> bool:
    """Whether the [[fluid]] / [[boundary]] key `path` (a PARAMS path) belongs in `spec`'s table: what
    a scene may give for it, and what run.json writes (ipsph.scene.serialise)."""
    target = PARAM_BY_PATH[path].target
    if target.startswith("transform.") or path in MESH_ONLY:
        return spec.shape == "mesh"  # a box's placement is folded into its corners
    if path in DYNAMIC_ONLY:
        return spec.dynamic
    if target.startswith("motion."):
        mt = spec.motion.type
        return mt != "static" and target.split(".", 1)[1] in ("type", *MOTION_KEYS[mt])
    return True
