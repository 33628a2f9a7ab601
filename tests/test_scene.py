"""The TOML scene layer: defaults, strict validation, overrides, round trip, generated docs."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import typing
from pathlib import Path

import pytest

from ipsph import config as model
from ipsph.config import Method, Role, Scene, Transform
from ipsph.errors import ConfigError
from ipsph.params import RENAMED
from ipsph.scene import (
    PARAMS,
    apply_overrides,
    default_scene_path,
    key_help,
    lattice_counts,
    load_scene,
    reference_markdown,
    scene_from_dict,
    scene_to_dict,
)

REPO = Path(__file__).resolve().parents[1]


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


MINIMAL = """
[[fluid]]
box = { min = [0, 0, 0], max = [0.5, 0.5, 0.5] }
"""


# -- the default scene ---------------------------------------------------------------------------


def test_default_scene_is_the_documented_dam_break():
    s = load_scene(default_scene_path())
    assert s.name == "default" and s.source == default_scene_path()
    assert s.method == Method.IPSPH and s.particle_radius == 0.02 and s.end_time == 2.0
    assert s.output.fps == 25.0 and s.output.folder == Path("out")  # as written: relative to CWD
    assert len(s.fluids) == 1 and len(s.boundaries) == 1 and s.warnings == ()
    fluid, tank = s.fluids[0], s.boundaries[0]
    assert (fluid.shape, fluid.box_min, fluid.box_max) == ("box", (0, 0, 0), (0.6, 0.8, 0.6))
    assert (tank.shape, tank.role, tank.box_max) == ("box", Role.CONTAINER, (1.6, 1.2, 0.6))
    # FluidBlocks lattice: round(extent / 2r) - 1 per axis -> 14 x 19 x 14
    assert lattice_counts(fluid.box_min, fluid.box_max, s.particle_radius) == (14, 19, 14)
    assert math.prod(lattice_counts(fluid.box_min, fluid.box_max, 0.02)) == 3724


def test_every_settable_model_field_has_a_scene_key():
    """No silently unreachable setting: every leaf field of the configs is some parameter's target."""
    targets = {p.target for p in PARAMS}

    def leaves(cls, prefix):
        for f in dataclasses.fields(cls):
            t = typing.get_type_hints(cls)[f.name]
            if dataclasses.is_dataclass(t):
                yield from leaves(t, f"{prefix}{f.name}.")
            else:
                yield prefix + f.name

    for prefix, cls in (
        ("time_step.", model.TimeStepConfig),
        ("solver.", model.SolverConfig),
        ("output.", model.OutputConfig),
        ("render.", model.RenderConfig),
        ("surface.", model.SurfaceConfig),
    ):
        for leaf in leaves(cls, prefix):
            assert leaf in targets, f"{leaf} has no scene key"


@pytest.mark.parametrize("old, new", sorted(RENAMED.items()))
def test_renamed_keys_are_refused_naming_the_new_one(tmp_path, old, new):
    table, key = old.rsplit(".", 1)
    with pytest.raises(ConfigError) as e:
        load_scene(write(tmp_path, f"[{table}]\n{key} = 1\n" + MINIMAL))
    msg = str(e.value)
    assert f"{old} was renamed to {new}" in msg and "\n" not in msg
    with pytest.raises(ConfigError, match=re.escape(f"{old} was renamed to {new}")):
        load_scene(default_scene_path(), [f"{old}=1"])


def test_keys_left_out_take_the_model_defaults(tmp_path):
    s = load_scene(write(tmp_path, MINIMAL))
    assert s == Scene(name="scene", fluids=s.fluids, source=s.source)
    assert s.fluids[0].transform == Transform() and s.fluids[0].name == "fluid0"


def test_docs_reference_is_generated_and_current():
    doc = (REPO / "docs" / "scene-reference.md").read_text()
    assert doc == reference_markdown(), (
        "docs/scene-reference.md is stale: run `python -m ipsph.scene > docs/scene-reference.md`"
    )
    for p in PARAMS:
        assert f"`{p.key}`" in doc or f"`box.{p.key}`" in doc or f"`motion.{p.key}`" in doc
        assert p.doc.replace("|", "\\|") in doc
    assert "Importing SPlisHSPlasH scenes" in doc


