"""Which scenes `ipsph bench` runs: the stock SPlisHSPlasH scenes, the Table 1 pipelines, the scaling tank.

* Stock scenes (``DamBreakModel``, ``DoubleDamBreak``, ``DamBreakModelDragons``) are looked up by name
  in ``--scene-dir``, else in ``$IPSPH_SPLISHSPLASH_SCENES``, else in the repository's copy
  ``tests/data/splishsplash/Scenes`` (MIT, with provenance; ``./Scenes`` too when run elsewhere). Our ``load_scene`` imports them directly
  and SPlisHSPlasH runs the same file.
* The Table 1 pipelines (``pipelines/*.toml``) are paired with the stock scene SPlisHSPlasH runs for
  the same case.
* The scaling tank is the built-in default scene with overrides: a dam-break column of ~N particles
  at r = 0.025 m in a tank 2.5 columns long (so the count is exact and nothing is written to disk).
  ``scaling_peer_scene`` writes the same dam break as a SPlisHSPlasH scene for the peer's rows.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from ..config import TimeStepConfig
from ..errors import ConfigError
from ..params import default, spacing
from ..scene import lattice_counts

__all__ = [
    "DEFAULT_SCENES",
    "PIPELINES",
    "resolve_scene",
    "pipeline_path",
    "scaling_overrides",
    "scaling_count",
    "scaling_dt_max",
    "scaling_peer_scene",
]

DEFAULT_SCENES = ("DamBreakModel", "DoubleDamBreak")
_REPO_ROOT = Path(__file__).resolve().parents[2]
_STOCK_SUBDIR = Path("tests") / "data" / "splishsplash" / "Scenes"  # tests/data/splishsplash/PROVENANCE.md
# Table 1 case -> (pipeline file stem, the SPlisHSPlasH stock scene for the same case)
PIPELINES = {
    "breaking_dam": "DamBreakModel",
    "double_dam_break": "DoubleDamBreak",
    "two_dragons": "DamBreakModelDragons",
}


def _candidates(scene_dir: str | Path | None) -> list[Path]:
    if scene_dir is not None:
        return [Path(scene_dir).expanduser()]
    out = []
    env = os.environ.get("IPSPH_SPLISHSPLASH_SCENES")
    if env:
        out.append(Path(env).expanduser())
    out += [_REPO_ROOT / _STOCK_SUBDIR, Path.cwd() / _STOCK_SUBDIR, Path.cwd() / "Scenes"]
    return list(dict.fromkeys(out))


def resolve_scene(name_or_path: str, scene_dir: str | Path | None = None) -> Path:
    """A scene file path, or a stock scene name (``DamBreakModel``) looked up in the stock folder."""
    given = Path(name_or_path).expanduser()
    if given.suffix.lower() in (".json", ".toml") or os.sep in name_or_path:
        if given.is_file():
            return given.resolve()
        raise ConfigError(f"bench scene {name_or_path} (resolved {given.resolve()}) is not a file")
    tried = []
    for c in _candidates(scene_dir):
        p = c / f"{name_or_path}.json"
        tried.append(str(p))
        if p.is_file():
            return p.resolve()
    raise ConfigError(
        f"bench scene {name_or_path!r} not found (looked for {', '.join(tried)}); pass a scene "
        f"file path, or the SPlisHSPlasH Scenes folder with --scene-dir"
    )


def pipeline_path(stem: str) -> Path:
    """pipelines/<stem>.toml in the repository (or the current directory)."""
    for base in (_REPO_ROOT, Path.cwd()):
        p = base / "pipelines" / f"{stem}.toml"
        if p.is_file():
            return p.resolve()
    raise ConfigError(f"pipeline {stem}.toml not found in {_REPO_ROOT / 'pipelines'} or {Path.cwd() / 'pipelines'}")


def _scaling_dims(n_target: int) -> tuple[int, int]:
    """(nx = nz, ny) with ny ~ 1.5 nx and nx * ny * nx ~ n_target."""
    nx = max(2, int(round((n_target / 1.5) ** (1.0 / 3.0))))
    ny = max(2, int(round(n_target / (nx * nx))))
    return nx, ny


def _scaling_boxes(n_target: int, radius: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Upper corners of the column's and the tank's boxes, both from the origin.

    A box holds round(extent / 2r) - 1 particles per axis (first one at min + 2r), so an extent of
    (n + 1) * 2r gives exactly n; the tank is 2.5 columns long, 1.25 columns high and as deep as
    the column, which keeps the first layer one spacing from every wall.
    """
    if not (isinstance(n_target, int) and n_target >= 8):
        raise ConfigError(f"--scaling size {n_target!r} must be an integer >= 8 fluid particles")
    d = spacing(radius)
    nx, ny = _scaling_dims(n_target)
    ex, ey = (nx + 1) * d, (ny + 1) * d
    return (ex, ey, ex), (2.5 * ex, 1.25 * ey, ex)


