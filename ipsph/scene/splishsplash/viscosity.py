"""The importer's materials: density0, the viscosity model and the XSPH filter -> simulation.density0,
viscosity_model, kinematic_viscosity_m2s, viscosity (XSPH zeta), viscosity_walls and
[solver.viscosity]; a mixin of `importer._Importer`.

SPlisHSPlasH has written a material's viscosity three ways, and its viscosityMethod numbers moved:

| releases | layout | numbers |
|---|---|---|
| 2.0.0 - 2.11.0 | flat in the material (2.0.0: in Configuration) | 0 None, 1 Standard, 2 XSPH, 3 Bender and Koschier 2017, 4 Peer et al. 2015, 5 Peer et al. 2016, 6 Takahashi et al. 2015, 7 Weiler et al. 2018 |
| 2.12.0 - 2.15.0 | flat; XSPH is a filter of its own (`xsph`, `xsphBoundary`) | 0 None, 1 Standard, 2 Bender and Koschier 2017, ..., 5 Takahashi et al. 2015, 6 Weiler et al. 2018 |
| since late 2025 | each model's keys in a block named after it ("Weiler et al. 2018", "XSPH") | as 2.12.0 |

A flat material with 7, or in Configuration, is read with the old numbers; one with blocks or with
`xsph` keys with the new; a flat 2 to 6 alone could be either and is read as 2.12.0 on (every release
since 2022), with a note naming what the old numbers would have meant.
"""

from __future__ import annotations

from .emitters import MATERIAL_KEYS

_UP_TO_2_11 = (
    "None",
    "Standard",
    "XSPH",
    "Bender and Koschier 2017",
    "Peer et al. 2015",
    "Peer et al. 2016",
    "Takahashi et al. 2015 (improved)",
    "Weiler et al. 2018",
)
_FROM_2_12 = tuple(m for m in _UP_TO_2_11 if m != "XSPH")
WEILER = "Weiler et al. 2018"
TAKAHASHI = "Takahashi et al. 2015 (improved)"  # a kinematic nu too (stress rho0 nu (grad v + grad v^T))
# model -> simulation.viscosity_model; the others (Bender 2017, Peer 2015/2016) scale the velocity
# gradient by a dimensionless factor and fall back to XSPH with it
_PHYSICAL = {"Standard": "standard", WEILER: "implicit", TAKAHASHI: "implicit"}
# a model's block, by the name SPlisHSPlasH gives it (METHOD_NAME), -> the model
_BLOCKS = {"Standard viscosity": "Standard"} | {m: m for m in _FROM_2_12[2:]}
XSPH_BLOCK = "XSPH"  # the XSPH filter's block: xsph, xsphBoundary
_XSPH_KEYS = ("xsph", "xsphBoundary")
_WEILER_KEYS = (
    "viscosityBoundary",
    "viscoMaxIter",
    "viscoMaxError",
)  # Weiler 2018's settings (Takahashi: the last two)


