"""Sweep files -> members: a base scene, fixed overrides, a grid and zipped lists.

    scene = "scene.toml"        # relative to the sweep file; a SPlisHSPlasH .json works too
    name = "radius-study"       # optional: the sweep's name (default: the sweep file's stem)
    [set]                       # fixed for every member
    "simulation.end_time" = 1.0
    [grid]                      # every combination of these
    "simulation.particle_radius" = [0.02, 0.015, 0.01]
    "simulation.method" = ["ipsph", "pf", "dfsph"]
    [zip]                       # equal-length lists varied together (one member per position)
    "solver.pf.stiffness" = [20000.0, 50000.0]
    "simulation.viscosity" = [0.01, 0.02]

Keys are exactly the `--set` keys of `ipsph run` (`fluid.0.velocity` addresses the first
[[fluid]]); quoted dotted keys and plain TOML tables (`[set.simulation] end_time = 1.0`) are the
same thing. Members are the product of the grid with the zip positions, in file order (the last
grid key varies fastest). A member's folder name is built from its varied values
(`particle_radius-0.02_method-ipsph`), so it is readable and stable across reruns.

`load_sweep` checks the file itself; `validate` resolves every member's scene (exactly what
`ipsph run` would do before allocating anything) and raises a one-line `ConfigError` naming the
member and the key, so a bad sweep exits 2 before any cluster starts.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError

TOP_KEYS = ("scene", "name", "set", "grid", "zip")
SECTIONS = ("set", "grid", "zip")


@dataclass(frozen=True)
class Member:
    """One scene of the sweep: its folder name and the overrides that make it (applied in order)."""

    index: int
    name: str
    overrides: tuple[tuple[str, Any], ...]  # [set] first, then the varied keys
    varied: tuple[tuple[str, Any], ...]  # the grid and zip values only (the name's source)

    def set_args(self) -> list[str]:
        """The overrides as `ipsph run --set KEY=VALUE` strings."""
        return [f"{k}={toml_value(v)}" for k, v in self.overrides]

    def params(self) -> dict:
        return {k: v for k, v in self.overrides}


@dataclass(frozen=True)
class Sweep:
    path: Path  # the sweep file (absolute)
    name: str
    scene: Path  # the base scene (absolute)
    fixed: tuple[tuple[str, Any], ...]
    grid: tuple[tuple[str, tuple], ...]
    zipped: tuple[tuple[str, tuple], ...]
    members: tuple[Member, ...] = field(default=())

    def as_dict(self) -> dict:
        return {
            "sweep_file": str(self.path),
            "name": self.name,
            "scene": str(self.scene),
            "set": dict(self.fixed),
            "grid": {k: list(v) for k, v in self.grid},
            "zip": {k: list(v) for k, v in self.zipped},
        }


def toml_value(v: Any) -> str:
    """`v` written as the TOML value `--set` parses back to the same thing."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string for everything JSON escapes
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise ConfigError(f"value {v!r} of type {type(v).__name__} cannot be a scene override")


def _flatten(table: dict, prefix: str = "") -> list[tuple[str, Any]]:
    out = []
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out += _flatten(v, key + ".")
        else:
            out.append((key, v))
    return out


def _label_value(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        return "-".join(_label_value(x) for x in v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float) and v == int(v) and abs(v) < 1e15:
        return repr(v)
    return str(v)


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+_-]+", "-", text).strip("-") or "x"


def member_names(varied_keys: list[str], rows: list[list[Any]]) -> list[str]:
    """Readable, unique folder names: `leaf-value` per varied key, joined by `_`.

    The leaf is the key's last part (`particle_radius`); the full key is used where two varied
    keys share a leaf (`fluid.0.velocity`, `fluid.1.velocity`). No varied keys: `base`."""
    if not varied_keys:
        return ["base"] * len(rows)
    leaves = [k.rsplit(".", 1)[-1] for k in varied_keys]
    labels = [k if leaves.count(leaf) > 1 else leaf for k, leaf in zip(varied_keys, leaves)]
    names = ["_".join(_safe(f"{lab}-{_label_value(v)}") for lab, v in zip(labels, row)) for row in rows]
    if len(set(names)) < len(names):  # values that differ only in characters _safe drops
        names = [f"{i:03d}_{n}" for i, n in enumerate(names)]
    return names


