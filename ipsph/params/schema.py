"""`Param`, one scene parameter, and the helpers that declare the key tables (`_P`, `_limits`,
`_transform`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Param:
    """One scene parameter.

    path: dotted key path in the file (`fluid.velocity` is `velocity` in each [[fluid]] table).
    kind: float | int | bool | choice | path | vec3 | range2 | fields | keyframes.
    target: where the value lands in the model: `time_step.dt_max` (Scene.time_step.dt_max),
      `particle_radius` (Scene.particle_radius); for fluid/boundary keys, the FluidSpec /
      BoundarySpec attribute (`transform.translate`). Empty: no direct model field.
    lo/hi (+ lo_open/hi_open): allowed range, per component for vectors.
    optional: the value may be None (key left out, or written "auto").
    at_most: the path of a key whose value this one must not exceed (min <= max pairs).
    """

    path: str
    kind: str
    default: Any
    unit: str
    doc: str
    target: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] | None = None
    optional: bool = False
    required: bool = False
    at_most: str | None = None  # another key (same table) this value must not exceed

    @property
    def key(self) -> str:
        return self.path.rsplit(".", 1)[-1]


_Z3 = (0.0, 0.0, 0.0)


def _P(path, kind, default, unit, doc, target=None, **kw) -> Param:
    """One parameter; `target` (where the value lands in the model) defaults to the key path."""
    return Param(path, kind, default, unit, doc, path if target is None else target, **kw)


def _limits(
    table: str, what: str, lo: int, hi: int, solve: str, *, stem: str = "", least: int = 0
) -> tuple[Param, ...]:
    """A loop's minimum and maximum counts (`<stem>min_<what>` <= `<stem>max_<what>`)."""
    low, high = f"{table}.{stem}min_{what}", f"{table}.{stem}max_{what}"
    return (
        _P(low, "int", lo, "", f"{solve}: minimum {what}.", low, lo=least, hi=100_000, at_most=high),
        _P(high, "int", hi, "", f"{solve}: maximum {what}.", high, lo=1, hi=100_000),
    )


def _transform(kind: str) -> tuple[Param, ...]:
    """The placement keys every [[fluid]] and [[boundary]] table has (model.Transform)."""
    return (
        _P(
            f"{kind}.translate",
            "vec3",
            _Z3,
            "m",
            "Translation t in x' = R(S x) + t. For boxes, applied to min and max.",
            "transform.translate",
        ),
        _P(
            f"{kind}.scale",
            "vec3",
            (1.0, 1.0, 1.0),
            "",
            "Scale S (per axis, > 0), applied first. For boxes, applied to min and max.",
            "transform.scale",
            lo=0.0,
            lo_open=True,
        ),
        _P(f"{kind}.rotate_axis", "vec3", (0.0, 1.0, 0.0), "", "Rotation axis (mesh only).", "transform.rotate_axis"),
        _P(
            f"{kind}.rotate_deg",
            "float",
            0.0,
            "deg",
            "Rotation angle about rotate_axis (mesh only; boxes are axis-aligned).",
            "transform.rotate_deg",
            lo=-360.0,
            hi=360.0,
        ),
    )
