"""SPlisHSPlasH JSON scenes: the 7 stock scenes import with the right lattices, methods and
solver settings; unsupported keys are warned about, unsupported physics refused."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from ipsph.config import Method, Role, Transform
from ipsph.errors import ConfigError
from ipsph.scene import load_scene, scene_from_dict, scene_to_dict

# SPlisHSPlasH's stock scenes, copied into the repository (tests/data/splishsplash/PROVENANCE.md)
ANCHORS = Path(__file__).resolve().parent / "data" / "splishsplash"

# Fluid particle counts SPlisHSPlasH itself creates for the stock scenes (method.md section 6).
STOCK = {
    "Scenes/DamBreakModel.json": ("dfsph", 6_859),
    "Scenes/DoubleDamBreak.json": ("dfsph", 4_732),
    "Scenes/DamBreakModelDragons.json": ("dfsph", 14_079),
    "Scenes/CompressibleSPH_PF.json": ("pf", 6_750),
    "Scenes_v2.0.0/DamBreakModel.json": ("dfsph", 6_859),
    "Scenes_v2.0.0/DoubleDamBreak.json": ("dfsph", 4_732),
    "Scenes_v2.0.0/DamBreakModelDragons.json": ("dfsph", 14_079),
}


def c_round(x: float) -> int:
    """C's round(): halves away from zero (SPlisHSPlasH), unlike Python's round()."""
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def lattice(f, r: float) -> int:
    """FluidBlocks rule, SimulatorBase::createFluidBlocks: prod(round((max - min) / 2r) - 1)."""
    return math.prod(c_round((hi - lo) / (2 * r)) - 1 for lo, hi in zip(f.box_min, f.box_max))


@pytest.mark.parametrize("rel", sorted(STOCK))
def test_stock_scenes_import(rel):
    method, count = STOCK[rel]
    s = load_scene(ANCHORS / rel)
    assert s.method == Method(method)
    assert s.particle_radius == 0.025 and s.density0 == 1000.0
    assert s.gravity == (0.0, -9.81, 0.0)
    assert all(f.shape == "box" and f.transform == Transform() for f in s.fluids)
    assert sum(lattice(f, s.particle_radius) for f in s.fluids) == count
    assert s.time_step.dt_max == 0.005 and s.time_step.dt_min == 1e-4  # SPlisHSPlasH's bounds
    assert s.end_time == 2.0  # no stopAt in the stock scenes
    unit_box = (ANCHORS / "models" / "UnitBox.obj").resolve()
    assert s.boundaries[0].mesh == unit_box and s.boundaries[0].role == Role.CONTAINER
    assert len(s.warnings) == 1 and "\n" not in s.warnings[0]
    # the imported scene survives the dict form (what run.json records and --set edits)
    assert scene_from_dict(scene_to_dict(s)) == s


def test_current_layout_solver_blocks_are_mapped():
    s = load_scene(ANCHORS / "Scenes/DamBreakModel.json")
    sv = s.solver
    assert sv.dfsph.density_error_pct == 0.05  # the stock 0.05 %, not ipsph's 0.01 % default
    assert (sv.dfsph.density_min_iterations, sv.dfsph.density_max_iterations) == (2, 100)
    assert (sv.divergence.error_pct, sv.divergence.max_iterations) == (0.1, 100)
    assert sv.divergence.enabled is True
    assert s.time_step.dt_initial == 0.005 and s.time_step.cfl_factor == 1.0
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("standard", 0.01, 0.0)  # its model, no XSPH
    w = s.warnings[0]
    assert "numberOfStepsPerRenderUpdate" in w and "particleAttributes" in w
    assert "boundaryHandlingMethod=2 (every value maps to simulation.boundary_model = akinci-volume" in w
    assert "mapResolution" in w and "RigidBodies[0].color" in w
    assert "viscosityMethod=1 (Standard): simulation.viscosity_model = standard, kinematic_viscosity_m2s = 0.01" in w


def test_fluid_block_translation_and_scale():
    # DamBreakModelDragons: start [-0.5, 0, -0.5], end [0.5, 1, 0.5], translation [-2.45, 0, 0],
    # scale [1, 2, 1] -> corner' = scale * corner + translation (SPlisHSPlasH SceneLoader)
    s = load_scene(ANCHORS / "Scenes/DamBreakModelDragons.json")
    f = s.fluids[0]
    assert f.box_min == pytest.approx((-2.95, 0.0, -0.5), abs=1e-12)
    assert f.box_max == pytest.approx((-1.95, 2.0, 0.5), abs=1e-12)
    box, dragon1, dragon2 = s.boundaries
    assert box.transform == Transform(translate=(0.0, 2.0, 0.0), scale=(6.0, 4.0, 3.0))
    assert dragon1.role == dragon2.role == Role.OBSTACLE
    assert dragon1.mesh == (ANCHORS / "models" / "Dragon_50k.obj").resolve()
    assert dragon2.transform.translate == (1.5, 0.0, 0.75)


def test_pf_scene_maps_the_projective_fluids_block_and_velocities():
    s = load_scene(ANCHORS / "Scenes/CompressibleSPH_PF.json")
    assert s.solver.pf.stiffness == 25_000.0
    assert (s.solver.ipsph.min_passes, s.solver.ipsph.max_passes) == (2, 100)
    assert s.solver.ipsph.density_error_pct == 0.05
    assert [f.velocity for f in s.fluids] == [(5.0, 0.0, 0.0), (-5.0, 0.0, 0.0)]
    assert s.render.camera_position == (0.0, 2.0, 5.0) and s.render.focal_point == (0.0, 0.0, 0.0)
    assert s.time_step.dt_initial == 0.001  # no timeStepSize: SPlisHSPlasH's default


def test_v200_flat_layout():
    s = load_scene(ANCHORS / "Scenes_v2.0.0/DamBreakModel.json")
    assert s.solver.dfsph.density_error_pct == 0.01 and s.solver.divergence.error_pct == 0.1
    assert s.solver.pf.stiffness == 50_000.0
    assert s.viscosity == 0.03 and s.time_step.cfl_factor == 0.5
    assert s.time_step.dt_initial == 0.001
    w = s.warnings[0]
    assert "surfaceTension" in w and "exponent" in w and "velocityUpdateMethod" in w
    assert "not XSPH" not in w  # viscosityMethod 2 is XSPH: mapped exactly
    bare = load_scene(ANCHORS / "Scenes_v2.0.0/DoubleDamBreak.json")
    assert bare.time_step.cfl_factor == 0.5  # SPlisHSPlasH's default when absent
    assert bare.method == Method.DFSPH and "no viscosity given" in bare.warnings[0]


def test_overrides_apply_to_imported_scenes():
    s = load_scene(
        ANCHORS / "Scenes/DamBreakModel.json",
        ["simulation.method=ipsph", "fluid.0.velocity=[1, 0, 0]", "simulation.end_time=1.0"],
    )
    assert s.method == Method.IPSPH and s.fluids[0].velocity == (1.0, 0.0, 0.0)
    assert s.end_time == 1.0 and s.solver.dfsph.density_error_pct == 0.05
    assert s.warnings and "boundaryHandlingMethod" in s.warnings[0]


# -- synthetic scenes ----------------------------------------------------------------------------


def scene_file(tmp_path: Path, data: dict, name: str = "s.json") -> Path:
    (tmp_path / "box.obj").write_text("v 0 0 0\n")  # the scene layer only checks existence
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


BLOCK = {"start": [0, 0, 0], "end": [0.5, 0.5, 0.5]}


def test_json_syntax_error_has_line_and_column(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{\n  "Configuration": {\n    "particleRadius": 0.025,\n  }\n}\n')
    with pytest.raises(ConfigError, match=rf"{re.escape(str(p))}:4:3: JSON syntax error"):
        load_scene(p)


@pytest.mark.parametrize(
    "data, fragment",
    [
        (
            {"Configuration": {"simulationMethod": 2}, "FluidBlocks": [BLOCK]},
            "Configuration.simulationMethod: 2 (PBF) is not supported",
        ),
        ({"FluidBlocks": [{**BLOCK, "denseMode": 1}]}, "FluidBlocks[0].denseMode: 1 is not supported"),
        (
            {"FluidBlocks": [BLOCK], "RigidBodies": [{"geometryFile": "box.obj", "isDynamic": True, "isWall": True}]},
            "RigidBodies[0].isDynamic: a dynamic body cannot be a wall",
        ),
        (
            {"FluidBlocks": [BLOCK], "RigidBodies": [{"geometryFile": "box.obj", "isDynamic": True, "density": 0}]},
            "RigidBodies[0].density: 0: a dynamic body needs a density > 0",
        ),
        ({"FluidBlocks": [BLOCK], "Emitters": [{"type": 2}]}, "Emitters[0].type: 2 is not an emitter type"),
        ({"FluidModels": [{"particleFile": "bunny.bgeo"}]}, "is a partio particle file"),
        (
            {"Configuration": {"particleRadius": "small"}, "FluidBlocks": [BLOCK]},
            "Configuration.particleRadius: expected a number",
        ),
        (
            {"FluidBlocks": [BLOCK], "Materials": [{"id": "A", "density0": 1000}, {"id": "B", "density0": 500}]},
            "multiphase",
        ),
        ({"Configuration": {"particleRadius": 0.025}}, "no FluidBlocks, FluidModels or Emitters"),
    ],
)
def test_unsupported_physics_is_refused(tmp_path, data, fragment):
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        load_scene(scene_file(tmp_path, data))


def test_fluid_models_rigid_bodies_and_fixed_step(tmp_path):
    data = {
        "Configuration": {
            "particleRadius": 0.02,
            "simulationMethod": 5,
            "cflMethod": 0,
            "timeStepSize": 0.002,
            "stopAt": 3.5,
            "dataExportFPS": 50,
            "kernel": 1,
        },
        "Materials": [{"id": "Fluid", "viscosityMethod": 0, "viscosity": 0.5}],
        "FluidModels": [
            {
                "particleFile": "box.obj",
                "translation": [1, 2, 3],
                "scale": 0.5,
                "rotationAxis": [0, 1, 0],
                "rotationAngle": math.pi,
                "initialVelocity": [0, -1, 0],
                "resolutionSDF": [20, 20, 20],
            }
        ],
        "RigidBodies": [{"geometryFile": "box.obj", "isWall": False, "mapInvert": True}, {"geometryFile": "box.obj"}],
    }
    s = load_scene(scene_file(tmp_path, data))
    assert s.method == Method.PF and s.end_time == 3.5 and s.output.fps == 50.0
    ts = s.time_step
    assert ts.dt_min == ts.dt_max == ts.dt_initial == 0.002  # cflMethod 0: a fixed step
    assert s.viscosity == 0.0  # viscosityMethod 0 (None)
    f = s.fluids[0]
    assert f.shape == "mesh" and f.mesh == (tmp_path / "box.obj").resolve()
    assert f.transform.scale == (0.5, 0.5, 0.5) and f.transform.translate == (1.0, 2.0, 3.0)
    assert f.transform.rotate_deg == pytest.approx(180.0, abs=1e-12)
    assert f.velocity == (0.0, -1.0, 0.0)
    assert [b.role for b in s.boundaries] == [Role.CONTAINER, Role.OBSTACLE]
    w = s.warnings[0]
    assert "Configuration.kernel (ipsph uses the cubic spline)" in w
    assert "FluidModels[0].resolutionSDF" in w and "cflMethod=0 (fixed step)" in w
    assert "viscosityMethod=0 (None)" in w


def test_missing_rigid_body_mesh_shows_both_paths(tmp_path):
    data = {"FluidBlocks": [BLOCK], "RigidBodies": [{"geometryFile": "../models/Nope.obj"}]}
    with pytest.raises(ConfigError) as e:
        load_scene(scene_file(tmp_path, data))
    msg = str(e.value)
    assert "boundary[0].mesh: mesh file not found: '../models/Nope.obj'" in msg
    assert str((tmp_path.parent / "models" / "Nope.obj").resolve()) in msg


def test_standard_viscosity_is_imported_as_the_same_model(tmp_path):
    data = {
        "FluidBlocks": [BLOCK],
        "Materials": [
            {"id": "Fluid", "viscosityMethod": 1, "Standard viscosity": {"viscosity": 0.02, "viscosityBoundary": 0.5}}
        ],
    }
    s = load_scene(scene_file(tmp_path, data))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("standard", 0.02, 0.0)
    w = s.warnings[0]
    assert "viscosityBoundary" in w  # the model's wall friction is not imported: said, not dropped
    assert "kinematic_viscosity_m2s = 0.02, XSPH off" in w
    # another non-XSPH model keeps the documented fallback (its value as XSPH zeta)
    data["Materials"] = [{"id": "Fluid", "viscosityMethod": 3, "viscosity": 0.02}]
    s = load_scene(scene_file(tmp_path, data, "b.json"))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("xsph", 0.0, 0.02)


CLOSED_CUBE = "".join(f"v {x} {y} {z}\n" for z in (0, 1) for y in (0, 1) for x in (0, 1)) + "".join(
    f"f {a + 1} {b + 1} {c + 1}\n"
    for q in ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
    for a, b, c in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))
)


def test_dynamic_rigid_body_is_imported_with_its_density(tmp_path):
    """isDynamic bodies become two-way coupled rigid bodies (issue 19) of the scene's density, or
    SPlisHSPlasH's default 1000 kg/m^3 with a note; the mesh is the body's closed surface."""
    data = {
        "FluidBlocks": [BLOCK],
        "RigidBodies": [
            {"geometryFile": "box.obj", "isDynamic": True, "density": 400},
            {"geometryFile": "box.obj", "isDynamic": True, "translation": [2, 0, 0]},
            {"geometryFile": "box.obj", "isWall": True, "scale": [4, 4, 4]},
        ],
    }
    path = scene_file(tmp_path, data)
    (tmp_path / "box.obj").write_text(CLOSED_CUBE)  # a dynamic body's mesh is checked closed
    s = load_scene(path)
    light, default, tank = s.boundaries
    assert light.dynamic and light.density == 400.0 and light.role == Role.OBSTACLE
    assert default.dynamic and default.density == 1000.0
    assert not tank.dynamic and not tank.moving
    assert "no density given, SPlisHSPlasH's default 1000 kg/m^3 used" in s.warnings[0]


@pytest.mark.parametrize("number", [6, 7])  # SPlisHSPlasH 2.x numbers Weiler 2018 6, older versions 7
def test_weiler_2018_viscosity_is_imported_as_the_implicit_model(tmp_path, number):
    """SPlisHSPlasH's CoilingModel_Weiler2018 material: nu in m^2/s, its solver settings, its walls."""
    weiler = {"viscosity": 5, "viscosityBoundary": 4, "viscoMaxIter": 200, "viscoMaxError": 0.05}
    data = {
        "FluidBlocks": [BLOCK],
        "Materials": [{"id": "Fluid", "viscosityMethod": number, "Weiler et al. 2018": weiler}],
    }
    s = load_scene(scene_file(tmp_path, data))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("implicit", 5.0, 0.0)
    assert (s.viscosity_walls, s.solver.viscosity.max_iterations, s.solver.viscosity.error_pct) == ("no-slip", 200, 5.0)
    w = s.warnings[0]
    assert "viscosityBoundary = 4" in w and "no separate wall viscosity" in w  # where the models differ: said
    weiler["viscosityBoundary"] = 0  # no wall friction: free-slip
    s = load_scene(scene_file(tmp_path, data, "b.json"))
    assert s.viscosity_walls == "free-slip"


