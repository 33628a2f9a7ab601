"""The SPlisHSPlasH JSON -> ipsph dict converter (see the package docstring)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..errors import ConfigError, read_text

SPH_BODY_DENSITY = 1000.0  # SPlisHSPlasH's RigidBodies density when a dynamic body leaves it out

__all__ = ["scene_dict", "DEFAULT_END_TIME"]

# SPlisHSPlasH's own defaults where a scene leaves a key out (doc/file_format.md, Simulation.cpp)
_SPH_DEFAULTS = {
    "particleRadius": 0.025,
    "simulationMethod": 4,
    "timeStepSize": 0.001,
    "cflFactor": 0.5,
    "cflMaxTimeStepSize": 0.005,
    "cflMinTimeStepSize": 1e-4,
    "density0": 1000.0,
    "gravitation": (0.0, -9.81, 0.0),
}
DEFAULT_END_TIME = 2.0  # s, when the scene has no positive stopAt (ipsph's own default)

_METHODS = {0: "WCSPH", 1: "PCISPH", 2: "PBF", 3: "IISPH", 4: "DFSPH", 5: "Projective Fluids"}
_SUPPORTED_METHODS = {4: "dfsph", 5: "pf"}
_VISCOSITY_METHODS = {
    0: "None",
    1: "Standard",
    2: "XSPH",
    3: "Bender and Koschier 2017",
    4: "Peer et al. 2015",
    5: "Peer et al. 2016",
    6: "Takahashi et al. 2015",
    7: "Weiler et al. 2018",
}

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


def scene_dict(path: Path, where: str | None = None) -> tuple[dict, tuple[str, ...]]:
    """Convert a SPlisHSPlasH scene file into ipsph's TOML dict form (unvalidated) and the
    import warnings (at most one string). Mesh paths stay as written: relative to the file."""
    path = Path(path)
    where = where or str(path)
    text = read_text(path, where)
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{where}:{exc.lineno}:{exc.colno}: JSON syntax error: {exc.msg}") from exc
    if not isinstance(raw, dict):
        raise ConfigError(
            f"{where}: a SPlisHSPlasH scene is a JSON object with Configuration, FluidBlocks, RigidBodies, ..."
        )
    return _Importer(where, raw).run()


class _Importer:
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
    def run(self) -> tuple[dict, tuple[str, ...]]:
        out: dict = {"simulation": {}, "time_step": {}, "solver": {}, "output": {}}
        for key in self.raw:
            if key == "AnimationFields" and self.raw[key]:
                raise self.fail(key, "not supported by ipsph; remove it to import the rest of the scene")
            if key not in (
                "Configuration",
                "Materials",
                "RigidBodies",
                "FluidBlocks",
                "FluidModels",
                "Emitters",
                "AnimationFields",
            ):
                self.ignore("", key)
        config = self.raw.get("Configuration", {})
        if not isinstance(config, dict):
            raise self.fail("Configuration", "expected an object")
        self.configuration(config, out)
        self.materials(config, out)
        out["fluid"] = [self.fluid_block(i, b) for i, b in enumerate(self.list_of_objects("FluidBlocks"))] + [
            self.fluid_model(i, m) for i, m in enumerate(self.list_of_objects("FluidModels"))
        ]
        from . import emitters

        r = out["simulation"]["particle_radius"]
        out["emitter"] = [emitters.emitter(self, i, e, r) for i, e in enumerate(self.list_of_objects("Emitters"))]
        mats = [(f"Materials[{i}]", m) for i, m in enumerate(self.list_of_objects("Materials"))]
        box = emitters.domain(self, [("Configuration", config)] + mats)
        if box is not None:
            out["domain"] = box
        for key in ("fluid", "emitter"):
            if not out[key]:
                del out[key]
        if "fluid" not in out and "emitter" not in out:
            raise ConfigError(f"{self.where}: no FluidBlocks, FluidModels or Emitters: nothing to simulate")
        out["boundary"] = [self.rigid_body(i, b) for i, b in enumerate(self.list_of_objects("RigidBodies"))]
        for section in ("simulation", "time_step", "solver", "output"):
            if not out[section]:
                del out[section]
        return out, self.warning()

    def configuration(self, c: dict, out: dict) -> None:
        sim, ts, solver = out["simulation"], out["time_step"], out["solver"]
        g = lambda k: c.get(k, _SPH_DEFAULTS.get(k))  # noqa: E731
        handled = {
            "particleRadius",
            "gravitation",
            "simulationMethod",
            "stopAt",
            "timeStepSize",
            "cflFactor",
            "cflMaxTimeStepSize",
            "cflMinTimeStepSize",
            "cflMethod",
            "cameraPosition",
            "cameraLookat",
            "dataExportFPS",
            "DFSPH",
            "Projective Fluids",
            "sim2D",
            "maxEmitterParticles",
            "emitterReuseParticles",
            "emitterBoxMin",
            "emitterBoxMax",
            # 2.0.0 flat layout (handled here or in materials())
            "density0",
            "viscosity",
            "viscosityMethod",
            "minIterations",
            "maxIterations",
            "maxError",
            "maxIterationsV",
            "maxErrorV",
            "enableDivergenceSolver",
            "stiffness",
        }
        for key, value in c.items():
            if key not in handled:
                self.ignore("Configuration", key, value)
        if "sim2D" in c and self.bool_(c["sim2D"], "Configuration.sim2D"):
            raise self.fail("Configuration.sim2D", "2D simulations are not supported")

        sim["particle_radius"] = self.num(g("particleRadius"), "Configuration.particleRadius")
        sim["gravity"] = self.vec3(list(g("gravitation")), "Configuration.gravitation")
        m = self.int_(g("simulationMethod"), "Configuration.simulationMethod")
        if m not in _SUPPORTED_METHODS:
            name = _METHODS.get(m, "unknown")
            raise self.fail(
                "Configuration.simulationMethod",
                f"{m} ({name}) is not supported: ipsph imports 4 (DFSPH) and 5 "
                f"(Projective Fluids); change it in the file and use --set "
                f"simulation.method=ipsph|pf|dfsph to pick ipsph's method",
            )
        sim["method"] = _SUPPORTED_METHODS[m]
        stop = c.get("stopAt")
        if stop is not None and self.num(stop, "Configuration.stopAt") > 0:
            sim["end_time"] = float(stop)
        else:
            sim["end_time"] = DEFAULT_END_TIME

        dt0 = self.num(g("timeStepSize"), "Configuration.timeStepSize")
        ts["dt_initial"] = dt0
        ts["cfl_factor"] = self.num(g("cflFactor"), "Configuration.cflFactor")
        ts["dt_max"] = self.num(g("cflMaxTimeStepSize"), "Configuration.cflMaxTimeStepSize")
        ts["dt_min"] = self.num(g("cflMinTimeStepSize"), "Configuration.cflMinTimeStepSize")
        cfl = self.int_(c.get("cflMethod", 1), "Configuration.cflMethod")
        if cfl == 0:
            ts["dt_min"] = ts["dt_max"] = dt0
            self.notes.append(
                f"Configuration.cflMethod=0 (fixed step): dt_min = dt_max = dt_initial = timeStepSize = {dt0:g} s"
            )
        elif cfl == 2:
            self.notes.append("Configuration.cflMethod=2 (CFL + solver iterations) is imported as 1 (plain CFL)")
        elif cfl != 1:
            raise self.fail("Configuration.cflMethod", f"{cfl} is not a SPlisHSPlasH CFL method (0, 1 or 2)")
        # a fixed timeStepSize above the CFL bounds would be refused by ipsph's validation
        if cfl != 0 and not ts["dt_min"] <= dt0 <= ts["dt_max"]:
            self.notes.append(
                f"Configuration.timeStepSize={dt0:g} s lies outside "
                f"[cflMinTimeStepSize, cflMaxTimeStepSize]; first step uses the "
                f"CFL value instead"
            )
            del ts["dt_initial"]

        if "dataExportFPS" in c:
            out["output"]["fps"] = self.num(c["dataExportFPS"], "Configuration.dataExportFPS")
        render = {}
        if "cameraPosition" in c:
            render["camera_position"] = self.vec3(c["cameraPosition"], "Configuration.cameraPosition")
        if "cameraLookat" in c:
            render["focal_point"] = self.vec3(c["cameraLookat"], "Configuration.cameraLookat")
        if render:
            out["render"] = render

        # solver settings: blocks (current layout) or flat keys (2.0.0 layout)
        dfsph = c.get("DFSPH", {})
        pf = c.get("Projective Fluids", {})
        for key, block in (("DFSPH", dfsph), ("Projective Fluids", pf)):
            if not isinstance(block, dict):
                raise self.fail(f"Configuration.{key}", "expected an object")
        flat = {
            k: c[k]
            for k in (
                "minIterations",
                "maxIterations",
                "maxError",
                "maxIterationsV",
                "maxErrorV",
                "enableDivergenceSolver",
                "stiffness",
            )
            if k in c
        }
        if flat:
            if "stiffness" in flat:  # 2.0.0: WCSPH and PF share the key
                pf = {**pf, "stiffness": flat.pop("stiffness")}
            if m == 4:
                dfsph = {**dfsph, **flat}
            else:
                for k in ("maxIterationsV", "maxErrorV", "enableDivergenceSolver"):
                    if k in flat:
                        dfsph = {**dfsph, k: flat.pop(k)}
                pf = {**pf, **flat}
        self.dfsph_block(dfsph, solver)
        self.pf_block(pf, solver)

    def dfsph_block(self, b: dict, solver: dict) -> None:
        keys = {
            "minIterations": ("dfsph", "density_min_iterations", self.int_),
            "maxIterations": ("dfsph", "density_max_iterations", self.int_),
            "maxError": ("dfsph", "density_error_pct", self.num),
            "maxIterationsV": ("divergence", "max_iterations", self.int_),
            "maxErrorV": ("divergence", "error_pct", self.num),
            "enableDivergenceSolver": ("divergence", "enabled", self.bool_),
        }
        self._block(b, "Configuration.DFSPH", keys, solver)

    def pf_block(self, b: dict, solver: dict) -> None:
        keys = {
            "stiffness": ("pf", "stiffness", self.num),
            "minIterations": ("ipsph", "min_passes", self.int_),
            "maxIterations": ("ipsph", "max_passes", self.int_),
            "maxError": ("ipsph", "density_error_pct", self.num),
        }
        self._block(b, "Configuration.Projective Fluids", keys, solver)

    def _block(self, b: dict, label: str, keys: dict, solver: dict) -> None:
        for key, value in b.items():
            if key not in keys:
                self.ignore(label, key, value)
                continue
            group, name, conv = keys[key]
            solver.setdefault(group, {})[name] = conv(value, f"{label}.{key}")

    def materials(self, config: dict, out: dict) -> None:
        sim = out["simulation"]
        mats = self.list_of_objects("Materials")
        found: list[tuple[int | None, float | None, float | None, int | None]] = []
        # 2.0.0 layout: material values flat in Configuration
        if any(k in config for k in ("density0", "viscosity", "viscosityMethod")):
            found.append(self.material(config, "Configuration", None, inline=True))
        for i, mat in enumerate(mats):
            found.append(self.material(mat, "Materials", i))
        if not found:
            self.notes.append("no viscosity given: XSPH zeta stays at ipsph's default")
            return
        densities = {d for _, d, _, _ in found if d is not None}
        viscosities = {v for _, _, v, _ in found if v is not None}
        if len(densities) > 1 or len(viscosities) > 1:
            raise self.fail(
                "Materials", "several fluids with different density0 or viscosity (multiphase) are not supported"
            )
        if densities:
            sim["density0"] = densities.pop()
        standard = {m == 1 for _, _, v, m in found if v is not None}
        if len(standard) > 1:
            raise self.fail("Materials", "fluids with different viscosity methods are not supported")
        if viscosities:
            if standard.pop():  # SPlisHSPlasH's Standard viscosity: the same model, no XSPH on top
                sim["standard_viscosity"] = viscosities.pop()
                sim["viscosity"] = 0.0
            else:
                sim["viscosity"] = viscosities.pop()
        else:
            self.notes.append("no viscosity given: XSPH zeta stays at ipsph's default")

    def material(self, mat: dict, section: str, index: int | None, inline: bool = False):
        label = section if index is None else f"{section}[{index}]"
        density = None
        if "density0" in mat:
            density = self.num(mat["density0"], f"{label}.density0")
        vmethod = None
        if "viscosityMethod" in mat:
            vmethod = self.int_(mat["viscosityMethod"], f"{label}.viscosityMethod")
        visc = None
        if "viscosity" in mat:
            visc = self.num(mat["viscosity"], f"{label}.viscosity")
        for key, value in mat.items():
            if key in ("id", "density0", "viscosity", "viscosityMethod") or inline:
                continue
            from .emitters import MATERIAL_KEYS

            if key in MATERIAL_KEYS:  # the emitter box: [domain] (emitters.domain)
                continue
            if isinstance(value, dict) and "viscosity" in value and "viscosity" in key.lower():
                visc = self.num(value["viscosity"], f"{label}.{key}.viscosity")
                for sub in value:
                    if sub != "viscosity":
                        self.ignore(f"{section}.{key}", sub, index=index)
                continue
            self.ignore(section, key, value, index=index)
        if vmethod is not None and vmethod != 2:
            vname = _VISCOSITY_METHODS.get(vmethod, "unknown")
            if vmethod == 0:
                visc = 0.0
                self.notes.append(f"{label}.viscosityMethod=0 (None): XSPH viscosity zeta = 0")
            elif vmethod == 1:
                if visc is not None:
                    self.notes.append(
                        f"{label}.viscosityMethod=1 (Standard): "
                        f"simulation.standard_viscosity = {visc:g} m^2/s, XSPH off"
                    )
            elif visc is not None:
                self.notes.append(
                    f"{label}.viscosityMethod={vmethod} ({vname}) is not XSPH: "
                    f"its viscosity {visc:g} is used as the XSPH coefficient zeta"
                )
        elif vmethod is None and visc is not None:
            self.notes.append(f"{label}: no viscosityMethod; viscosity {visc:g} is used as the XSPH coefficient zeta")
        return index, density, visc, vmethod

    def dense_mode(self, item: dict, label: str) -> None:
        mode = self.int_(item.get("denseMode", 0), f"{label}.denseMode")
        if mode != 0:
            raise self.fail(
                f"{label}.denseMode", f"{mode} is not supported: ipsph samples the regular lattice only (denseMode 0)"
            )

    def fluid_block(self, i: int, b: dict) -> dict:
        label = f"FluidBlocks[{i}]"
        for key in ("start", "end"):
            if key not in b:
                raise self.fail(label, f"missing {key!r}")
        start = self.vec3(b["start"], f"{label}.start")
        end = self.vec3(b["end"], f"{label}.end")
        t = self.vec3(b.get("translation", [0, 0, 0]), f"{label}.translation")
        s = self.vec3(b.get("scale", [1, 1, 1]), f"{label}.scale")
        self.dense_mode(b, label)
        self.angular_velocity(b, label)
        for key, value in b.items():
            if key not in (
                "start",
                "end",
                "translation",
                "scale",
                "denseMode",
                "initialVelocity",
                "initialAngularVelocity",
                "id",
            ):
                self.ignore("FluidBlocks", key, value, index=i)
        # SPlisHSPlasH SceneLoader: corner' = scale * corner + translation, per component
        lo = [si * c + ti for si, c, ti in zip(s, start, t)]
        hi = [si * c + ti for si, c, ti in zip(s, end, t)]
        entry = {"name": f"block{i}", "box": {"min": lo, "max": hi}}
        if "initialVelocity" in b:
            entry["velocity"] = self.vec3(b["initialVelocity"], f"{label}.initialVelocity")
        return entry

    def angular_velocity(self, item: dict, label: str) -> None:
        if "initialAngularVelocity" in item and any(
            self.vec3(item["initialAngularVelocity"], f"{label}.initialAngularVelocity")
        ):
            raise self.fail(f"{label}.initialAngularVelocity", "is not supported")

    def transform(self, item: dict, label: str, entry: dict) -> None:
        if "translation" in item:
            entry["translate"] = self.vec3(item["translation"], f"{label}.translation")
        if "scale" in item:
            entry["scale"] = self.vec3(item["scale"], f"{label}.scale")
        angle = self.num(item.get("rotationAngle", 0.0), f"{label}.rotationAngle")
        if angle != 0.0:
            axis = self.vec3(item.get("rotationAxis", [1, 0, 0]), f"{label}.rotationAxis")
            entry["rotate_axis"] = axis
            entry["rotate_deg"] = math.degrees(angle)

    def fluid_model(self, i: int, m: dict) -> dict:
        label = f"FluidModels[{i}]"
        f = m.get("particleFile")
        if not isinstance(f, str) or not f:
            raise self.fail(f"{label}.particleFile", "missing: the mesh of the fluid body")
        if Path(f).suffix.lower() in (".bgeo", ".bhclassic", ".geo", ".ptc", ".pdb"):
            raise self.fail(
                f"{label}.particleFile",
                f"{f!r} is a partio particle file; ipsph samples fluid from closed meshes only (.obj, .ply, .stl)",
            )
        self.dense_mode(m, label)
        self.angular_velocity(m, label)
        if "invert" in m and self.bool_(m["invert"], f"{label}.invert"):
            raise self.fail(f"{label}.invert", "inverted fluid models are not supported")
        entry: dict = {"name": f"model{i}", "mesh": f}
        self.transform(m, label, entry)
        if "initialVelocity" in m:
            entry["velocity"] = self.vec3(m["initialVelocity"], f"{label}.initialVelocity")
        for key, value in m.items():
            if key not in (
                "particleFile",
                "translation",
                "scale",
                "rotationAxis",
                "rotationAngle",
                "initialVelocity",
                "initialAngularVelocity",
                "denseMode",
                "invert",
                "id",
            ):
                self.ignore("FluidModels", key, value, index=i)
        return entry

    def rigid_body(self, i: int, b: dict) -> dict:
        label = f"RigidBodies[{i}]"
        f = b.get("geometryFile")
        if not isinstance(f, str) or not f:
            raise self.fail(f"{label}.geometryFile", "missing: ipsph samples walls from their mesh")
        dynamic = "isDynamic" in b and self.bool_(b["isDynamic"], f"{label}.isDynamic")
        wall = self.bool_(b.get("isWall", False), f"{label}.isWall")
        invert = self.bool_(b.get("mapInvert", False), f"{label}.mapInvert")
        entry: dict = {"name": f"body{i}", "mesh": f, "role": "container" if wall or invert else "obstacle"}
        if dynamic:  # a two-way coupled rigid body (ipsph.boundary.rigid) of SPlisHSPlasH's density (default 1000)
            if wall or invert:
                raise self.fail(
                    f"{label}.isDynamic",
                    "a dynamic body cannot be a wall (isWall / mapInvert): it is an obstacle the fluid flows around",
                )
            density = b.get("density", SPH_BODY_DENSITY)
            if isinstance(density, bool) or not isinstance(density, (int, float)) or not density > 0:
                raise self.fail(f"{label}.density", f"{density!r}: a dynamic body needs a density > 0 (kg/m^3)")
            entry["density"] = float(density)
            if "density" not in b:
                self.notes.append(f"{label}: no density given, SPlisHSPlasH's default {SPH_BODY_DENSITY:g} kg/m^3 used")
        self.transform(b, label, entry)
        for key, value in b.items():
            if key not in (
                "geometryFile",
                "translation",
                "scale",
                "rotationAxis",
                "rotationAngle",
                "isDynamic",
                "isWall",
                "mapInvert",
                "density",
            ):
                self.ignore("RigidBodies", key, value, index=i)
        return entry

    def warning(self) -> tuple[str, ...]:
        parts = []
        if self.ignored:
            items = []
            for label, idx in self.ignored.items():
                if idx:
                    label = label.replace("[*]", "[" + ",".join(dict.fromkeys(idx)) + "]")
                items.append(label)
            parts.append("SPlisHSPlasH keys not supported, ignored: " + "; ".join(items))
        if self.notes:
            parts.append("notes: " + "; ".join(self.notes))
        if not parts:
            return ()
        return (f"{self.where}: " + ". ".join(parts),)
