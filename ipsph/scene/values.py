"""Checking values against their declared `Param`: walking a table against the key tree, the
"did you mean" of an unknown key, the renamed keys, types and ranges (house-style 6 and 7). No
model knowledge: `validate` builds the Scene from what these return.
"""

from __future__ import annotations

import difflib
import math
import re
from typing import Any, Iterable

from ..errors import ConfigError
from ..params import AUTO, PARAMS, RENAMED, REPLACED, Param
from .text import _allowed, _fmt, _show

ENTITIES = ("fluid", "boundary", "emitter", "sink", "gauge")
ENTITY_TABLE = {e: f"[[{e}]]" for e in ENTITIES}


def _tree(params: Iterable[Param]) -> dict:
    root: dict = {}
    for p in params:
        node = root
        parts = p.path.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = p
    return root


_ROOT = _tree(p for p in PARAMS if p.path.split(".", 1)[0] not in ENTITIES)
_ENTITY_TREES = {e: _tree(p for p in PARAMS if p.path.startswith(e + "."))[e] for e in ENTITIES}
_TOP_KEYS = sorted(set(_ROOT) | set(ENTITIES))


def renamed_error(path: str, where: str) -> None:
    """ConfigError naming the new key when `path` (dotted, or `fluid[0].x`) is a renamed one."""
    plain = re.sub(r"\[\d+\]|\.\d+(?=\.)", "", path)
    if plain in RENAMED:
        raise ConfigError(f"{where}: {path} was renamed to {RENAMED[plain]}: write it as {RENAMED[plain]}")
    if plain in REPLACED:
        raise ConfigError(f"{where}: {path} was replaced: write {REPLACED[plain]}")


class _Ctx:
    def __init__(self, where: str):
        self.where = where

    def fail(self, key: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.where}: {key}: {msg}")


def _walk(ctx: _Ctx, data: Any, tree: dict, prefix: str, out: dict) -> None:
    if not isinstance(data, dict):
        raise ctx.fail(prefix, f"expected a table ([{prefix}]), got {_show(data)}")
    for key, value in data.items():
        shown = f"{prefix}.{key}"
        if key not in tree:
            renamed_error(shown, ctx.where)
            raise _unknown(ctx, key, prefix, sorted(tree))
        node = tree[key]
        if isinstance(node, Param):
            out[node.path] = _convert(ctx, node, value, shown)
        else:
            _walk(ctx, value, node, shown, out)


def _unknown(ctx: _Ctx, key: str, prefix: str, allowed: list[str]) -> ConfigError:
    shown = f"{prefix}.{key}" if prefix else key
    close = difflib.get_close_matches(key, allowed, n=3, cutoff=0.6)
    if close:
        hint = "; did you mean " + " or ".join(repr(c) for c in close) + "?"
    else:
        # the right key in the wrong table: [simulation] cfl_factor -> time_step.cfl_factor
        elsewhere = [p.path for p in PARAMS if p.key == key and p.path != "source"]
        elsewhere = [re.sub(rf"^({'|'.join(ENTITIES)})\.", r"\1[i].", e) for e in elsewhere]
        hint = "; did you mean " + " or ".join(repr(e) for e in elsewhere) + "?" if elsewhere else ""
    where_ = f"[{prefix}]" if prefix else "the top level"
    return ConfigError(f"{ctx.where}: unknown key {shown!r}{hint} (allowed in {where_}: {', '.join(allowed)})")


def _convert(ctx: _Ctx, p: Param, value: Any, shown: str) -> Any:
    """Check one value against its Param; return it in model form."""
    if p.optional and (value is None or value == AUTO):
        return None
    kind = p.kind
    if kind == "float":
        x = _number(ctx, value, shown, p)
        _check_range(ctx, p, x, shown)
        return x
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.fail(shown, f"expected an integer, got {_show(value)}")
        _check_range(ctx, p, value, shown)
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise ctx.fail(shown, f"expected true or false, got {_show(value)}")
        return value
    if kind in ("str", "path"):
        if not isinstance(value, str) or not value.strip():
            raise ctx.fail(shown, f"expected a non-empty string, got {_show(value)}")
        return value
    if kind == "choice":
        if not isinstance(value, str) or value not in p.choices:
            close = difflib.get_close_matches(str(value), p.choices, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ctx.fail(shown, f"{_show(value)} is not one of {', '.join(p.choices)}{hint}")
        return value
    if kind == "vec3":
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise ctx.fail(shown, f"expected 3 numbers [x, y, z], got {_show(value)}")
        v = tuple(_number(ctx, c, f"{shown}[{i}]", p) for i, c in enumerate(value))
        for i, c in enumerate(v):
            _check_range(ctx, p, c, f"{shown}[{i}]")
        return v
    if kind == "range2":
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise ctx.fail(shown, f"expected 2 numbers [min, max], got {_show(value)}")
        lo, hi = (_number(ctx, c, f"{shown}[{i}]", p) for i, c in enumerate(value))
        _check_range(ctx, p, lo, f"{shown}[0]")
        if not lo < hi:
            raise ctx.fail(shown, f"min {_fmt(lo)} must be < max {_fmt(hi)}")
        return (lo, hi)
    if kind == "keyframes":
        from .bodies import convert_keyframes

        return convert_keyframes(ctx, value, shown)
    if kind == "fields":
        if not isinstance(value, (list, tuple)):
            raise ctx.fail(shown, f"expected a list of field names, got {_show(value)}")
        for i, f in enumerate(value):
            if not isinstance(f, str) or f not in p.choices:
                raise ctx.fail(f"{shown}[{i}]", f"{_show(f)} is not one of {', '.join(p.choices)}")
        dup = sorted({f for f in value if list(value).count(f) > 1})
        if dup:
            raise ctx.fail(shown, f"listed more than once: {', '.join(dup)}")
        return tuple(value)
    raise AssertionError(f"unknown parameter kind {kind!r}")  # programming error, not input


def _number(ctx: _Ctx, value: Any, shown: str, p: Param) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ctx.fail(shown, f"expected a number, got {_show(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ctx.fail(shown, f"expected a finite number, got {_show(value)}")
    return x


def _check_range(ctx: _Ctx, p: Param, x: float, shown: str) -> None:
    bad = (p.lo is not None and (x < p.lo or (p.lo_open and x == p.lo))) or (
        p.hi is not None and (x > p.hi or (p.hi_open and x == p.hi))
    )
    if bad:
        unit = f" {p.unit}" if p.unit else ""
        raise ctx.fail(shown, f"{_fmt(x)}{unit} is out of range: allowed {_allowed(p)}")


def _get(obj: Any, target: str) -> Any:
    for part in target.split("."):
        obj = getattr(obj, part)
    return obj