def test_key_help_lists_every_settable_key():
    text = key_help()
    assert "simulation.particle_radius" in text and "fluid.<i>.velocity" in text
    assert len(text.splitlines()) == len(PARAMS) - 1  # all but `source`


# -- errors --------------------------------------------------------------------------------------


def test_toml_syntax_error_names_file_line_and_column(tmp_path):
    p = write(tmp_path, "[simulation]\nend_time = 2.0\nmethod = ipsph\n", "bad.toml")
    with pytest.raises(ConfigError) as e:
        load_scene(p)
    msg = str(e.value)
    assert re.match(rf"{re.escape(str(p))}:3:\d+: TOML syntax error", msg), msg
    assert "\n" not in msg


@pytest.mark.parametrize(
    "text, expect",
    [
        ("[simulation]\nparticle_radus = 0.02\n", "did you mean 'particle_radius'"),
        ("particle_radius = 0.02\n", "did you mean 'simulation.particle_radius'"),
        ("[simulation]\ncfl_factor = 0.5\n", "did you mean 'time_step.cfl_factor'"),
        ("[simulaton]\nend_time = 1\n", "did you mean 'simulation'"),
        ("[solver.dfsph]\ndensity_eror_pct = 0.1\n", "did you mean 'density_error_pct'"),
    ],
)
def test_unknown_keys_are_refused_with_a_suggestion(tmp_path, text, expect):
    with pytest.raises(ConfigError, match=re.escape(expect)):
        load_scene(write(tmp_path, text + MINIMAL))


def test_unknown_key_in_a_fluid_names_its_index(tmp_path):
    text = MINIMAL + "\n[[fluid]]\nbox = { min = [1, 0, 0], max = [1.5, 0.5, 0.5] }\nvelocty = [1, 0, 0]\n"
    with pytest.raises(ConfigError, match=r"'fluid\[1\]\.velocty'; did you mean 'velocity'"):
        load_scene(write(tmp_path, text))


@pytest.mark.parametrize(
    "line, key, fragment",
    [
        ("velocity = [1, 0]", r"fluid\[1\]\.velocity", "expected 3 numbers"),
        ("velocity = [1, true, 0]", r"fluid\[1\]\.velocity\[1\]", "expected a number"),
        ('velocity = "fast"', r"fluid\[1\]\.velocity", "expected 3 numbers"),
    ],
)
def test_wrong_types_name_the_full_key_path(tmp_path, line, key, fragment):
    text = MINIMAL + f"\n[[fluid]]\nbox = {{ min = [1, 0, 0], max = [1.5, 0.5, 0.5] }}\n{line}\n"
    with pytest.raises(ConfigError, match=key + ": " + fragment):
        load_scene(write(tmp_path, text))


def test_bools_are_not_numbers_but_ints_are_floats(tmp_path):
    with pytest.raises(ConfigError, match=r"simulation\.end_time: expected a number, got a boolean"):
        load_scene(write(tmp_path, "[simulation]\nend_time = true\n" + MINIMAL))
    with pytest.raises(ConfigError, match=r"render\.width: expected an integer, got a float"):
        load_scene(write(tmp_path, "[render]\nwidth = 640.5\n" + MINIMAL))
    s = load_scene(write(tmp_path, "[simulation]\nend_time = 3\n" + MINIMAL))
    assert s.end_time == 3.0 and isinstance(s.end_time, float)


@pytest.mark.parametrize(
    "text, fragment",
    [
        (
            "[simulation]\nparticle_radius = -0.1\n",
            "simulation.particle_radius: -0.1 m is out of range: allowed 0 < value <= 1",
        ),
        ("[simulation]\nviscosity = 2\n", "simulation.viscosity: 2 is out of range: allowed 0 <= value <= 1"),
        ("[render]\nwidth = 4\n", "render.width: 4 px is out of range: allowed 16 <= value <= 16384"),
        ("[simulation]\nend_time = nan\n", "simulation.end_time: expected a finite number"),
        ("[time_step]\ndt_min = 0.01\ndt_max = 0.005\n", "time_step.dt_min: 0.01 s is larger than time_step.dt_max"),
        ("[time_step]\ndt_min = 0.01\n", "larger than time_step.dt_max (auto: 5 ms * r / 0.025 m = 0.005 s)"),
        (
            "[solver.ipsph]\nmin_passes = 5\nmax_passes = 3\n",
            "solver.ipsph.min_passes: 5 is larger than max_passes = 3",
        ),
        ('[output]\nfields = ["velocity", "vorticity"]\n', "output.fields[1]: a string ('vorticity') is not one of"),
        ("[render]\nspeed_range = [2, 1]\n", "render.speed_range: min 2 must be < max 1"),
    ],
)
def test_out_of_range_values_name_key_and_range(tmp_path, text, fragment):
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        load_scene(write(tmp_path, text + MINIMAL))


