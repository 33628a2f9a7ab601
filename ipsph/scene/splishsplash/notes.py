"""What the importer maps, and how: the section of docs/scene-reference.md generated from it."""

IMPORT_NOTES = """
## Importing SPlisHSPlasH scenes

`ipsph run scene.json` (or `load_scene("scene.json")`) reads a SPlisHSPlasH scene, in the
current layout (solver settings in `Configuration.DFSPH` / `Configuration."Projective Fluids"`,
viscosity in `Materials`) or the 2.0.0 layout (everything flat in `Configuration`). The scene is
converted to the TOML layout above first, then `--set` overrides are applied and the whole is
validated as a TOML scene, so override keys are ipsph's (`--set simulation.method=ipsph`).

| SPlisHSPlasH | ipsph |
|---|---|
| `particleRadius`, `gravitation` | `simulation.particle_radius`, `simulation.gravity` |
| `simulationMethod` 4 / 5 (default 4) | `simulation.method` dfsph / pf; any other value is refused |
| `stopAt` (if > 0) | `simulation.end_time`; otherwise 2.0 s |
| `timeStepSize` (default 0.001) | `time_step.dt_initial` |
| `cflFactor` (default 0.5), `cflMaxTimeStepSize` (default 0.005), `cflMinTimeStepSize` (default 1e-4) | `time_step.cfl_factor`, `dt_max`, `dt_min` |
| `cflMethod` 0 (fixed step) | `dt_min = dt_max = dt_initial = timeStepSize`; 2 is treated as 1 (warned) |
| `DFSPH`: `minIterations`, `maxIterations`, `maxError` (%), `maxIterationsV`, `maxErrorV` (%), `enableDivergenceSolver` | `solver.dfsph.density_min_iterations`, `density_max_iterations`, `density_error_pct`; `solver.divergence.max_iterations`, `error_pct`, `enabled` |
| `Projective Fluids`: `stiffness` | `solver.pf.stiffness` |
| `Projective Fluids`: `minIterations`, `maxIterations`, `maxError` (%) | `solver.ipsph.min_passes`, `max_passes`, `density_error_pct` (used when you switch the method to ipsph; plain PF runs `solver.pf.passes` = 3 fixed passes, as SPlisHSPlasH does) |
| 2.0.0 flat `maxIterations`, `maxError`, ... | as the block of the scene's method; `stiffness` -> `solver.pf.stiffness` |
| `Materials[].density0` | `simulation.density0` |
| `Materials[].viscosityMethod`: the model, by the numbers of the scene's release (below) | 0 None: no viscosity; 1 Standard, with its `viscosity`: `simulation.viscosity_model` = standard, `kinematic_viscosity_m2s` = nu (the same model); Weiler et al. 2018: implicit (next row); Takahashi et al. 2015 (its `viscosity` a kinematic nu too): implicit with free-slip walls (its operator has no wall term) and its `viscoMaxIter`, `viscoMaxError`; 2.0-2.11's 2 XSPH: `simulation.viscosity` (zeta) = its `viscosity`; Bender and Koschier 2017, Peer et al. 2015 and 2016 (a dimensionless factor on the velocity gradient): its `viscosity` as zeta (noted) |
| Weiler et al. 2018's `viscosity`, `viscosityBoundary`, `viscoMaxIter`, `viscoMaxError` (a fraction), flat in the material or in its `"Weiler et al. 2018"` block | `simulation.viscosity_model` = implicit, `kinematic_viscosity_m2s` = nu; `viscosity_walls` = no-slip if `viscosityBoundary` > 0 (with the fluid's nu: noted when it differs), else free-slip; `solver.viscosity.max_iterations`, `error_pct` = 100 x `viscoMaxError`; docs/method.md section 10 says where the models differ |
| `Materials[].xsph` (2.12-2.15) or `Materials[].XSPH.xsph` (since late 2025) | `simulation.viscosity` (XSPH zeta), beside any viscosity model; 0 when the scene gives none with a physical model (`xsphBoundary` is warned about) |

SPlisHSPlasH's `viscosityMethod` numbers moved in 2.12.0, when XSPH left the list of models:

| releases | layout | numbers |
|---|---|---|
| 2.0.0-2.11.0 | flat in the material (2.0.0: in `Configuration`) | 0 None, 1 Standard, 2 XSPH, 3 Bender and Koschier 2017, 4 Peer et al. 2015, 5 Peer et al. 2016, 6 Takahashi et al. 2015, 7 Weiler et al. 2018 |
| 2.12.0-2.15.0 | flat; XSPH its own filter (`xsph`, `xsphBoundary`) | 0 None, 1 Standard, 2 Bender and Koschier 2017, 3 Peer et al. 2015, 4 Peer et al. 2016, 5 Takahashi et al. 2015, 6 Weiler et al. 2018 |
| since late 2025 (pysplishsplash 2.19) | each model's keys in a block named after it (`"Standard viscosity"`, `"Weiler et al. 2018"`, `"XSPH"`) | as 2.12.0 |

The importer reads the numbers of the layout it finds: `Configuration` (2.0.0) and a flat 7 with
the old numbers; blocks or `xsph` keys with the new. A flat 2-6 alone could be either and is read
with the new numbers (every release since 2022), with a note saying what the old ones meant (6 was
Takahashi 2015, today's Weiler 2018; both run as the implicit model). With blocks, only the chosen model's block is read, as
SPlisHSPlasH does; a lone block whose model `viscosityMethod` does not name decides (noted).

| `dataExportFPS` | `output.fps` |
| `cameraPosition`, `cameraLookat` | `render.camera_position`, `render.focal_point` |
| `FluidBlocks[]`: `start`, `end`, `translation`, `scale`, `initialVelocity` | `[[fluid]] box` with min = scale * start + translation, max = scale * end + translation (as SPlisHSPlasH's scene loader), `velocity` |
| `FluidModels[]`: `particleFile` (a mesh), `translation`, `scale`, `rotationAxis`, `rotationAngle` (radians), `initialVelocity` | `[[fluid]] mesh`, `translate`, `scale`, `rotate_axis`, `rotate_deg`, `velocity` |
| `RigidBodies[]`: `geometryFile`, `translation`, `scale`, `rotationAxis`, `rotationAngle` (radians), `isWall`, `mapInvert` | `[[boundary]] mesh`, ..., `role` = container if `isWall` or `mapInvert`, else obstacle |
| `Emitters[]`: `type` 0 / 1, `width`, `height` (particles), `translation`, `rotationAxis`, `rotationAngle` (radians), `velocity`, `emitStartTime`, `emitEndTime` | `[[emitter]]` `shape` box / circle, `width` = width * 2r, `height` = height * 2r (circle: `radius` = width * r), `position`, `direction` and `height_axis` = the rotation's first and second columns, `velocity`, `start_time`, `end_time` (REAL_MAX: the run's end) |
| `emitterReuseParticles` with `emitterBoxMin`, `emitterBoxMax` (a material, or the 2.0.0 `Configuration`) | `[domain] min`, `max`: fluid leaving the box is removed (ipsph emits fresh particles with new ids instead of reusing them); `maxEmitterParticles` is not needed (the capacity is planned from the emitters) |
| `RigidBodies[]`: `isDynamic` = true, `density` (default 1000) | a dynamic rigid body: `[[boundary]] density`, role obstacle (ipsph.boundary.rigid; the mesh must be closed) |

Mesh paths are relative to the scene file, as in SPlisHSPlasH (`../models/UnitBox.obj`).

Refused (ConfigError): `simulationMethod` other than 4 or 5, `denseMode` other than 0,
`isDynamic` bodies that are walls (`isWall`, `mapInvert`) or have a density <= 0, `AnimationFields`, `sim2D`, partio particle files as fluid models,
`invert`ed fluid models, several materials with different density or viscosity.

Warned about, in one message (`Scene.warnings`): every other key, e.g.
`boundaryHandlingMethod` (every value maps to `simulation.boundary_model = "akinci-volume"`: Akinci
particles placed so that the fluid's volume meets the surface, what its volume and density maps aim at),
`numberOfStepsPerRenderUpdate`, `mapResolution`, `color`, `surfaceTension`, and a
`viscosityMethod` of Bender 2017 or Peer 2015/2016: its `viscosity` value is then used as the
XSPH coefficient, or dropped when the scene gives `xsph` too. The Standard model's wall friction
(`viscosityBoundary`, default 0) is not imported (warned if set). Where a key is absent,
SPlisHSPlasH's own default is used (listed in the table), except `end_time`, which defaults to
2.0 s.
"""
