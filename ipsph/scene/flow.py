"""[[emitter]], [[sink]] and [domain] tables -> EmitterSpec, SinkSpec, DomainConfig (validated).

The key types and ranges come from params.PARAMS like every other key (`validate._walk`); this
module adds the rules that tie keys together: a box nozzle has width and height, a circle a
radius; the direction is not zero and the height axis not parallel to it; end_time after
start_time; a nozzle holds at least one particle; both domain corners or none. Each failure is
one line naming the key. Whether a nozzle lies inside a container needs the walls' geometry and
is checked before allocation by `ipsph.flow.check_placement` (preflight).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..config import DomainConfig, EmitterSpec, SinkSpec
from ..params import PARAM_BY_PATH, spacing
from .text import _fmt, _fmt_vec


def _unit(v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    return a / np.linalg.norm(a)


def emitter_entity(ctx, walk, tree: dict, i: int, entry: dict, r: float, end_time: float) -> EmitterSpec:
    prefix = f"emitter[{i}]"
    vals: dict[str, Any] = {}
    walk(ctx, entry, tree, prefix, vals)
    g = lambda key: vals.get(f"emitter.{key}", PARAM_BY_PATH[f"emitter.{key}"].default)  # noqa: E731
    name = vals.get("emitter.name") or f"emitter{i}"
    if "emitter.position" not in vals:
        raise ctx.fail(f"{prefix}.position", "missing: the nozzle's centre [x, y, z]")
    shape = g("shape")
    direction = g("direction")
    if not any(direction):
        raise ctx.fail(f"{prefix}.direction", "must not be the zero vector")
    axis = g("height_axis")
    if axis is not None:
        if not any(axis):
            raise ctx.fail(f"{prefix}.height_axis", "must not be the zero vector")
        if abs(float(np.dot(_unit(axis), _unit(direction)))) > 1.0 - 1e-6:
            raise ctx.fail(
                f"{prefix}.height_axis",
                f"{_fmt_vec(axis)} is parallel to direction {_fmt_vec(direction)}; give an axis across the nozzle",
            )
    d = spacing(r)
    if shape == "box":
        for key in ("width", "height"):
            if g(key) is None:
                raise ctx.fail(f"{prefix}.{key}", "missing: a box nozzle needs width and height [m]")
            if math.floor(g(key) / d + 0.5) < 1:
                raise ctx.fail(
                    f"{prefix}.{key}",
                    f"{_fmt(g(key))} m holds no particle at particle_radius "
                    f"{_fmt(r)} m (round({key} / 2r) = 0); use at least 2r = {_fmt(d)} m",
                )
        if "emitter.radius" in vals:
            raise ctx.fail(f"{prefix}.radius", 'applies to circle nozzles only (shape = "circle")')
    else:
        if g("radius") is None:
            raise ctx.fail(f"{prefix}.radius", "missing: a circle nozzle needs a radius [m]")
        if math.floor(2.0 * g("radius") / d + 0.5) < 1:
            raise ctx.fail(
                f"{prefix}.radius",
                f"{_fmt(g('radius'))} m holds no particle at particle_radius {_fmt(r)} m; use at least r = {_fmt(r)} m",
            )
        for key in ("width", "height"):
            if f"emitter.{key}" in vals:
                raise ctx.fail(f"{prefix}.{key}", "applies to box nozzles only; a circle takes radius")
        if axis is not None:
            raise ctx.fail(f"{prefix}.height_axis", "applies to box nozzles only")
    start, end = g("start_time"), g("end_time")
    if end is not None and end <= start:
        raise ctx.fail(f"{prefix}.end_time", f"{_fmt(end)} s is not after start_time = {_fmt(start)} s")
    if start >= end_time:
        raise ctx.fail(
            f"{prefix}.start_time",
            f"{_fmt(start)} s is not before simulation.end_time = {_fmt(end_time)} s: the emitter would emit nothing",
        )
    return EmitterSpec(
        name=name,
        position=vals["emitter.position"],
        shape=shape,
        direction=direction,
        height_axis=axis,
        width=g("width"),
        height=g("height"),
        radius=g("radius"),
        velocity=g("velocity"),
        start_time=start,
        end_time=end,
    )


def sink_entity(ctx, walk, tree: dict, i: int, entry: dict) -> SinkSpec:
    prefix = f"sink[{i}]"
    vals: dict[str, Any] = {}
    walk(ctx, entry, tree, prefix, vals)
    for end in ("min", "max"):
        if f"sink.{end}" not in vals:
            raise ctx.fail(f"{prefix}.{end}", "missing: an outflow box needs min and max [x, y, z]")
    lo, hi = vals["sink.min"], vals["sink.max"]
    if not all(a < b for a, b in zip(lo, hi)):
        raise ctx.fail(f"{prefix}.min", f"{_fmt_vec(lo)} must be < max {_fmt_vec(hi)} on every axis")
    return SinkSpec(name=vals.get("sink.name") or f"sink{i}", box_min=lo, box_max=hi)


def check_domain(ctx, domain: DomainConfig) -> None:
    if (domain.min is None) != (domain.max is None):
        missing = "domain.max" if domain.max is None else "domain.min"
        raise ctx.fail(missing, "missing: give both corners of the domain box, or neither")
    if domain.min is not None and not all(a < b for a, b in zip(domain.min, domain.max)):
        raise ctx.fail(
            "domain.min", f"{_fmt_vec(domain.min)} must be < domain.max {_fmt_vec(domain.max)} on every axis"
        )


def unique_names(ctx, kind: str, items) -> None:
    seen: dict[str, int] = {}
    for i, item in enumerate(items):
        if item.name in seen:
            raise ctx.fail(
                f"{kind}[{i}].name",
                f"{item.name!r} is already the name of {kind}[{seen[item.name]}]; names must be unique",
            )
        seen[item.name] = i
