"""Every declared fact the rest of ipsph is generated from.

* `PARAMS`: every scene parameter, once: key path, type, default, unit, allowed values, one line
  of doc. The model's dataclass defaults (`ipsph.config`), scene validation and `--set`
  (`ipsph.scene`), `--help`, the CLI's choices and docs/scene-reference.md are generated from it.
* `RENAMED`: keys that moved, old path -> new path; reading an old key is a one-line error that
  names the new one.
* `METHOD_NAMES`, `PHASES` (the timers a step reports, the stats.csv `ms_*` columns and the plot
  bars), `OUTPUT_FIELDS`, `RENDER_VIEWS`.

The declarations, by topic: facts.py (the facts that are not keys), schema.py (`Param`), and
the keys: run_keys.py ([simulation], [time_step], [solver.*]), output_keys.py ([output],
[render], [surface]), body_keys.py ([[fluid]], [[boundary]]), flow_keys.py ([[emitter]],
[[sink]], [domain]), gauge_keys.py ([[gauge]]). Adding a scene key: one `_P(...)` entry in its table's
file (the field it lands in, reading and writing it follow from the entry), then
`python -m ipsph.scene > docs/scene-reference.md`.

This module imports nothing from ipsph, so everything may import it.
"""

from __future__ import annotations

from typing import Any

from . import body_keys, flow_keys, gauge_keys, output_keys, run_keys
from .facts import (  # noqa: F401 - re-exported: every module reads its facts from ipsph.params
    AUTO,
    AUTO_DT_MAX,
    BACKEND_NAMES,
    BOUNDARY_MODELS,
    BOUNDARY_ROLES,
    BYTES_PER_PARTICLE,
    COURANT,
    FIELD_WALLS,
    METHOD_NAMES,
    MOTION_KEYS,
    MOTION_TYPES,
    OUTPUT_FIELDS,
    PHASES,
    PRECISIONS,
    RENDER_MODES,
    RENDER_VIEWS,
    SETTLE_MODES,
    SPACING_RADII,
    SUPPORT_RADII,
    VISCOSITY_MODELS,
    VISCOSITY_WALLS,
    VISCOUS_STEP,
    auto_dt_max,
    spacing,
    support,
)
from .flow_keys import EMITTER_SHAPES  # noqa: F401 - re-exported
from .gauge_keys import GAUGE_KEYS, GAUGE_KINDS, GAUGE_QUANTITIES  # noqa: F401 - re-exported
from .schema import Param

PARAMS: tuple[Param, ...] = run_keys.KEYS + output_keys.KEYS + body_keys.KEYS + flow_keys.KEYS + gauge_keys.KEYS

PARAM_BY_PATH: dict[str, Param] = {p.path: p for p in PARAMS}
_ENTITIES = ("fluid", "boundary")
_ENTITY_TABLE = {"fluid": "[[fluid]]", "boundary": "[[boundary]]"}

SECTION_DOCS = {
    "": "Top-level keys (outside any table).",
    "simulation": "The physics: method, resolution, material, duration.",
    "time_step": "Adaptive time step (CFL). method.md section 1.",
    "solver": "Shared by the pressure solvers.",
    "solver.divergence": "The divergence solve of DFSPH and of IPSPH (method.md sections 2, 4).",
    "solver.dfsph": "DFSPH's density solve (method.md section 2).",
    "solver.pf": "Projective Fluids (method.md section 3); the stiffness also applies to IPSPH.",
    "solver.ipsph": "IPSPH's average-density loop around the PF passes (method.md section 4).",
    "solver.viscosity": "The implicit viscosity solve (simulation.viscosity_model = implicit; method.md section 10).",
    "output": "What is written, where and how often.",
    "render": "Offscreen renders of the written frames.",
    "surface": "Surface meshes of the fluid (output.surface, `ipsph surface`), reconstructed by "
    "splashsurf (docs/output-format.md). Lengths are in particle radii r.",
    "fluid": "One [[fluid]] table per fluid body: `box = {min = [..], max = [..]}` or "
    '`mesh = "file.obj"`. `fluid[0]` in messages is the first [[fluid]] table.',
    "boundary": "One [[boundary]] table per wall (Akinci boundary particles on its "
    "surface): a box or a closed mesh, as a container or an obstacle. A wall is static, "
    'moves as prescribed (`motion = {type = "sinusoid", ...}`: a kinematic wall) or, '
    "with a density or mass, is a dynamic rigid body two-way coupled to the fluid.",
    "domain": "Optional box outside which fluid is removed (docs/output-format.md: particle counts vary).",
    "emitter": "One [[emitter]] table per nozzle emitting fluid layers at a velocity from start_time "
    "to end_time (SPlisHSPlasH's Emitters). Its position must lie inside a container's "
    "bounds or the [domain] box. New particles carry rho0 (2r)^3 and fresh ids.",
    "sink": "One [[sink]] table per axis-aligned outflow box: fluid entering it is removed (ids are never reused).",
    "gauge": "One [[gauge]] table per gauge: a time series of pressure, velocity and density at a point, "
    "the water level along a vertical line, the force on a wall or body, or the flux through a "
    "rectangle, written to gauges.csv during the run (docs/gauges.md); `ipsph gauge OUT --scene "
    "FILE` measures them on a finished run's frames.",
}

# keys that moved: old path -> new path (a scene that uses the old one gets a one-line error)
RENAMED = {
    "solver.dfsph.divergence_error_pct": "solver.divergence.error_pct",
    "solver.dfsph.divergence_min_iterations": "solver.divergence.min_iterations",
    "solver.dfsph.divergence_max_iterations": "solver.divergence.max_iterations",
    "solver.dfsph.divergence_solve": "solver.divergence.enabled",
}

# keys that were replaced by more than one key: old path -> what to write instead (a one-line error)
REPLACED = {
    "simulation.standard_viscosity": 'simulation.kinematic_viscosity_m2s = <nu> with simulation.viscosity_model = "standard"',
}


def default(path: str) -> Any:
    """The declared default of a parameter (the model's dataclasses take theirs from here)."""
    return PARAM_BY_PATH[path].default