def test_unknown_method_lists_the_choices(tmp_path):
    with pytest.raises(
        ConfigError,
        match=r"simulation\.method: a string \('sph'\) is not one of "
        r"ipsph, pf, dfsph",
    ):
        load_scene(write(tmp_path, '[simulation]\nmethod = "sph"\n' + MINIMAL))
    with pytest.raises(ConfigError, match="did you mean 'dfsph'"):
        load_scene(write(tmp_path, '[simulation]\nmethod = "dfsp"\n' + MINIMAL))


def test_missing_mesh_shows_path_as_given_and_resolved(tmp_path):
    (tmp_path / "scenes").mkdir()
    p = write(tmp_path / "scenes", '[[fluid]]\nmesh = "../meshes/bunny.obj"\n')
    with pytest.raises(ConfigError) as e:
        load_scene(p)
    msg = str(e.value)
    assert "fluid[0].mesh: mesh file not found: '../meshes/bunny.obj'" in msg
    assert f"resolved: {(tmp_path / 'meshes' / 'bunny.obj').resolve()}" in msg


def test_mesh_paths_resolve_against_the_scene_folder(tmp_path):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "bunny.obj").write_text("v 0 0 0\n")
    (tmp_path / "scenes").mkdir()
    p = write(
        tmp_path / "scenes",
        '[[fluid]]\nmesh = "../meshes/bunny.obj"\nrotate_deg = 90\n'
        '[[boundary]]\nmesh = "../meshes/bunny.obj"\nrole = "obstacle"\n',
    )
    s = load_scene(p)
    assert s.fluids[0].mesh == (tmp_path / "meshes" / "bunny.obj").resolve()
    assert s.fluids[0].transform.rotate_deg == 90.0
    assert s.boundaries[0].role == Role.OBSTACLE


@pytest.mark.parametrize(
    "fluid, fragment",
    [
        ("box = { min = [0, 0, 0], max = [0.5, 0.0, 0.5] }", "fluid[0].box: min [0, 0, 0] must be < max"),
        ("box = { min = [0, 0, 0] }", "fluid[0].box: missing max"),
        ('box = { min = [0, 0, 0], max = [0.5, 0.5, 0.5] }\nmesh = "a.obj"', "give exactly one shape"),
        ("velocity = [1, 0, 0]", "give exactly one shape"),
        ("box = { min = [0, 0, 0], max = [0.5, 0.5, 0.5] }\nrotate_deg = 30", "boxes are axis-aligned"),
        ("box = { min = [0, 0, 0], max = [0.5, 0.05, 0.5] }", "holds no particle at particle_radius 0.025 m"),
        (
            "box = { min = [0, 0, 0], max = [0.5, 0.5, 0.5] }\nscale = [1, 0, 1]",
            "fluid[0].scale[1]: 0 is out of range: allowed 0 < each component",
        ),
    ],
)
def test_bad_fluid_shapes(tmp_path, fluid, fragment):
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        load_scene(write(tmp_path, f"[[fluid]]\n{fluid}\n"))


def test_scene_needs_a_fluid_and_unique_names(tmp_path):
    with pytest.raises(ConfigError, match=r"no \[\[fluid\]\] table"):
        load_scene(write(tmp_path, "[simulation]\nend_time = 1.0\n"))
    with pytest.raises(ConfigError, match=r"write \[\[fluid\]\] \(double brackets\)"):
        load_scene(write(tmp_path, "[fluid]\nbox = { min = [0, 0, 0], max = [1, 1, 1] }\n"))
    two = MINIMAL.replace("[[fluid]]", '[[fluid]]\nname = "w"')
    with pytest.raises(ConfigError, match=r"fluid\[1\]\.name: 'w' is already the name of fluid\[0\]"):
        load_scene(
            write(tmp_path, two + two.replace("[0, 0, 0]", "[1, 0, 0]").replace("[0.5, 0.5, 0.5]", "[1.5, 0.5, 0.5]"))
        )


