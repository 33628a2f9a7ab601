"""The SPlisHSPlasH JSON -> ipsph dict converter (see the package docstring)."""

from __future__ import annotations

import json
from pathlib import Path

from ...errors import ConfigError, read_text
from .bodies import BodyReader
from .reader import Reader

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
WEILER_2018 = 7  # _VISCOSITY_METHODS' number of "Weiler et al. 2018" (SPlisHSPlasH 2.x scenes number it 6)
_PHYSICAL = {1: "standard", WEILER_2018: "implicit"}  # viscosityMethod -> simulation.viscosity_model (else XSPH)
# a material's viscosity block named after its model: the name decides (the numbers moved between versions)
_VISCOSITY_BLOCKS = {"Standard viscosity": 1, "XSPH viscosity": 2, "Weiler et al. 2018": WEILER_2018}


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


class _Importer(Reader, BodyReader):
    def __init__(self, where: str, raw: dict):
        super().__init__(where, raw)
        self.viscous_solver: dict = {}  # [solver.viscosity] from a Weiler 2018 block
        self.viscous_walls: str | None = None  # simulation.viscosity_walls from its viscosityBoundary

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
        models = {_PHYSICAL.get(m, "xsph") for _, _, v, m in found if v is not None}
        if len(models) > 1:
            raise self.fail("Materials", "fluids with different viscosity methods are not supported")
        if viscosities:
            model = models.pop()
            if model != "xsph":  # Standard or Weiler 2018: nu in m^2/s, the same operator, no XSPH on top
                sim["viscosity_model"] = model
                sim["kinematic_viscosity_m2s"] = viscosities.pop()
                sim["viscosity"] = 0.0
                if self.viscous_solver:
                    out.setdefault("solver", {})["viscosity"] = self.viscous_solver
                if self.viscous_walls is not None:
                    sim["viscosity_walls"] = self.viscous_walls
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
            named = isinstance(value, dict) and (key in _VISCOSITY_BLOCKS or "viscosity" in key.lower())
            if named and "viscosity" in value:
                visc = self.num(value["viscosity"], f"{label}.{key}.viscosity")
                if _VISCOSITY_BLOCKS.get(key) == WEILER_2018:
                    vmethod = WEILER_2018  # SPlisHSPlasH 2.x numbers it 6, older versions 7
                    self.weiler_block(value, f"{label}.{key}", section, key, index)
                    continue
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
                        f"{label}.viscosityMethod=1 (Standard): simulation.viscosity_model = standard, "
                        f"kinematic_viscosity_m2s = {visc:g}, XSPH off"
                    )
            elif vmethod == WEILER_2018:
                if visc is not None:
                    self.notes.append(
                        f"{label}: Weiler et al. 2018: simulation.viscosity_model = implicit, "
                        f"kinematic_viscosity_m2s = {visc:g}, XSPH off (the same operator and backward-Euler "
                        "solve; ours uses Jacobi-preconditioned CG, the fluid's nu at no-slip walls, and "
                        "its own wall particles: docs/method.md section 10)"
                    )
            elif visc is not None:
                self.notes.append(
                    f"{label}.viscosityMethod={vmethod} ({vname}) is not XSPH: "
                    f"its viscosity {visc:g} is used as the XSPH coefficient zeta"
                )
        elif vmethod is None and visc is not None:
            self.notes.append(f"{label}: no viscosityMethod; viscosity {visc:g} is used as the XSPH coefficient zeta")
        return index, density, visc, vmethod

    def weiler_block(self, b: dict, label: str, section: str, key: str, index: int | None) -> None:
        """The "Weiler et al. 2018" block's solver settings -> [solver.viscosity], its wall
        coefficient -> simulation.viscosity_walls (no-slip with the fluid's nu, or free-slip at 0)."""
        for sub, value in b.items():
            if sub == "viscosity":
                continue
            if sub == "viscoMaxIter":
                self.viscous_solver["max_iterations"] = self.int_(value, f"{label}.{sub}")
            elif sub == "viscoMaxError":  # a relative residual: 0.01 is 1 %
                self.viscous_solver["error_pct"] = 100.0 * self.num(value, f"{label}.{sub}")
            elif sub == "viscosityBoundary":
                nu_b = self.num(value, f"{label}.{sub}")
                self.viscous_walls = "no-slip" if nu_b > 0.0 else "free-slip"
                fluid = b.get("viscosity")
                if nu_b > 0.0 and nu_b != fluid:
                    self.notes.append(
                        f"{label}.viscosityBoundary = {nu_b:g}: walls are no-slip with the fluid's nu "
                        f"({fluid:g}); ipsph has no separate wall viscosity"
                    )
            else:
                self.ignore(f"{section}.{key}", sub, index=index)

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
