"""Scene -> the JSON-serialisable dict in the TOML layout (run.json, checkpoints' fingerprints)."""

from __future__ import annotations

import dataclasses
from enum import Enum
from pathlib import Path
from typing import Any

from ..config import Scene, Transform
from ..params import PARAMS
from .bodies import applies
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
    if dataclasses.is_dataclass(v):  # a keyframe
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, Enum):
        return v.value
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    return v


def _entity_to_dict(kind: str, e) -> dict:
    """A [[fluid]] or [[boundary]] table: every declared key of `kind` that applies to `e`
    (`bodies.applies`), by its target, None left out; a box with its placement folded into its corners."""
    d: dict = {}
    for p in PARAMS:
        if p.path.startswith(kind + ".") and applies(p.path, e):
            value = _get_attr(e, p.target)
            if value is not None:
                set_path(d, p.path.split(".", 1)[1], _plain(value))
    tf = e.transform
    if e.shape == "box" and tf != Transform():
        if tf.rotate_deg != 0.0:
            raise ValueError(
                f"{kind} {e.name!r}: a box with a rotation cannot be written in the scene format (boxes are axis-aligned)"
            )
        lo = [s * c + t for s, c, t in zip(tf.scale, e.box_min, tf.translate)]
        hi = [s * c + t for s, c, t in zip(tf.scale, e.box_max, tf.translate)]
        d["box"] = {"min": lo, "max": hi}
    return d
