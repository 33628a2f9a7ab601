"""Scene files -> `ipsph.config.Scene`: the TOML format, strictly validated.

Every parameter is declared once, in `ipsph.params.PARAMS` (key path, type, default, unit,
allowed values, one-line doc); this package is generated from it:

    validate.py    TOML / dict -> Scene: the tables, the entities, the rules between sections
    values.py      one value against its Param: key trees, did-you-mean, renamed keys, types, ranges
    overrides.py   `--set key.path=value` on the dict, before validation
    flow.py, bodies.py, gauges.py   the rules between the keys of [[emitter]]/[[sink]], [[boundary]], [[gauge]]
    serialise.py   Scene -> dict (run.json, checkpoint fingerprints)
    reference.py   docs/scene-reference.md (`python -m ipsph.scene`) and `ipsph run --help`'s key list
    text.py        how values and ranges are written in messages

Sources: `.toml` and `.json` (SPlisHSPlasH scenes, `ipsph.scene.splishsplash`, which converts them to
the same dict form first, so overrides and validation are shared). Paths: mesh files resolve
relative to the scene file's folder; the output folder resolves relative to the current working
directory when the run starts (it is stored as written).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Iterable

from ..config import Scene, SurfaceConfig
from ..errors import ConfigError
from ..params import OUTPUT_FIELDS, PARAM_BY_PATH, PARAMS, RENDER_VIEWS, Param
from .overrides import apply_overrides
from .reference import key_help, reference_markdown
from .serialise import scene_to_dict
from .validate import _build_scene, _read_toml, lattice_counts, surface_values

__all__ = [
    "Param",
    "PARAMS",
    "PARAM_BY_PATH",
    "OUTPUT_FIELDS",
    "RENDER_VIEWS",
    "load_scene",
    "scene_from_dict",
    "read_toml",
    "apply_overrides",
    "scene_to_dict",
    "default_scene_path",
    "reference_markdown",
    "key_help",
    "lattice_counts",
    "surface_config",
]


def default_scene_path() -> Path:
    """The built-in dam break (`ipsph/scene/default.toml`)."""
    return Path(__file__).resolve().with_name("default.toml")


def load_scene(path: str | Path, overrides: Iterable[str] = ()) -> Scene:
    """Read a scene file (.toml, or .json for SPlisHSPlasH), apply `--set` overrides, validate.

    JSON scenes are converted to the TOML dict form first (`ipsph.scene.splishsplash.scene_dict`), so
    overrides use the same key paths for both (`fluid.0.velocity=[1,0,0]`); the importer's
    warnings are kept in `Scene.warnings`.
    """
    given = Path(path)
    where = str(given)
    suffix = given.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise ConfigError(
            f"{where}: unknown scene file type {given.suffix or '(none)'!r}: "
            f"expected .toml (ipsph scene) or .json (SPlisHSPlasH scene)"
        )
    resolved = given.expanduser().resolve()
    if not resolved.is_file():
        raise ConfigError(f"scene file not found: {where} (resolved: {resolved})")
    warnings: tuple[str, ...] = ()
    if suffix == ".toml":
        data = _read_toml(resolved, where)
    else:
        from . import splishsplash

        data, warnings = splishsplash.scene_dict(resolved, where=where)
    data.setdefault("name", resolved.stem)
    data = apply_overrides(data, overrides)
    scene = _build_scene(data, resolved.parent, None, resolved, where)
    return dataclasses.replace(scene, warnings=tuple(warnings)) if warnings else scene


def read_toml(path: str | Path) -> dict:
    """A TOML file as a dict; a syntax error is a ConfigError naming the line and column."""
    given = Path(path)
    resolved = given.expanduser().resolve()
    if not resolved.is_file():
        raise ConfigError(f"file not found: {given} (resolved: {resolved})")
    return _read_toml(resolved, str(given))


def scene_from_dict(
    data: dict, base_dir: Path | None = None, name: str | None = None, *, source: Path | None = None
) -> Scene:
    """Validate a dict in the TOML layout and build the Scene.

    base_dir: folder that relative mesh paths resolve against (default: current directory).
    name: scene name (default: data["name"], else "scene"). source: recorded in Scene.source
    (default: data["source"] if present).
    """
    where = str(source) if source is not None else "scene"
    return _build_scene(data, Path(base_dir) if base_dir is not None else Path.cwd(), name, source, where)


def surface_config(stored: dict | None, overrides: Iterable[str] = (), where: str = "surface") -> SurfaceConfig:
    """The [surface] settings of a stored scene dict (run.json's `scene`), with `--set surface.KEY=VALUE`
    overrides, validated by PARAMS alone: no meshes are resolved (`ipsph surface`, `ipsph render`)."""
    data = apply_overrides({"surface": dict((stored or {}).get("surface") or {})}, overrides)
    other = sorted(set(data) - {"surface"})
    if other:
        raise ConfigError(f"{where}: only surface.* keys can be set here, not {other[0]}")
    return surface_values(data["surface"], where)
