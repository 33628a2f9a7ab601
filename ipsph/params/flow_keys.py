"""The [[emitter]], [[sink]] and [domain] keys: fluid entering and leaving (ipsph.flow)."""

from __future__ import annotations

from .schema import _P, Param

EMITTER_SHAPES = ("box", "circle")  # emitter.shape: a rectangular or a circular nozzle


KEYS: tuple[Param, ...] = (
    _P(
        "domain.min",
        "vec3",
        None,
        "m",
        "Domain box, minimum corner: fluid that leaves the box "
        "is removed (an outflow on every side). auto: no domain box; fluid leaving the containers' "
        "bounds is then a numerical failure. SPlisHSPlasH's emitterBoxMin with emitterReuseParticles.",
        optional=True,
    ),
    _P("domain.max", "vec3", None, "m", "Domain box, maximum corner.", optional=True),
    _P("emitter.name", "str", None, "", "Name of the emitter. Default: emitter<i>.", "name"),
    _P(
        "emitter.shape",
        "choice",
        "box",
        "",
        "Nozzle shape: box (width x height) or circle (radius), as SPlisHSPlasH's Emitters type 0 / 1.",
        "shape",
        choices=EMITTER_SHAPES,
    ),
    _P(
        "emitter.position",
        "vec3",
        None,
        "m",
        "Centre of the nozzle's outlet; the first layer of each emission is placed here and moves off along direction.",
        "position",
        required=True,
    ),
    _P(
        "emitter.direction",
        "vec3",
        (1.0, 0.0, 0.0),
        "",
        "Direction the fluid leaves in (normalised; SPlisHSPlasH: the first column of the emitter's rotation).",
        "direction",
    ),
    _P(
        "emitter.height_axis",
        "vec3",
        None,
        "",
        "Box nozzle: the direction of its height (made "
        "perpendicular to direction). auto: +y, or +z when the direction is vertical.",
        "height_axis",
        optional=True,
    ),
    _P(
        "emitter.width",
        "float",
        None,
        "m",
        "Box nozzle: width; round(width / 2r) particles across (at least 1).",
        "width",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.height",
        "float",
        None,
        "m",
        "Box nozzle: height; round(height / 2r) particles.",
        "height",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.radius",
        "float",
        None,
        "m",
        "Circle nozzle: radius; the lattice points of spacing 2r within it.",
        "radius",
        lo=0.0,
        lo_open=True,
        hi=1e3,
        optional=True,
    ),
    _P(
        "emitter.velocity",
        "float",
        1.0,
        "m/s",
        "Speed of the emitted fluid along direction. A "
        "layer leaves every 2r / velocity seconds, so the mass rate is rho0 * A * velocity "
        "(A: the particles of a layer times (2r)^2).",
        "velocity",
        lo=0.0,
        lo_open=True,
        hi=1e3,
    ),
    _P("emitter.start_time", "float", 0.0, "s", "First emission.", "start_time", lo=0.0, hi=1e6),
    _P(
        "emitter.end_time",
        "float",
        None,
        "s",
        "Last emission (no layer after it). auto: simulation.end_time.",
        "end_time",
        lo=0.0,
        lo_open=True,
        hi=1e6,
        optional=True,
    ),
    _P("sink.name", "str", None, "", "Name of the sink. Default: sink<i>.", "name"),
    _P(
        "sink.min",
        "vec3",
        None,
        "m",
        "Outflow box, minimum corner: fluid inside is removed after every step.",
        "box_min",
        required=True,
    ),
    _P("sink.max", "vec3", None, "m", "Outflow box, maximum corner.", "box_max", required=True),
)