def scaling_overrides(n_target: int, radius: float = 0.025) -> list[str]:
    """--set overrides turning the default scene into a dam break with ~n_target fluid particles
    (the column and tank of `_scaling_boxes`)."""
    column, tank = _scaling_boxes(n_target, radius)
    vec = lambda v: "[" + ", ".join(repr(round(x, 9)) for x in v) + "]"  # noqa: E731
    return [
        f"simulation.particle_radius={radius!r}",
        "fluid.0.box.min=[0.0, 0.0, 0.0]",
        f"fluid.0.box.max={vec(column)}",
        "boundary.0.box.min=[0.0, 0.0, 0.0]",
        f"boundary.0.box.max={vec(tank)}",
    ]


def scaling_count(n_target: int, radius: float = 0.025) -> int:
    """The exact fluid count of scaling_overrides(n_target, radius)."""
    column, _ = _scaling_boxes(n_target, radius)
    return math.prod(lattice_counts((0, 0, 0), column, radius))


def scaling_dt_max(radius: float = 0.025) -> float:
    """The scaling dam break's maximum step: our default for a scene without time_step.dt_max
    (5 ms * r / 0.025 m, method.md section 1), which the column starting at rest takes."""
    return TimeStepConfig().resolved_dt_max(radius)


def scaling_peer_scene(n_target: int, folder: Path, radius: float = 0.025) -> Path:
    """Write the scaling dam break as a SPlisHSPlasH scene (and its tank mesh) into `folder`.

    The same column, tank, radius, CFL and maximum step as ``scaling_overrides``: SPlisHSPlasH fills
    a FluidBlock as we fill a box (round(extent / 2r) - 1 per axis, the first at min + 2r), so the
    fluid counts match. Its walls are Akinci boundary particles, as ours (boundaryHandlingMethod 0;
    its stock scenes use volume maps), its viscosity XSPH with our default coefficient, and its
    DFSPH the stock scenes' tolerances (0.05 % density, 0.1 % divergence).
    """
    import meshio

    from ..geometry.meshes import box_mesh, mesh_arrays

    column, tank = _scaling_boxes(n_target, radius)
    folder = Path(folder)
    mesh = folder / "scaling_tank.obj"  # in place: the rigid body needs no transform
    points, faces = mesh_arrays(box_mesh((0.0, 0.0, 0.0), tank))
    meshio.write(mesh, meshio.Mesh(points, [("triangle", faces)]))
    dt_max = scaling_dt_max(radius)
    zeta = default("simulation.viscosity")  # ours, which scaling_overrides leaves as it is
    scene = {
        "Configuration": {
            "particleRadius": radius,
            "gravitation": [0.0, -9.81, 0.0],  # the method: run_peer's
            "timeStepSize": dt_max,
            "cflMethod": 1,
            "cflFactor": 1.0,
            "cflMaxTimeStepSize": dt_max,
            "boundaryHandlingMethod": 0,
            "DFSPH": {
                "minIterations": 2,
                "maxIterations": 100,
                "maxError": 0.05,
                "maxIterationsV": 100,
                "maxErrorV": 0.1,
                "enableDivergenceSolver": True,
            },
        },
        "Materials": [
            {
                "id": "Fluid",
                "density0": 1000.0,
                "viscosityMethod": 0,  # no viscosity model: XSPH is a filter of its own since 2.12
                "XSPH": {"xsph": zeta},  # (the peer, 2.19, reads a model's keys from its named block)
            }
        ],
        "RigidBodies": [{"geometryFile": str(mesh.resolve()), "isDynamic": False, "isWall": True}],
        "FluidBlocks": [{"denseMode": 0, "start": [0.0, 0.0, 0.0], "end": list(column)}],
    }
    path = folder / f"scaling_{n_target}.json"
    path.write_text(json.dumps(scene, indent=1))
    return path
