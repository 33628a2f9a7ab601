"""The SPlisHSPlasH JSON -> ipsph dict converter (see the package docstring)."""

from __future__ import annotations

import json
from pathlib import Path

from ...errors import ConfigError, read_text
from .bodies import BodyReader
from .reader import Reader
from .viscosity import ViscosityReader

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
# SPlisHSPlasH 2.0.0's solver settings, flat in Configuration (later versions: per-method blocks)
_FLAT_SOLVER_KEYS = (
    "minIterations",
    "maxIterations",
    "maxError",
    "maxIterationsV",
    "maxErrorV",
    "enableDivergenceSolver",
    "stiffness",
)


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


class _Importer(Reader, BodyReader, ViscosityReader):
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
            *_FLAT_SOLVER_KEYS,
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
        flat = {k: c[k] for k in _FLAT_SOLVER_KEYS if k in c}
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
