"""The [[gauge]] keys: time series at chosen places (ipsph.gauges, docs/gauges.md)."""

from __future__ import annotations

from .schema import _P, Param

# gauge.kind -> the quantities it can record (gauge.quantities), the first ones its default
GAUGE_QUANTITIES = {
    "point": ("pressure", "velocity", "density"),
    "level": ("level", "level_max"),
    "force": ("force", "torque"),
    "flow": ("flow",),
}
GAUGE_KINDS = tuple(GAUGE_QUANTITIES)
# the keys each kind takes besides name, kind, quantities and interval (scene/gauges.py refuses the others)
GAUGE_KEYS = {
    "point": ("position",),
    "level": ("position", "top"),
    "force": ("wall", "point"),
    "flow": ("min", "max"),
}

KEYS: tuple[Param, ...] = (
    _P(
        "gauge.name",
        "str",
        None,
        "",
        "Name of the gauge (letters, digits, _ and -), the prefix of its gauges.csv columns. Default: gauge<i>.",
        "name",
    ),
    _P(
        "gauge.kind",
        "choice",
        None,
        "",
        "point: pressure, velocity and density at a point (SPH interpolation, Shepard-normalised); "
        "level: the free-surface height along a vertical line and the highest so far; force: the "
        "fluid's force and torque on a [[boundary]]; flow: the volume flux through an axis-aligned rectangle.",
        "kind",
        choices=GAUGE_KINDS,
        required=True,
    ),
    _P(
        "gauge.position",
        "vec3",
        None,
        "m",
        "point: where it measures. level: the lower end of its vertical line (y is up).",
        "position",
    ),
    _P("gauge.top", "float", None, "m", "level: the height y of the line's upper end (above position's y).", "top"),
    _P("gauge.wall", "str", None, "", "force: the name of the [[boundary]] (a wall or a rigid body).", "wall"),
    _P(
        "gauge.point",
        "vec3",
        None,
        "m",
        "force: the point the torque is taken about (fixed in space). auto: the centre of the wall's "
        "particles' bounding box at t = 0.",
        "point",
        optional=True,
    ),
    _P(
        "gauge.min",
        "vec3",
        None,
        "m",
        "flow: one corner of the rectangle. min and max agree on exactly one axis, the rectangle's "
        "normal; the flux counts positive along +axis.",
        "box_min",
    ),
    _P("gauge.max", "vec3", None, "m", "flow: the opposite corner of the rectangle.", "box_max"),
    _P(
        "gauge.quantities",
        "fields",
        None,
        "",
        "What the gauge records; auto: all its kind records. point: pressure, velocity, density; "
        "level: level, level_max; force: force, torque; flow: flow.",
        "quantities",
        choices=tuple(dict.fromkeys(q for qs in GAUGE_QUANTITIES.values() for q in qs)),
        optional=True,
    ),
    _P(
        "gauge.interval",
        "float",
        None,
        "s",
        "Simulated seconds between samples, independent of output.fps: a sample at the end of "
        "the first step at or after each multiple of interval. auto: after every step.",
        "interval",
        lo=0.0,
        lo_open=True,
        hi=1e6,
        optional=True,
    ),
)