# SPlisHSPlasH's viscosityMethod numbers by release (ipsph/scene/splishsplash/viscosity.py's table):
# 2.12.0 took XSPH out of the list, so Weiler 2018 went from 7 to 6 and Takahashi 2015 from 6 to 5.
def test_a_2_12_flat_material_numbers_weiler_2018_six(tmp_path):
    """The thick slump of issue 42: a 2.12-2.15 scene (flat keys) with viscosityMethod 6 and
    nu = 1 m^2/s is Weiler 2018, not an XSPH filter of strength 1 (the old numbers' Takahashi 2015,
    whose fallback took the viscosity's effect away)."""
    weiler = {"viscosity": 1.0, "viscosityBoundary": 1.0, "viscoMaxIter": 100, "viscoMaxError": 0.01}
    data = {"FluidBlocks": [BLOCK], "Materials": [{"id": "Fluid", "viscosityMethod": 6, **weiler}]}
    s = load_scene(scene_file(tmp_path, data))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("implicit", 1.0, 0.0)
    # the flat settings are Weiler 2018's: mapped, not ignored
    assert (s.viscosity_walls, s.solver.viscosity.max_iterations, s.solver.viscosity.error_pct) == ("no-slip", 100, 1.0)
    w = s.warnings[0]
    assert "ignored" not in w
    assert "viscosityMethod=6 read as Weiler et al. 2018" in w and "6 was Takahashi" in w  # the assumption, said


