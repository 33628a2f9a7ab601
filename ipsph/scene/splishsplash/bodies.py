"""The importer's bodies: FluidBlocks, FluidModels and RigidBodies -> [[fluid]] and [[boundary]]
entries (placement, dense mode, angular velocity); a mixin of `importer._Importer`."""

from __future__ import annotations

import math
from pathlib import Path

SPH_BODY_DENSITY = 1000.0  # SPlisHSPlasH's RigidBodies density when a dynamic body leaves it out


class BodyReader:
    """FluidBlocks, FluidModels, RigidBodies: the `Reader`'s typed reads, into entry dicts."""

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