class ViscosityReader:
    """Materials (and the 2.0.0 Configuration's material keys): the `Reader`'s typed reads."""

    viscous_solver: dict  # [solver.viscosity] from Weiler 2018's settings
    viscous_walls: str | None  # simulation.viscosity_walls from its viscosityBoundary

    def materials(self, config: dict, out: dict) -> None:
        sim = out["simulation"]
        self.viscous_solver, self.viscous_walls = {}, None
        found: list[tuple[float | None, str, float | None, float | None]] = []
        if any(k in config for k in ("density0", "viscosity", "viscosityMethod")):  # 2.0.0: flat in Configuration
            found.append(self.material(config, "Configuration", None, inline=True))
        for i, mat in enumerate(self.list_of_objects("Materials")):
            found.append(self.material(mat, "Materials", i))
        densities = {d for d, _, _, _ in found if d is not None}
        given = [(model, nu, zeta) for _, model, nu, zeta in found if nu is not None or zeta is not None]
        if len(densities) > 1 or len({(nu, zeta) for _, nu, zeta in given}) > 1:
            raise self.fail(
                "Materials", "several fluids with different density0 or viscosity (multiphase) are not supported"
            )
        if densities:
            sim["density0"] = densities.pop()
        if len({model for model, _, _ in given}) > 1:
            raise self.fail("Materials", "fluids with different viscosity methods are not supported")
        if not given:
            self.notes.append("no viscosity given: XSPH zeta stays at ipsph's default")
            return
        model, nu, zeta = given[0]
        if model != "xsph":  # Standard or Weiler 2018: nu in m^2/s; XSPH only if the scene filters too
            sim["viscosity_model"] = model
            sim["kinematic_viscosity_m2s"] = nu if nu is not None else 0.0
            if self.viscous_solver:
                out.setdefault("solver", {})["viscosity"] = self.viscous_solver
            if self.viscous_walls is not None:
                sim["viscosity_walls"] = self.viscous_walls
        sim["viscosity"] = zeta if zeta is not None else 0.0

    def material(self, mat: dict, section: str, index: int | None, inline: bool = False):
        """One material -> (density0, ipsph's viscosity_model, nu, XSPH zeta); None where not given."""
        label = section if index is None else f"{section}[{index}]"
        density = self.num(mat["density0"], f"{label}.density0") if "density0" in mat else None
        number = self.int_(mat["viscosityMethod"], f"{label}.viscosityMethod") if "viscosityMethod" in mat else None
        blocks = {k: v for k, v in mat.items() if k in _BLOCKS and isinstance(v, dict)}
        xsph_block = mat.get(XSPH_BLOCK) if isinstance(mat.get(XSPH_BLOCK), dict) else None
        flat_xsph = any(k in mat for k in _XSPH_KEYS)
        for key in mat:
            if inline or key in ("id", "density0", "viscosity", "viscosityMethod", *_WEILER_KEYS, *_XSPH_KEYS):
                continue
            if key in MATERIAL_KEYS or key in blocks or (key == XSPH_BLOCK and xsph_block is not None):
                continue  # MATERIAL_KEYS: the emitter box, [domain] (emitters.domain)
            self.ignore(section, key, mat[key], index=index)

        # which numbers the scene was written with (the module docstring's table)
        new = not inline and (bool(blocks) or xsph_block is not None or flat_xsph or number != 7)
        table = _FROM_2_12 if new else _UP_TO_2_11
        model = table[number] if number is not None and 0 <= number < len(table) else None
        if number is not None and model is None:
            self.notes.append(f"{label}.viscosityMethod={number} names no SPlisHSPlasH viscosity model")
        if len(blocks) == 1 and model != _BLOCKS[next(iter(blocks))]:
            (key,) = blocks
            if number is not None:
                self.notes.append(f"{label}.viscosityMethod={number} ({model}) has no block; its {key!r} block decides")
            model = _BLOCKS[key]
        elif new and not blocks and not flat_xsph and number is not None and 2 <= number <= 6 and not inline:
            self.notes.append(
                f"{label}.viscosityMethod={number} read as {model} (SPlisHSPlasH 2.12 and later; "
                f"in 2.0-2.11 scenes {number} was {_UP_TO_2_11[number]})"
            )

        # the model's own settings: its block, or flat in the material before the blocks
        block_key = next((k for k in blocks if _BLOCKS[k] == model), None)
        for key in blocks:
            if key != block_key:
                self.ignore(section, key, index=index)  # another model's block: SPlisHSPlasH reads only its own
        flat = ("viscosity",) if inline else ("viscosity", *_WEILER_KEYS)  # 2.0.0: the rest is Configuration's
        settings = blocks[block_key] if block_key else {k: mat[k] for k in flat if k in mat}
        prefix = f"{block_key}." if block_key else ""  # a block's keys are named inside it
        where = f"{label}.{block_key}" if block_key else label
        visc = self.num(settings["viscosity"], f"{where}.viscosity") if "viscosity" in settings else None
        if block_key and "viscosity" in mat:
            self.ignore(section, "viscosity", index=index)  # flat beside the blocks: SPlisHSPlasH reads the block
        if model in (WEILER, TAKAHASHI):
            self.implicit_settings(settings, model, where, section, prefix, index)
        else:
            for key in settings:
                if key != "viscosity":
                    self.ignore(section, prefix + key, index=index)

        # the XSPH filter (2.12.0 on): flat keys or its block
        xsph = xsph_block if xsph_block is not None else {k: mat[k] for k in _XSPH_KEYS if k in mat and not inline}
        xprefix = f"{XSPH_BLOCK}." if xsph_block is not None else ""
        zeta = self.num(xsph["xsph"], f"{label}.{xprefix}xsph") if "xsph" in xsph else None
        for key in xsph:
            if key != "xsph":
                self.ignore(section, xprefix + key, index=index)
        return density, *self._mapped(label, model, visc, zeta)

    def _mapped(self, label: str, model: str | None, visc: float | None, zeta: float | None):
        """(ipsph's viscosity_model, nu, zeta) for a material's model and values, with its note."""
        physical = _PHYSICAL.get(model)
        if physical is not None:
            if visc is not None:
                xsph = f"XSPH zeta = {zeta:g}" if zeta is not None else "XSPH off"
                if model == WEILER:
                    self.notes.append(
                        f"{label}: Weiler et al. 2018: simulation.viscosity_model = implicit, "
                        f"kinematic_viscosity_m2s = {visc:g}, {xsph} (the same operator and backward-Euler "
                        "solve; ours uses Jacobi-preconditioned CG, the fluid's nu at no-slip walls, and "
                        "its own wall particles: docs/method.md section 10)"
                    )
                elif model == TAKAHASHI:
                    self.notes.append(
                        f"{label}: Takahashi et al. 2015 (improved): simulation.viscosity_model = implicit, "
                        f"kinematic_viscosity_m2s = {visc:g}, {xsph}, free-slip walls (its nu; ipsph solves "
                        "Weiler et al. 2018's operator backward-Euler, not Takahashi's: docs/method.md section 10)"
                    )
                else:
                    self.notes.append(
                        f"{label}.viscosityMethod=1 (Standard): simulation.viscosity_model = standard, "
                        f"kinematic_viscosity_m2s = {visc:g}, {xsph}"
                    )
            return physical, visc, zeta
        if model == "None":
            self.notes.append(f"{label}.viscosityMethod=0 (None): no viscosity, XSPH zeta = {zeta or 0.0:g}")
            return "xsph", None, zeta if zeta is not None else 0.0
        if model == "XSPH" or zeta is not None:  # the 2.0-2.11 XSPH model, or the 2.12+ filter
            if model not in (None, "XSPH") and visc is not None:
                self.notes.append(f"{label}: {model} is not supported: its viscosity {visc:g} is dropped")
            return "xsph", None, zeta if zeta is not None else visc
        if visc is not None:
            what = f"{model} is not XSPH" if model is not None else "no viscosityMethod"
            self.notes.append(f"{label}: {what}: its viscosity {visc:g} is used as the XSPH coefficient zeta")
        return "xsph", None, visc

    def implicit_settings(self, b: dict, model: str, label: str, section: str, prefix: str, index) -> None:
        """Weiler 2018's or Takahashi 2015's solver settings -> [solver.viscosity]; Weiler's wall
        coefficient -> simulation.viscosity_walls (no-slip with the fluid's nu, or free-slip at 0);
        Takahashi's operator has no wall term: free-slip."""
        if model == TAKAHASHI:
            self.viscous_walls = "free-slip"
        for sub, value in b.items():
            if sub == "viscosity":
                continue
            if sub == "viscoMaxIter":
                self.viscous_solver["max_iterations"] = self.int_(value, f"{label}.{sub}")
            elif sub == "viscoMaxError":  # a relative residual: 0.01 is 1 %
                self.viscous_solver["error_pct"] = 100.0 * self.num(value, f"{label}.{sub}")
            elif sub == "viscosityBoundary" and model == WEILER:
                nu_b = self.num(value, f"{label}.{sub}")
                self.viscous_walls = "no-slip" if nu_b > 0.0 else "free-slip"
                fluid = b.get("viscosity")
                if nu_b > 0.0 and nu_b != fluid:
                    fluid_nu = "" if fluid is None else f" ({fluid:g})"
                    self.notes.append(
                        f"{label}.viscosityBoundary = {nu_b:g}: walls are no-slip with the fluid's nu"
                        f"{fluid_nu}; ipsph has no separate wall viscosity"
                    )
            else:
                self.ignore(section, prefix + sub, index=index)