def test_a_2_11_flat_material_numbers_weiler_2018_seven(tmp_path):
    weiler = {"viscosity": 5.0, "viscosityBoundary": 0.0, "viscoMaxIter": 200, "viscoMaxError": 0.05}
    data = {"FluidBlocks": [BLOCK], "Materials": [{"id": "Fluid", "viscosityMethod": 7, **weiler}]}
    s = load_scene(scene_file(tmp_path, data))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("implicit", 5.0, 0.0)
    assert (s.viscosity_walls, s.solver.viscosity.max_iterations, s.solver.viscosity.error_pct) == (
        "free-slip",
        200,
        5.0,
    )
    assert "read as" not in s.warnings[0]  # 7 exists only in the old numbers: nothing assumed


def test_the_xsph_filter_is_imported_beside_a_viscosity_model(tmp_path):
    """2.12.0 on: XSPH is a filter of its own (flat xsph, or its "XSPH" block since late 2025), which
    applies on top of any viscosity model; its presence also dates the numbers (2 is Bender 2017)."""
    data = {
        "FluidBlocks": [BLOCK],
        "Materials": [{"id": "Fluid", "viscosityMethod": 1, "viscosity": 0.01, "xsph": 0.05}],
    }
    s = load_scene(scene_file(tmp_path, data))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity) == ("standard", 0.01, 0.05)
    nested = {"id": "Fluid", "viscosityMethod": 0, "XSPH": {"xsph": 0.03, "xsphBoundary": 0.1}}
    s = load_scene(scene_file(tmp_path, {"FluidBlocks": [BLOCK], "Materials": [nested]}, "b.json"))
    assert (s.viscosity_model, s.viscosity) == ("xsph", 0.03)
    assert "Materials[0].XSPH.xsphBoundary" in s.warnings[0]  # no XSPH at walls in ipsph: said, not dropped
    data["Materials"][0] = {"id": "Fluid", "viscosityMethod": 2, "viscosity": 0.02, "xsph": 0.01}
    s = load_scene(scene_file(tmp_path, data, "c.json"))
    assert s.viscosity == 0.01 and "Bender and Koschier 2017 is not supported" in s.warnings[0]


