"""The package's floor plan (docs/architecture.md, "Layers"): every import inside ipsph runs down the
layer order, never back up, and only the modules the plan names lie loose at the top of ipsph/."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "ipsph"

# Bottom to top, as the data flows: declared facts, the resolved scene, geometry, the solver's
# seam and search, walls, emitters, sampling, scene readers, methods, the time loop, writers, gauges and
# post-processing, `ipsph run`, sweeps, benchmarks, the command line. A room may import its own
# layer and the layers below it.
LAYERS = [
    {"errors", "_version", "params"},
    {"config"},
    {"geometry"},
    {"backends"},
    {"neighbours"},
    {"boundary"},
    {"flow"},
    {"sampling"},
    {"scene"},
    {"methods"},
    {"simulation"},
    {"io"},
    {"gauges"},
    {"post"},
    {"run"},
    {"sweeps"},
    {"bench"},
    {"cli"},
    {"__init__", "__main__"},
]
LOOSE_MODULES = {"__init__", "__main__", "_version", "errors", "config", "flow", "simulation", "cli"}


def _room(parts: list[str]) -> str:
    """The room of a module ipsph.<room>...: its top-level package or loose module."""
    return parts[1] if len(parts) > 1 else "__init__"


def _imports():
    """(importer file, importer room, imported room) for every ipsph import, at any depth in a file."""
    for path in PACKAGE.rglob("*.py"):
        parts = ["ipsph", *path.relative_to(PACKAGE).with_suffix("").parts]
        pkg = parts[:-1]  # the package a relative import starts from (a module's or an __init__'s own)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name.split(".") for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = pkg[: len(pkg) - node.level + 1] if node.level else []
                mod = base + (node.module.split(".") if node.module else [])
                targets = [mod + [a.name] for a in node.names] if len(mod) == 1 else [mod]
            else:
                continue
            for t in targets:
                if t[0] == "ipsph":
                    yield path, _room(parts), _room(t)


def _layer(room: str) -> int:
    for k, rooms in enumerate(LAYERS):
        if room in rooms:
            return k
    raise AssertionError(f"ipsph/{room} is in no layer of LAYERS: add it where it belongs")


def _upward(imports) -> list[str]:
    return sorted(
        f"{path} ({room}) imports ipsph.{target}" for path, room, target in imports if _layer(target) > _layer(room)
    )


def test_every_import_runs_down_the_layers():
    upward = _upward(_imports())
    assert upward == [], "imports that run back up the floor plan:\n" + "\n".join(upward)


def test_the_layer_check_sees_an_upward_import():
    """The check itself can fail: a methods module importing the runner is reported, and the walk
    finds relative imports (methods/ reaches backends/ only through them)."""
    assert _upward([("ipsph/methods/x.py", "methods", "run")]) == ["ipsph/methods/x.py (methods) imports ipsph.run"]
    assert ("methods", "backends") in {(room, target) for _, room, target in _imports()}


def test_only_the_planned_modules_lie_loose():
    loose = {p.stem for p in PACKAGE.glob("*.py")}
    assert loose <= LOOSE_MODULES, f"loose modules outside the plan: {sorted(loose - LOOSE_MODULES)}"
    rooms = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    for room in rooms | loose:
        _layer(room)


def test_the_studies_use_only_public_helpers_of_the_package():
    """benchmarks/ (not installed) builds on ipsph as a user would: no `_private` module or name."""
    private = []
    for path in (PACKAGE.parent / "benchmarks").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("ipsph"):
                names = node.module.split(".") + [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                names = [part for a in node.names if a.name.startswith("ipsph") for part in a.name.split(".")]
            else:
                continue
            private += [f"{path.name}: {n}" for n in names if n.startswith("_")]
    assert private == [], private
