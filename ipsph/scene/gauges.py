"""[[gauge]] tables -> GaugeSpec (validated).

Types and ranges come from params.PARAMS like every other key (`validate._walk`: a NaN position
is refused there); this module adds the rules between keys: the keys each kind takes (and only
those), the quantities of its kind, a level line that goes up, a flow rectangle flat along exactly
one axis with an area, a force gauge naming a [[boundary]] of the scene. Each failure is one line
naming the key. Whether a gauge lies inside the domain needs the walls' geometry and is checked
before allocation by `ipsph.gauges.check_placement` (preflight).
"""

from __future__ import annotations

import re
from typing import Any

from ..config import GaugeSpec
from ..params import GAUGE_KEYS, GAUGE_QUANTITIES
from .text import _fmt, _fmt_vec

_COMMON = ("name", "kind", "quantities", "interval")
_NAME = re.compile(r"[A-Za-z0-9_-]+")  # a gauge's name heads its gauges.csv columns (`p1.pressure [Pa]`)


def gauge_entity(ctx, walk, tree: dict, i: int, entry: dict, walls: tuple[str, ...]) -> GaugeSpec:
    """One [[gauge]] table; `walls` are the names of the scene's [[boundary]] tables."""
    prefix = f"gauge[{i}]"
    vals: dict[str, Any] = {}
    walk(ctx, entry, tree, prefix, vals)
    g = {path.split(".", 1)[1]: v for path, v in vals.items()}
    if "name" in g and not _NAME.fullmatch(g["name"]):
        raise ctx.fail(
            f"{prefix}.name",
            f"{g['name']!r}: a gauge's name is letters, digits, '_' and '-' (it heads the columns of gauges.csv)",
        )
    kind = g.get("kind")
    if kind is None:
        raise ctx.fail(f"{prefix}.kind", f"missing: one of {', '.join(GAUGE_QUANTITIES)}")
    takes = GAUGE_KEYS[kind]
    for key in entry:
        if key not in _COMMON and key not in takes:
            raise ctx.fail(f"{prefix}.{key}", f"does not apply to a {kind} gauge (it takes {', '.join(takes)})")
    for key in takes:
        if key not in g and key != "point":
            raise ctx.fail(f"{prefix}.{key}", f"missing: a {kind} gauge needs {' and '.join(t for t in takes)}")
    allowed = GAUGE_QUANTITIES[kind]
    quantities = g.get("quantities")
    if quantities is None:
        quantities = allowed
    else:
        for k, q in enumerate(quantities):
            if q not in allowed:
                raise ctx.fail(
                    f"{prefix}.quantities[{k}]", f"{q!r} is not a quantity of a {kind} gauge: {', '.join(allowed)}"
                )
        if not quantities:
            raise ctx.fail(f"{prefix}.quantities", f"is empty: give some of {', '.join(allowed)} or leave it out")
    if kind == "level" and not g["top"] > g["position"][1]:
        raise ctx.fail(
            f"{prefix}.top", f"{_fmt(g['top'])} m is not above the line's lower end y = {_fmt(g['position'][1])} m"
        )
    if kind == "flow":
        lo, hi = g["min"], g["max"]
        flat = [a for a in range(3) if lo[a] == hi[a]]
        wide = [a for a in range(3) if lo[a] < hi[a]]
        if len(flat) != 1 or len(wide) != 2:
            raise ctx.fail(
                f"{prefix}.max",
                f"min {_fmt_vec(lo)} and max {_fmt_vec(hi)} make no rectangle: they must agree on exactly one "
                f"axis (the normal) and have min < max on the other two (an empty rectangle has no flux)",
            )
    if kind == "force" and g["wall"] not in walls:
        have = ", ".join(repr(w) for w in walls) or "none: the scene has no [[boundary]]"
        raise ctx.fail(f"{prefix}.wall", f"{g['wall']!r} names no [[boundary]] of the scene (walls: {have})")
    return GaugeSpec(
        name=g.get("name") or f"gauge{i}",
        kind=kind,
        position=g.get("position"),
        top=g.get("top"),
        wall=g.get("wall"),
        box_min=g.get("min"),
        box_max=g.get("max"),
        point=g.get("point"),
        quantities=tuple(quantities),
        interval=g.get("interval"),
    )