def test_only_the_chosen_models_block_is_read(tmp_path):
    """Late-2025 layout: each model's keys in a block named after it; SPlisHSPlasH reads the block of
    the model viscosityMethod picks, so another model's block is ignored (and said), never mixed in."""
    mat = {
        "id": "Fluid",
        "viscosityMethod": 6,
        "Standard viscosity": {"viscosity": 0.01},
        "Weiler et al. 2018": {"viscosity": 2.0, "viscoMaxIter": 150},
    }
    s = load_scene(scene_file(tmp_path, {"FluidBlocks": [BLOCK], "Materials": [mat]}))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.solver.viscosity.max_iterations) == ("implicit", 2.0, 150)
    assert "Materials[0].Standard viscosity" in s.warnings[0] and "read as" not in s.warnings[0]


def test_takahashi_2015_is_a_kinematic_viscosity(tmp_path):
    """Takahashi 2015's viscosity is a kinematic nu (its stress is rho0 nu (grad v + grad v^T)): the
    implicit model with its solver settings and free-slip walls (its operator has no wall term), not
    an XSPH filter of strength nu. Bender 2017 and Peer 2015/2016 scale the velocity gradient by a
    dimensionless factor: those keep the XSPH fallback."""
    mat = {
        "id": "Fluid",
        "viscosityMethod": 5,
        "viscosity": 0.5,
        "viscoMaxIter": 80,
        "viscoMaxError": 0.02,
        "xsph": 0.0,
    }
    s = load_scene(scene_file(tmp_path, {"FluidBlocks": [BLOCK], "Materials": [mat]}))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s, s.viscosity, s.viscosity_walls) == (
        "implicit",
        0.5,
        0.0,
        "free-slip",
    )
    assert (s.solver.viscosity.max_iterations, s.solver.viscosity.error_pct) == (80, 2.0)
    assert "Takahashi et al. 2015 (improved): simulation.viscosity_model = implicit" in s.warnings[0]
    mat = {"id": "Fluid", "viscosityMethod": 3, "viscosity": 0.5, "xsph": 0.0}  # 2.12 numbers: Peer 2015
    s = load_scene(scene_file(tmp_path, {"FluidBlocks": [BLOCK], "Materials": [mat]}, "b.json"))
    assert (s.viscosity_model, s.kinematic_viscosity_m2s) == ("xsph", 0.0)
