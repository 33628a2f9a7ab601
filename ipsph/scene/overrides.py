"""`--set key.path=value` overrides on a scene dict (TOML layout), before validation."""

from __future__ import annotations

import copy
import difflib
import re
import tomllib
from typing import Any, Iterable

from ..errors import ConfigError
from ..params import PARAM_BY_PATH, PARAMS
from .validate import ENTITIES, ENTITY_TABLE, renamed_error


def apply_overrides(data: dict, overrides: Iterable[str]) -> dict:
    """Apply `key.path=value` overrides (CLI `--set`) to a copy of `data`.

    The value is parsed as a TOML value (`1.5`, `true`, `[1, 0, 0]`, `"text"`), falling back to
    the raw string (`out/run1`, `dfsph`, `auto`). Fluid and boundary entries are addressed by
    index: `fluid.0.velocity=[1,0,0]` or `fluid[0].velocity=...`. Setting `mesh` on an entry
    drops its `box` and setting `box.min`/`box.max` drops its `mesh`. The result is validated
    by `scene_from_dict` as a whole.
    """
    out = copy.deepcopy(data)
    for item in overrides:
        key, sep, raw = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. simulation.end_time=1.5")
        value = _parse_override_value(raw.strip())
        parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
        if parts[0] in ENTITIES:
            _override_entity(out, parts, key, value)
            continue
        path = ".".join(parts)
        p = PARAM_BY_PATH.get(path)
        renamed_error(path, f"--set {key}")
        if p is None or path == "source":
            raise ConfigError(
                f"--set {key}: unknown key{_suggest_path(path)}; see "
                f"`ipsph --help` or docs/scene-reference.md for the keys"
            )
        node = out
        for i, part in enumerate(parts[:-1]):
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {key}: {'.'.join(parts[: i + 1])} in the scene is not a table")
            node = nxt
        node[parts[-1]] = value
    return out


def _parse_override_value(raw: str) -> Any:
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def _override_entity(out: dict, parts: list[str], key: str, value: Any) -> None:
    kind = parts[0]
    if len(parts) < 3 or not parts[1].isdigit():
        raise ConfigError(
            f"--set {key}: address a {ENTITY_TABLE[kind]} entry by index, e.g. "
            f"{kind}.0.{'velocity' if kind == 'fluid' else 'role'}=..."
        )
    idx = int(parts[1])
    entries = out.get(kind, [])
    if not isinstance(entries, list) or not 0 <= idx < len(entries):
        n = len(entries) if isinstance(entries, list) else 0
        have = f"indices 0..{n - 1}" if n else "none"
        raise ConfigError(
            f"--set {key}: no {kind} number {idx} in the scene ({n} "
            f"{ENTITY_TABLE[kind]} table{'s' if n != 1 else ''}: {have})"
        )
    rest = parts[2:]
    path = ".".join([kind] + rest)
    renamed_error(path, f"--set {key}")
    if path not in PARAM_BY_PATH:
        close = difflib.get_close_matches(path, [p.path for p in PARAMS if p.path.startswith(kind + ".")], n=3)
        hint = (
            ("; did you mean " + " or ".join(repr(f"{kind}.{idx}.{c.split('.', 1)[1]}") for c in close) + "?")
            if close
            else ""
        )
        raise ConfigError(f"--set {key}: unknown key{hint}")
    entry = entries[idx]
    if rest == ["mesh"]:
        entry.pop("box", None)
    elif rest[0] == "box":
        entry.pop("mesh", None)
    node = entry
    for part in rest[:-1]:
        node = node.setdefault(part, {})
    node[rest[-1]] = value


def _suggest_path(path: str) -> str:
    paths = [p.path for p in PARAMS if p.path.split(".", 1)[0] not in ENTITIES and p.path != "source"]
    close = difflib.get_close_matches(path, paths, n=3, cutoff=0.8)
    if not close:
        leaf = path.rsplit(".", 1)[-1]
        close = [p for p in paths if p.rsplit(".", 1)[-1] == leaf]
    return ("; did you mean " + " or ".join(repr(c) for c in close) + "?") if close else ""
