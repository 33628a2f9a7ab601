"""The importer's reading helpers: one-line errors naming the JSON key, typed reads, the record
of what was ignored."""

from __future__ import annotations

import math
from typing import Any

from ...errors import ConfigError

# Unsupported keys worth a reason in the warning (anything else is listed bare).
_NOTES = {
    "boundaryHandlingMethod": "every value maps to simulation.boundary_model = akinci-volume: Akinci particles "
    "placed so that the fluid's volume meets the surface, what its volume and density maps aim at",
    "numberOfStepsPerRenderUpdate": "GUI only",
    "particleAttributes": "ipsph writes output.fields",
    "kernel": "ipsph uses the cubic spline",
    "gradKernel": "ipsph uses the cubic spline",
    "mapResolution": "volume maps are not used",
    "mapThickness": "volume maps are not used",
    "mapFile": "volume maps are not used",
    "surfaceTension": "no surface tension model",
    "surfaceTensionMethod": "no surface tension model",
    "vorticity": "no vorticity model",
    "vorticityMethod": "no vorticity model",
    "drag": "no drag model",
    "dragMethod": "no drag model",
    "exponent": "WCSPH only",
    "velocityUpdateMethod": "PBF only",
    "enablePartioExport": "ipsph writes VTU/PVD",
    "enableVTKExport": "ipsph writes VTU/PVD",
    "color": "visual only",
    "colorMapType": "visual only",
    "colorField": "visual only",
    "renderMinValue": "visual only",
    "renderMaxValue": "visual only",
    "renderWalls": "visual only",
    "pause": "GUI only",
    "pauseAt": "GUI only",
    "samplingMode": "ipsph samples walls itself",
    "particleFile": "ipsph samples walls itself",
    "resolutionSDF": "ipsph samples meshes itself",
    "enableZSort": "ipsph sorts by cell",
}


class Reader:
    """The state and typed reads every part of the importer shares."""

    def __init__(self, where: str, raw: dict):
        self.where = where
        self.raw = raw
        self.ignored: dict[str, list[str]] = {}  # "RigidBodies[*].color" -> ["0", "1"]
        self.notes: list[str] = []

    # -- helpers ---------------------------------------------------------------------------------
    def fail(self, key: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.where}: {key}: {msg}")

    def ignore(self, section: str, key: str, value: Any = None, index: int | None = None):
        label = f"{section}[*].{key}" if index is not None else (f"{section}.{key}" if section else key)
        note = _NOTES.get(key)
        if key == "boundaryHandlingMethod" and value is not None:
            label = f"{label}={value}"
        if note:
            label = f"{label} ({note})"
        self.ignored.setdefault(label, [])
        if index is not None:
            self.ignored[label].append(str(index))

    def num(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(key, f"expected a number, got {value!r}")
        return float(value)

    def int_(self, value: Any, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or float(value) != int(value):
            raise self.fail(key, f"expected an integer, got {value!r}")
        return int(value)

    def bool_(self, value: Any, key: str) -> bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, int):  # SPlisHSPlasH reads integers as booleans (v != 0)
            return value != 0
        raise self.fail(key, f"expected true or false, got {value!r}")

    def vec3(self, value: Any, key: str) -> list[float]:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return [self.num(value, key)] * 3  # SPlisHSPlasH accepts a scalar scale
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(key, f"expected 3 numbers [x, y, z], got {value!r}")
        return [self.num(c, f"{key}[{i}]") for i, c in enumerate(value)]

    def list_of_objects(self, key: str) -> list[dict]:
        items = self.raw.get(key, [])
        if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
            raise self.fail(key, "expected an array of objects")
        return items

    # -- conversion ------------------------------------------------------------------------------
