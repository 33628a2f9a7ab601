"""The [[fluid]] and [[boundary]] keys (placement, motion, rigid bodies).

Each key's value lands on the FluidSpec / BoundarySpec attribute its target names; reading
(ipsph.scene.validate) and writing (ipsph.scene.serialise) go through every key of the table, so
a new key is one line here. What only some bodies take is declared below the table.
"""

from __future__ import annotations

from .facts import BOUNDARY_ROLES, MOTION_TYPES
from .schema import _P, _Z3, Param, _transform

KEYS: tuple[Param, ...] = (
    # -- [[fluid]] ------------------------------------------------------------------------------
    _P("fluid.name", "str", None, "", "Name of the body. Default: fluid<i> (i counts from 0).", "name"),
    _P(
        "fluid.box.min",
        "vec3",
        None,
        "m",
        "Box fluid: minimum corner. Lattice as "
        "SPlisHSPlasH's FluidBlocks: round(extent / 2r) - 1 particles per axis, the first at "
        "min + 2r.",
        "box_min",
        required=True,
    ),
    _P("fluid.box.max", "vec3", None, "m", "Box fluid: maximum corner.", "box_max", required=True),
    _P(
        "fluid.mesh",
        "path",
        None,
        "",
        "Mesh fluid: closed surface mesh file, relative to the scene file. Give box or mesh, not both.",
        "mesh",
    ),
    *_transform("fluid"),
    _P(
        "fluid.velocity",
        "vec3",
        _Z3,
        "m/s",
        "Initial velocity of every particle of the body.",
        "velocity",
        lo=-1e3,
        hi=1e3,
    ),
    _P(
        "fluid.allow_open_mesh",
        "bool",
        False,
        "",
        "Mesh only: sample a mesh that is not watertight (at your own risk) instead of refusing it.",
        "allow_open_mesh",
    ),
    # -- [[boundary]] ---------------------------------------------------------------------------
    _P("boundary.name", "str", None, "", "Name of the wall. Default: boundary<i>.", "name"),
    _P(
        "boundary.role",
        "choice",
        "container",
        "",
        "container: the fluid lives inside the closed surface; obstacle: the fluid flows around it.",
        "role",
        choices=BOUNDARY_ROLES,
    ),
    _P("boundary.box.min", "vec3", None, "m", "Box wall: minimum corner.", "box_min", required=True),
    _P("boundary.box.max", "vec3", None, "m", "Box wall: maximum corner.", "box_max", required=True),
    _P(
        "boundary.mesh",
        "path",
        None,
        "",
        "Mesh wall: closed surface mesh file, relative to the scene file. Give box or mesh, not both.",
        "mesh",
    ),
    *_transform("boundary"),
    _P(
        "boundary.allow_open_mesh",
        "bool",
        False,
        "",
        "Mesh obstacle only: use a mesh that is not closed as a thin shell (one layer of wall "
        "particles on its surface, its inside where the winding number exceeds 1/2) instead of "
        "refusing it. An obstacle's inside decides where fluid may start, so an open one is refused "
        "by default; a container's mesh may be open anyway, a dynamic body's never.",
        "allow_open_mesh",
    ),
    # -- [[boundary]] motion and rigid bodies (ipsph/boundary/motion.py, ipsph/boundary/rigid.py; method.md section 9)
    _P(
        "boundary.motion.type",
        "choice",
        "static",
        "",
        "Prescribed motion of the wall (a kinematic "
        "wall: it pushes the fluid, the fluid does not push it): static, constant (velocity and "
        "angular_velocity), sinusoid (a paddle or piston: amplitude along axis and/or angle_amplitude "
        "about axis, with period and phase_deg) or keyframes. The scene places the wall at t = 0; "
        "every motion is an offset from there.",
        "motion.type",
        choices=MOTION_TYPES,
    ),
    _P(
        "boundary.motion.velocity", "vec3", _Z3, "m/s", "constant: linear velocity.", "motion.velocity", lo=-1e3, hi=1e3
    ),
    _P(
        "boundary.motion.angular_velocity",
        "vec3",
        _Z3,
        "deg/s",
        "constant: angular velocity about pivot (the vector's direction is the axis, right-handed).",
        "motion.angular_velocity",
        lo=-1e5,
        hi=1e5,
    ),
    _P(
        "boundary.motion.pivot",
        "vec3",
        None,
        "m",
        "Centre of rotation at t = 0 (it moves with the wall). auto: the centre of the wall's bounding box.",
        "motion.pivot",
        optional=True,
    ),
    _P(
        "boundary.motion.axis",
        "vec3",
        (1.0, 0.0, 0.0),
        "",
        "sinusoid: direction of the displacement and axis of the rotation (normalised).",
        "motion.axis",
    ),
    _P(
        "boundary.motion.amplitude",
        "float",
        0.0,
        "m",
        "sinusoid: displacement amplitude A: the "
        "wall moves by A (sin(2 pi t / period + phase) - sin(phase)) along axis.",
        "motion.amplitude",
        lo=0.0,
        hi=1e3,
    ),
    _P(
        "boundary.motion.angle_amplitude",
        "float",
        0.0,
        "deg",
        "sinusoid: rotation amplitude about axis through pivot (a flap paddle), with the same time dependence.",
        "motion.angle_amplitude",
        lo=0.0,
        hi=180.0,
    ),
    _P(
        "boundary.motion.period",
        "float",
        None,
        "s",
        "sinusoid: period (required, > 0).",
        "motion.period",
        lo=0.0,
        hi=1e6,
        lo_open=True,
        optional=True,
    ),
    _P(
        "boundary.motion.phase_deg",
        "float",
        0.0,
        "deg",
        "sinusoid: phase; -90 starts at rest at one end of the stroke (no jerk at t = 0), 0 starts at full speed.",
        "motion.phase_deg",
        lo=-360.0,
        hi=360.0,
    ),
    _P(
        "boundary.motion.keyframes",
        "keyframes",
        (),
        "",
        "keyframes: an array of tables "
        "{time, translate = [x, y, z], rotate_axis = [x, y, z], rotate_deg} with strictly "
        "increasing times: the wall's offset from its placement, interpolated by Catmull-Rom "
        "cubic Hermite splines (translation) and slerp (rotation about pivot); held before the "
        "first and after the last keyframe.",
        "motion.keyframes",
    ),
    _P(
        "boundary.density",
        "float",
        None,
        "kg/m^3",
        "Makes the wall a dynamic rigid body "
        "(role obstacle, a closed surface) of this density: the fluid pushes it and it pushes "
        "back, under gravity, with contacts (method.md section 9). auto: not a body.",
        "density",
        lo=0.0,
        hi=1e6,
        lo_open=True,
        optional=True,
    ),
    _P(
        "boundary.mass",
        "float",
        None,
        "kg",
        "A dynamic body's mass instead of density (give one of them). auto: from density.",
        "mass",
        lo=0.0,
        hi=1e9,
        lo_open=True,
        optional=True,
    ),
    _P("boundary.velocity", "vec3", _Z3, "m/s", "A dynamic body's initial velocity.", "velocity", lo=-1e3, hi=1e3),
    _P(
        "boundary.angular_velocity",
        "vec3",
        _Z3,
        "deg/s",
        "A dynamic body's initial angular velocity.",
        "angular_velocity",
        lo=-1e5,
        hi=1e5,
    ),
)

# Keys only some bodies take: a scene that gives them elsewhere is refused, and run.json leaves them
# out there. A box's translate and scale are folded into its corners (boxes do not rotate).
MESH_ONLY: tuple[str, ...] = ("fluid.allow_open_mesh", "boundary.allow_open_mesh")
DYNAMIC_ONLY: tuple[str, ...] = ("boundary.velocity", "boundary.angular_velocity")  # a density or mass given
