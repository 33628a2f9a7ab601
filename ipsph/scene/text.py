"""How scene values and parameters are written in messages and in the generated reference."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..params import AUTO, Param


def _fmt(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _fmt_vec(v) -> str:
    return "[" + ", ".join(_fmt(float(c)) for c in v) + "]"


def _tname(v: Any) -> str:
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, int):
        return "an integer"
    if isinstance(v, float):
        return "a float"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, (list, tuple)):
        return "an array"
    if isinstance(v, dict):
        return "a table"
    return type(v).__name__


def _show(v: Any) -> str:
    text = repr(v) if not isinstance(v, bool) else str(v).lower()
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{_tname(v)} ({text})" if not isinstance(v, (list, tuple)) else text


def _type_name(p: Param) -> str:
    return {
        "float": "float",
        "int": "integer",
        "bool": "boolean",
        "str": "string",
        "path": "path",
        "choice": "string",
        "vec3": "[x, y, z]",
        "range2": "[min, max]",
        "fields": "list of strings",
        "keyframes": "array of tables",
    }[p.kind]


def _fmt_default(p: Param) -> str:
    v = p.default
    if v is None:
        return AUTO if p.optional else "-"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (tuple, list)):
        if p.kind == "fields":
            return "[" + ", ".join(f'"{x}"' for x in v) + "]"
        if p.kind == "keyframes":
            return "[]"
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"
    if isinstance(v, (str, Path)):
        return f'"{v}"'
    return repr(v)


def _allowed(p: Param) -> str:
    if p.choices:
        return ("any of " if p.kind == "fields" else "") + ", ".join(p.choices)
    if p.lo is None and p.hi is None:
        return ""
    what = "each component" if p.kind in ("vec3", "range2") else "value"
    lo = "" if p.lo is None else f"{_fmt(p.lo)} {'<' if p.lo_open else '<='} "
    hi = "" if p.hi is None else f" {'<' if p.hi_open else '<='} {_fmt(p.hi)}"
    return f"{lo}{what}{hi}"
