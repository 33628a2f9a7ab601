"""Reading and validating a scene dict (the TOML layout) into `ipsph.config.Scene`.

Rules (house-style 6 and 7): unknown keys are refused with a "did you mean"; a renamed key names
its new path; a wrong type or an out-of-range value is refused naming the full key path
(`fluid[1].velocity`) and the allowed range; nothing is clamped; every error is one line
(`ConfigError`, exit code 2).
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
import typing
from pathlib import Path
from typing import Any

from ..config import (
    ENUMS,
    BoundarySpec,
    DomainConfig,
    FluidSpec,
    OutputConfig,
    RenderConfig,
    Scene,
    SolverConfig,
    SurfaceConfig,
    TimeStepConfig,
    Transform,
)
from ..errors import ConfigError, read_text
from ..params import AUTO_DT_MAX, PARAM_BY_PATH, PARAMS, Param, default, spacing
from ..params.body_keys import MESH_ONLY
from .text import _fmt, _fmt_vec, _show, _tname
from .values import (  # noqa: F401 - ENTITIES, ENTITY_TABLE, renamed_error: read from here too
    _ENTITY_TREES,
    _ROOT,
    _TOP_KEYS,
    ENTITIES,
    ENTITY_TABLE,
    _convert,
    _Ctx,
    _get,
    _tree,
    _unknown,
    _walk,
    renamed_error,
)

_Z3 = (0.0, 0.0, 0.0)


def set_path(d: dict, path: str, value: Any) -> None:
    parts = path.split(".")
    for part in parts[:-1]:
        d = d.setdefault(part, {})
    d[parts[-1]] = value


def _construct(cls, values: dict):
    """cls(**values), building nested dataclass fields (solver.divergence, ...) from sub-dicts."""
    hints = typing.get_type_hints(cls)
    return cls(
        **{
            k: _construct(hints[k], v) if dataclasses.is_dataclass(hints[k]) and isinstance(v, dict) else v
            for k, v in values.items()
        }
    )


def lattice_counts(box_min, box_max, particle_radius: float) -> tuple[int, int, int]:
    """Particles per axis of a box fluid, SPlisHSPlasH's FluidBlocks rule (denseMode 0):
    n = round(extent / 2r) - 1 with C's round (halves away from zero, not Python's banker's
    rounding); the first particle sits at min + 2r."""
    d = spacing(particle_radius)
    return tuple(int(math.floor((hi - lo) / d + 0.5)) - 1 for lo, hi in zip(box_min, box_max))


def _read_toml(path: Path, where: str) -> dict:
    text = read_text(path, where)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = " ".join(str(exc).split())
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        if m:
            msg = msg[: m.start()].strip()
            if msg == "Invalid value":
                msg += ' (text values need double quotes, e.g. method = "ipsph")'
            raise ConfigError(f"{where}:{m.group(1)}:{m.group(2)}: TOML syntax error: {msg}") from exc
        raise ConfigError(f"{where}: TOML syntax error: {msg}") from exc


def _build_scene(data: dict, base_dir: Path, name: str | None, source: Path | None, where: str) -> Scene:
    ctx = _Ctx(where)
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: a scene must be a table of keys, got {_tname(data)}")
    values: dict[str, Any] = {}
    for key, value in data.items():
        if key in ENTITIES:
            continue
        if key not in _ROOT:
            raise _unknown(ctx, key, "", _TOP_KEYS)
        node = _ROOT[key]
        if isinstance(node, Param):
            if key == "name":
                if not isinstance(value, str) or not value.strip():
                    raise ctx.fail(key, f"expected a non-empty string, got {_show(value)}")
                values[key] = value
            else:
                values[key] = _convert(ctx, node, value, key)
        else:
            _walk(ctx, value, node, key, values)

    kw: dict[str, Any] = {}
    for ppath, v in values.items():  # nested by where each value lands in the model
        set_path(kw, PARAM_BY_PATH[ppath].target, v)
    kw["name"] = name or kw.get("name") or "scene"
    if source is not None:
        kw["source"] = Path(source)
    elif kw.get("source") is not None:
        kw["source"] = Path(kw["source"])
    if "method" in kw:
        kw["method"] = ENUMS["simulation.method"](kw["method"])
    if "folder" in kw.get("output", {}):
        kw["output"]["folder"] = Path(kw["output"]["folder"]).expanduser()
    sections = {
        k: _construct(t, kw.pop(k, {}))
        for k, t in (
            ("time_step", TimeStepConfig),
            ("solver", SolverConfig),
            ("output", OutputConfig),
            ("render", RenderConfig),
            ("surface", SurfaceConfig),
            ("domain", DomainConfig),
        )
    }
    r = kw.get("particle_radius", default("simulation.particle_radius"))
    _check_viscosity(ctx, kw)

    fluids_raw = _entity_list(ctx, data, "fluid")
    if not fluids_raw and not _entity_list(ctx, data, "emitter"):
        raise ConfigError(
            f"{where}: no [[fluid]] table: a scene needs at least one fluid body (a box or a mesh) or an [[emitter]]"
        )
    fluids = tuple(_entity(ctx, "fluid", i, e, base_dir, r) for i, e in enumerate(fluids_raw))
    try:
        _check_sections(ctx, sections["time_step"], sections["solver"], sections["render"], r)
    except ConfigError:
        # A radius far too small also breaks the auto dt_max; its size is the error to report
        # (the runner checks the count again against --max-particles before sampling).
        from ..sampling.budget import check_fluid_count

        check_fluid_count(fluids, r, None)
        raise
    boundaries = tuple(
        _entity(ctx, "boundary", i, e, base_dir, r) for i, e in enumerate(_entity_list(ctx, data, "boundary"))
    )
    from . import flow

    for kind, items in (("fluid", fluids), ("boundary", boundaries)):
        flow.unique_names(ctx, kind, items)
    end_time = kw.get("end_time", default("simulation.end_time"))
    emitters = tuple(
        flow.emitter_entity(ctx, _walk, _ENTITY_TREES["emitter"], i, e, r, end_time)
        for i, e in enumerate(_entity_list(ctx, data, "emitter"))
    )
    sinks = tuple(
        flow.sink_entity(ctx, _walk, _ENTITY_TREES["sink"], i, e) for i, e in enumerate(_entity_list(ctx, data, "sink"))
    )
    flow.unique_names(ctx, "emitter", emitters)
    flow.unique_names(ctx, "sink", sinks)
    flow.check_domain(ctx, sections["domain"])
    from .gauges import gauge_entity

    walls = tuple(b.name for b in boundaries)
    gauges = tuple(
        gauge_entity(ctx, _walk, _ENTITY_TREES["gauge"], i, e, walls)
        for i, e in enumerate(_entity_list(ctx, data, "gauge"))
    )
    flow.unique_names(ctx, "gauge", gauges)
    return Scene(fluids=fluids, boundaries=boundaries, emitters=emitters, sinks=sinks, gauges=gauges, **sections, **kw)


def _check_viscosity(ctx: _Ctx, kw: dict) -> None:
    """A kinematic viscosity needs a model that uses it (xsph would silently ignore it)."""
    nu = kw.get("kinematic_viscosity_m2s", default("simulation.kinematic_viscosity_m2s"))
    model = kw.get("viscosity_model", default("simulation.viscosity_model"))
    if nu > 0.0 and model == "xsph":
        raise ctx.fail(
            "simulation.kinematic_viscosity_m2s",
            f'{_fmt(nu)} m^2/s has no effect with viscosity_model = "xsph": '
            'set simulation.viscosity_model = "implicit" (or "standard")',
        )


def _check_sections(ctx: _Ctx, ts: TimeStepConfig, sv: SolverConfig, rd: RenderConfig, r: float) -> None:
    sv_root = Scene(name="", solver=sv)  # min <= max pairs, by their model targets
    dt_max = ts.resolved_dt_max(r)
    if ts.dt_min > dt_max:
        src = (
            "time_step.dt_max"
            if ts.dt_max is not None
            else f"time_step.dt_max (auto: {AUTO_DT_MAX} = {_fmt(dt_max)} s)"
        )
        raise ctx.fail("time_step.dt_min", f"{_fmt(ts.dt_min)} s is larger than {src}; lower dt_min or raise dt_max")
    if ts.dt_initial is not None and not ts.dt_min <= ts.dt_initial <= dt_max:
        raise ctx.fail(
            "time_step.dt_initial",
            f"{_fmt(ts.dt_initial)} s is outside [dt_min, dt_max] = [{_fmt(ts.dt_min)}, {_fmt(dt_max)}] s",
        )
    for p in PARAMS:
        if p.at_most:
            lo, hi = _get(sv_root, p.target), _get(sv_root, PARAM_BY_PATH[p.at_most].target)
            if lo > hi:
                raise ctx.fail(p.path, f"{lo} is larger than {p.at_most.rsplit('.', 1)[1]} = {hi}")
    if rd.view_up is not None and not any(rd.view_up):
        raise ctx.fail("render.view_up", "must not be the zero vector")
    if rd.camera_position is not None and rd.focal_point is not None and rd.camera_position == rd.focal_point:
        raise ctx.fail("render.camera_position", "equals render.focal_point; the camera needs a direction to look in")


def _entity_list(ctx: _Ctx, data: dict, kind: str) -> list:
    raw = data.get(kind, [])
    if isinstance(raw, dict):
        raise ctx.fail(kind, f"expected an array of tables: write [[{kind}]] (double brackets), not [{kind}]")
    if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
        raise ctx.fail(kind, f"expected an array of tables ([[{kind}]]), got {_show(raw)}")
    return raw


def _entity(ctx: _Ctx, kind: str, i: int, entry: dict, base_dir: Path, r: float):
    """A [[fluid]] or [[boundary]] table as its spec: every given value lands where its key's target
    says (params.body_keys), the rest keep the spec's declared defaults; a box's placement is folded
    into its corners."""
    prefix = f"{kind}[{i}]"
    vals: dict[str, Any] = {}
    _walk(ctx, entry, _ENTITY_TREES[kind], prefix, vals)
    kw: dict[str, Any] = {}
    for path, v in vals.items():
        set_path(kw, PARAM_BY_PATH[path].target, ENUMS[path](v) if path in ENUMS else v)
    kw["name"] = kw.get("name") or f"{kind}{i}"
    has_box, has_mesh = "box" in entry, "mesh" in entry
    if has_box == has_mesh:
        raise ctx.fail(
            prefix,
            "give exactly one shape: box = {min = [x, y, z], max = "
            '[x, y, z]} or mesh = "file.obj"' + (", not both" if has_box else ""),
        )
    tf = Transform(**kw.pop("transform", {}))
    if not any(tf.rotate_axis):
        raise ctx.fail(f"{prefix}.rotate_axis", "must not be the zero vector")
    shape = "box" if has_box else "mesh"
    mesh = _resolve_mesh(ctx, f"{prefix}.mesh", vals[f"{kind}.mesh"], base_dir) if has_mesh else None
    if kind == "boundary":
        from .bodies import boundary_motion  # motion, rigid bodies: the rules between their keys

        kw["motion"] = boundary_motion(ctx, prefix, vals, shape, mesh)
    cls = FluidSpec if kind == "fluid" else BoundarySpec
    if has_mesh:
        return cls(**{**kw, "shape": shape, "mesh": mesh, "transform": tf})
    for end in ("min", "max"):
        if f"{kind}.box.{end}" not in vals:
            raise ctx.fail(f"{prefix}.box", f"missing {end} = [x, y, z]")
    if tf.rotate_deg != 0.0:
        raise ctx.fail(
            f"{prefix}.rotate_deg",
            f"{_fmt(tf.rotate_deg)}: boxes are axis-aligned and cannot be rotated; use a mesh (e.g. a box .obj) to rotate",
        )
    for path in MESH_ONLY:
        if path in vals:
            raise ctx.fail(f"{prefix}.{path.split('.', 1)[1]}", f"applies to mesh {kind}s only")
    lo_given, hi_given = kw.pop("box_min"), kw.pop("box_max")
    t, s = tf.translate, tf.scale
    lo = tuple(si * c + ti for si, c, ti in zip(s, lo_given, t))
    hi = tuple(si * c + ti for si, c, ti in zip(s, hi_given, t))
    note = (
        ""
        if (t, s) == (_Z3, (1.0, 1.0, 1.0))
        else f" (after scale and translate: min {_fmt_vec(lo)}, max {_fmt_vec(hi)})"
    )
    for a in range(3):
        if not lo[a] < hi[a]:
            raise ctx.fail(
                f"{prefix}.box", f"min {_fmt_vec(lo_given)} must be < max {_fmt_vec(hi_given)} on every axis{note}"
            )
    if kind == "fluid":
        n = lattice_counts(lo, hi, r)
        if min(n) < 1:
            a = n.index(min(n))
            raise ctx.fail(
                f"{prefix}.box",
                f"extent {_fmt(hi[a] - lo[a])} m along "
                f"{'xyz'[a]} holds no particle at particle_radius {_fmt(r)} m "
                f"(round(extent / 2r) - 1 = {n[a]}); need an extent of at "
                f"least 3r = {_fmt(3 * r)} m",
            )
    return cls(**{**kw, "shape": shape, "box_min": lo, "box_max": hi})


def _resolve_mesh(ctx: _Ctx, key: str, given: str, base_dir: Path) -> Path:
    p = Path(given).expanduser()
    resolved = (p if p.is_absolute() else base_dir / p).resolve()
    if not resolved.is_file():
        what = "is a folder, not a mesh file" if resolved.is_dir() else "mesh file not found"
        raise ctx.fail(
            key,
            f"{what}: {given!r} (resolved: {resolved}; relative paths are "
            f"relative to the scene file's folder {base_dir})",
        )
    return resolved


def surface_values(data: dict, where: str) -> SurfaceConfig:
    """A [surface] table alone, validated by PARAMS (no meshes resolved)."""
    values: dict[str, Any] = {}
    _walk(_Ctx(where), data, _ROOT["surface"], "surface", values)
    return SurfaceConfig(**{PARAM_BY_PATH[k].target.split(".", 1)[1]: v for k, v in values.items()})