def test_box_translate_and_scale_are_applied_to_the_corners(tmp_path):
    s = load_scene(
        write(
            tmp_path,
            "[[fluid]]\nbox = { min = [-0.5, 0, -0.5], max = [0.5, 1, 0.5] }\n"
            "translate = [-2.45, 0, 0]\nscale = [1, 2, 1]\n",
        )
    )
    f = s.fluids[0]
    assert f.transform == Transform()
    assert f.box_min == pytest.approx((-2.95, 0.0, -0.5), abs=1e-12)
    assert f.box_max == pytest.approx((-1.95, 2.0, 0.5), abs=1e-12)


def test_file_level_errors(tmp_path):
    with pytest.raises(ConfigError, match=r"unknown scene file type '\.yaml'"):
        load_scene(tmp_path / "scene.yaml")
    with pytest.raises(ConfigError, match=r"scene file not found: .*nope\.toml \(resolved: /"):
        load_scene(tmp_path / "nope.toml")


# -- overrides -----------------------------------------------------------------------------------


def test_overrides_set_sections_and_entities(tmp_path):
    s = load_scene(
        default_scene_path(),
        [
            "simulation.end_time=1.5",
            "simulation.method=dfsph",
            "fluid.0.velocity=[1, 0, 0]",
            "fluid[0].name=water",
            "output.folder=runs/a",
            "time_step.dt_max=0.002",
            "solver.dfsph.density_error_pct=0.05",
            "render.enabled=false",
            "boundary.0.role=obstacle",
        ],
    )
    assert s.end_time == 1.5 and s.method == Method.DFSPH
    assert s.fluids[0].velocity == (1.0, 0.0, 0.0) and s.fluids[0].name == "water"
    assert s.output.folder == Path("runs/a")  # bare words parse as strings
    assert s.time_step.dt_max == 0.002 and s.solver.dfsph.density_error_pct == 0.05
    assert s.render.enabled is False and s.boundaries[0].role == Role.OBSTACLE
    back = load_scene(default_scene_path(), ["time_step.dt_max=0.002", "time_step.dt_max=auto"])
    assert back.time_step.dt_max is None