def load_sweep(path: str | Path, extra: list[str] = ()) -> Sweep:
    """Read and check a sweep file (ConfigError naming the file and key); `extra`: more [set] as KEY=VALUE."""
    given = Path(path)
    where = str(given)
    resolved = given.expanduser().resolve()
    if given.suffix.lower() != ".toml":
        raise ConfigError(f"{where}: a sweep file is TOML (.toml), with scene = ... and [set] / [grid] / [zip]")
    if not resolved.is_file():
        raise ConfigError(f"sweep file not found: {where} (resolved: {resolved})")
    try:
        data = tomllib.loads(resolved.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{where}: not valid TOML: {' '.join(str(exc).split())}") from exc
    for k in data:
        if k not in TOP_KEYS:
            raise ConfigError(
                f"{where}: unknown key {k!r}; a sweep file has {', '.join(TOP_KEYS)} "
                f"(scene keys go under [set], [grid] or [zip])"
            )
    scene = data.get("scene")
    if not isinstance(scene, str) or not scene:
        raise ConfigError(f'{where}: scene = "..." (the base scene file, relative to the sweep file) is missing')
    scene_path = (resolved.parent / scene).resolve()
    if scene_path.suffix.lower() not in (".toml", ".json"):
        raise ConfigError(f"{where}: scene = {scene!r}: expected a .toml scene or a SPlisHSPlasH .json scene")
    if not scene_path.is_file():
        raise ConfigError(f"{where}: scene = {scene!r}: file not found (resolved: {scene_path})")
    name = data.get("name", resolved.stem)
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{where}: name must be a non-empty string")
    sections = {}
    for s in SECTIONS:
        table = data.get(s, {})
        if not isinstance(table, dict):
            raise ConfigError(f'{where}: [{s}] must be a table of "key.path" = value')
        sections[s] = _flatten(table)
    for item in extra:
        k, sep, raw = str(item).partition("=")
        if not sep or not k.strip():
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. simulation.end_time=1.5")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        sections["set"] = [(a, b) for a, b in sections["set"] if a != k.strip()] + [(k.strip(), value)]
    seen: dict[str, str] = {}
    for s in SECTIONS:
        for k, v in sections[s]:
            if k in seen:
                raise ConfigError(f"{where}: key {k!r} is in both [{seen[k]}] and [{s}]; give it once")
            seen[k] = s
            if s == "set":
                continue
            if not isinstance(v, list) or not v:
                raise ConfigError(f"{where}: [{s}] {k!r} must be a non-empty list of values, got {v!r}")
    zipped = sections["zip"]
    if zipped:
        lengths = {k: len(v) for k, v in zipped}
        if len(set(lengths.values())) > 1:
            raise ConfigError(
                f"{where}: the [zip] lists must have equal lengths, got "
                + ", ".join(f"{k}: {n}" for k, n in lengths.items())
            )
    grid = sections["grid"]
    varied_keys = [k for k, _ in grid] + [k for k, _ in zipped]
    rows = []
    zip_rows = list(zip(*[v for _, v in zipped])) if zipped else [()]
    for combo in itertools.product(*[v for _, v in grid]):
        for z in zip_rows:
            rows.append(list(combo) + list(z))
    names = member_names(varied_keys, rows)
    fixed = tuple(sections["set"])
    members = tuple(
        Member(i, n, fixed + tuple(zip(varied_keys, row)), tuple(zip(varied_keys, row)))
        for i, (n, row) in enumerate(zip(names, rows))
    )
    for m in members:  # every value must be writable as a --set value
        for k, v in m.overrides:
            try:
                toml_value(v)
            except ConfigError as exc:
                raise ConfigError(f"{where}: member {m.name}: {k}: {exc}") from None
    return Sweep(
        resolved,
        name,
        scene_path,
        fixed,
        tuple((k, tuple(v)) for k, v in grid),
        tuple((k, tuple(v)) for k, v in zipped),
        members,
    )


def validate(sweep: Sweep, max_particles: int | None = None, concurrent: int = 1) -> list:
    """Resolve every member's scene and run `ipsph run`'s pre-allocation checks on it.

    Returns the members' Scenes. Raises ConfigError/InputError `"<sweep file>: member <name>: <why>"`
    (one line, the key named by the scene loader). `concurrent`: members that may run side by side on
    this machine, which share its memory budget when `max_particles` is not given."""
    from ..errors import InputError
    from ..run import preflight
    from ..sampling.budget import default_max_particles
    from ..scene import load_scene

    limit = max_particles or max(1, default_max_particles() // max(1, concurrent))
    scenes = []
    for m in sweep.members:
        try:
            scene = load_scene(sweep.scene, m.set_args())
            preflight.check_size(scene, limit)
            preflight.check_geometry(scene)
        except InputError as exc:
            raise type(exc)(f"{sweep.path.name}: member {m.name}: {exc}") from None
        scenes.append(scene)
    return scenes
