"""Scene -> the JSON-serialisable dict in the TOML layout (run.json, checkpoints' fingerprints)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Any

from ..config import Scene, Transform
from ..params import PARAMS
from .validate import ENTITIES, set_path


def scene_to_dict(scene: Scene) -> dict:
    """The Scene as a JSON-serialisable dict in the TOML layout (None values left out).

    `scene_from_dict(scene_to_dict(s)) == s`. Mesh paths are written absolute, so the dict is
    independent of the folder it is read from; boxes are written already transformed.
    """
    d: dict = {"name": scene.name}
    if scene.source is not None:
        d["source"] = str(scene.source)
    for p in PARAMS:
        if p.path.split(".", 1)[0] in ENTITIES or p.path in ("name", "source"):
            continue
        value = _get_attr(scene, p.target)
        if value is None:
            continue
        set_path(d, p.path, _plain(value))
    if scene.fluids:
        d["fluid"] = [_entity_to_dict("fluid", f) for f in scene.fluids]
    if scene.boundaries:
        d["boundary"] = [_entity_to_dict("boundary", b) for b in scene.boundaries]
    if scene.emitters:
        d["emitter"] = [_flow_to_dict("emitter", e) for e in scene.emitters]
    if scene.sinks:
        d["sink"] = [_flow_to_dict("sink", e) for e in scene.sinks]
    if scene.gauges:
        d["gauge"] = [_flow_to_dict("gauge", g) for g in scene.gauges]
    return d


def _flow_to_dict(kind: str, e) -> dict:
    """An [[emitter]], [[sink]] or [[gauge]] table: each key's value by its declared target (None left out)."""
    d: dict = {}
    for p in PARAMS:
        if p.path.startswith(kind + "."):
            value = getattr(e, p.target)
            if value is not None:
                d[p.key] = _plain(value)
    return d


def _get_attr(obj: Any, target: str) -> Any:
    for part in target.split("."):
        obj = getattr(obj, part)
    return obj


def _plain(v: Any) -> Any:
    if isinstance(v, Enum):
        return v.value
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    return v


def _entity_to_dict(kind: str, e) -> dict:
    d: dict = {"name": e.name}
    if kind == "boundary":
        d["role"] = _plain(e.role)
    tf = e.transform
    if e.shape == "box":
        lo, hi = e.box_min, e.box_max
        if tf != Transform():
            if tf.rotate_deg != 0.0:
                raise ValueError(
                    f"{kind} {e.name!r}: a box with a rotation cannot be written "
                    f"in the scene format (boxes are axis-aligned)"
                )
            lo = tuple(s * c + t for s, c, t in zip(tf.scale, lo, tf.translate))
            hi = tuple(s * c + t for s, c, t in zip(tf.scale, hi, tf.translate))
        d["box"] = {"min": _plain(lo), "max": _plain(hi)}
    else:
        d["mesh"] = str(e.mesh)
        d["translate"] = _plain(tf.translate)
        d["scale"] = _plain(tf.scale)
        d["rotate_axis"] = _plain(tf.rotate_axis)
        d["rotate_deg"] = tf.rotate_deg
        if kind == "fluid":
            d["allow_open_mesh"] = e.allow_open_mesh
    if kind == "fluid":
        d["velocity"] = _plain(e.velocity)
    else:
        d.update(_motion_to_dict(e))
    return d


def _motion_to_dict(b) -> dict:
    """A boundary's motion and rigid-body keys (only those that differ from a static wall)."""
    d: dict = {}
    m = b.motion
    if m.type != "static":
        md = {"type": m.type}
        keys = {
            "constant": ("velocity", "angular_velocity", "pivot"),
            "sinusoid": ("axis", "amplitude", "angle_amplitude", "period", "phase_deg", "pivot"),
            "keyframes": ("pivot",),
        }[m.type]
        for k in keys:
            if getattr(m, k) is not None:
                md[k] = _plain(getattr(m, k))
        if m.type == "keyframes":
            md["keyframes"] = [
                {
                    "time": k.time,
                    "translate": _plain(k.translate),
                    "rotate_axis": _plain(k.rotate_axis),
                    "rotate_deg": k.rotate_deg,
                }
                for k in m.keyframes
            ]
        d["motion"] = md
    if b.dynamic:
        if b.density is not None:
            d["density"] = b.density
        else:
            d["mass"] = b.mass
        d["velocity"] = _plain(b.velocity)
        d["angular_velocity"] = _plain(b.angular_velocity)
    return d