def test_override_mesh_replaces_box(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\n")
    p = write(tmp_path, MINIMAL)
    s = load_scene(p, ["fluid.0.mesh=m.obj"])
    assert s.fluids[0].shape == "mesh" and s.fluids[0].mesh == (tmp_path / "m.obj").resolve()


def test_override_values_are_validated_like_the_file():
    with pytest.raises(ConfigError, match=r"simulation\.end_time: -1 s is out of range"):
        load_scene(default_scene_path(), ["simulation.end_time=-1"])


@pytest.mark.parametrize(
    "item, fragment",
    [
        ("simulation.end_tim=1", "did you mean 'simulation.end_time'"),
        ("end_time=1", "did you mean 'simulation.end_time'"),
        ("fluid.0.velocty=[1,0,0]", "did you mean 'fluid.0.velocity'"),
        ("fluid.3.velocity=[1,0,0]", "no fluid number 3 in the scene (1 [[fluid]] table: indices 0..0)"),
        ("fluid.velocity=[1,0,0]", "address a [[fluid]] entry by index"),
        ("simulation.end_time", "expected KEY=VALUE"),
    ],
)
def test_bad_overrides(item, fragment):
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        load_scene(default_scene_path(), [item])


def test_apply_overrides_leaves_the_input_alone():
    data = {"simulation": {"end_time": 2.0}}
    out = apply_overrides(data, ["simulation.end_time=1"])
    assert data == {"simulation": {"end_time": 2.0}} and out["simulation"]["end_time"] == 1


# -- round trip ----------------------------------------------------------------------------------


def test_round_trip_default_scene():
    s = load_scene(default_scene_path())
    d = scene_to_dict(s)
    json.dumps(d, allow_nan=False)  # JSON-serialisable, for run.json
    assert scene_from_dict(d) == s


def test_round_trip_with_meshes_and_optional_values(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\n")
    p = write(
        tmp_path,
        """
name = "custom"
[simulation]
method = "pf"
gravity = [0, -9.81, 0.5]
[time_step]
dt_max = 0.003
dt_initial = 0.001
[output]
checkpoint_interval = 0.25
fields = ["velocity", "id"]
every_step = true
[render]
camera_position = [1, 2, 3]
focal_point = [0, 0.5, 0]
view_up = [0, 1, 0]
speed_range = [0, 3.5]
[[fluid]]
mesh = "m.obj"
translate = [0.1, 0.2, 0.3]
scale = [2, 2, 2]
rotate_axis = [1, 0, 0]
rotate_deg = 45
velocity = [0, -1, 0]
allow_open_mesh = true
[[fluid]]
box = { min = [1, 0, 0], max = [1.5, 0.5, 0.5] }
[[boundary]]
mesh = "m.obj"
role = "obstacle"
""",
    )
    s = load_scene(p)
    assert s.name == "custom"
    d = json.loads(json.dumps(scene_to_dict(s)))
    assert scene_from_dict(d) == s
    assert scene_from_dict(d, Path("/"), "other").name == "other"  # absolute mesh paths


# A [[fluid]] key added to the table, and nothing else: the table is patched before any module
# that generates from it is imported (a fresh process, so the rest of the suite keeps its classes).
_DUMMY_KEY = """
import importlib, json, sys
import ipsph.params
from ipsph.params import body_keys
from ipsph.params.schema import _P

body_keys.KEYS = body_keys.KEYS + (_P("fluid.dummy", "float", 1.0, "", "A key nothing reads.", "dummy"),)
importlib.reload(ipsph.params)
from ipsph.scene import load_scene, scene_from_dict, scene_to_dict

scene = load_scene(sys.argv[1])
stored = scene_to_dict(scene)
print(json.dumps({"spec": [f.dummy for f in scene.fluids], "again": scene_from_dict(stored) == scene}))
from ipsph.cli import main

sys.exit(main(["run", sys.argv[1], "-o", sys.argv[2], "--end-time", "0.01", "--no-render", "--quiet"]))
"""


def test_a_new_fluid_key_reaches_the_spec_and_run_json(tmp_path):
    """One line in params/body_keys.py is all a [[fluid]] key needs: the given value lands on the
    FluidSpec (the default where left out) and run.json's scene writes it back."""
    import subprocess
    import sys

    from ipsph.io import RUN_JSON
    from ipsph.io.provenance import read_run_json

    p = write(tmp_path, MINIMAL + "dummy = 2.5\n[[fluid]]\nbox = { min = [1, 0, 0], max = [1.2, 0.2, 0.2] }\n")
    res = subprocess.run(
        [sys.executable, "-c", _DUMMY_KEY, str(p), str(tmp_path / "out")], capture_output=True, text=True, timeout=600
    )
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[0]) == {"spec": [2.5, 1.0], "again": True}
    stored = read_run_json(tmp_path / "out" / RUN_JSON)["scene"]
    assert [f["dummy"] for f in stored["fluid"]] == [2.5, 1.0]


def test_each_motion_type_takes_declared_motion_keys():
    from ipsph.params import MOTION_KEYS

    declared = {p.key for p in PARAMS if p.path.startswith("boundary.motion.")}
    assert all(set(keys) <= declared - {"type"} for keys in MOTION_KEYS.values()), MOTION_KEYS


def test_from_scene_applies_overrides_to_a_dict_and_refuses_them_on_a_resolved_scene():
    """`--set` items reach a dict scene as they reach a file; a resolved Scene cannot take them
    (dropping them silently would run a different scene than the caller asked for)."""
    from ipsph import Simulation

    data = {
        "simulation": {"particle_radius": 0.05, "method": "ipsph"},
        "fluid": [{"name": "w", "box": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]}}],
        "boundary": [{"name": "tank", "role": "container", "box": {"min": [0, 0, 0], "max": [0.3, 0.3, 0.3]}}],
    }
    sim = Simulation.from_scene(data, overrides=["simulation.method=dfsph"])
    assert sim.scene.method == Method.DFSPH
    assert data["simulation"]["method"] == "ipsph", "the caller's dict is not changed"
    with pytest.raises(ValueError, match="overrides"):
        Simulation.from_scene(sim.scene, overrides=["simulation.method=pf"])
