"""Bad input through `ipsph run`: exit 2, one line on stderr naming what, where, why and what to do,
before any output is written (issue 6). Runs the CLI in-process (`cli.main`) for speed."""

from __future__ import annotations

import os
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ipsph import cli
from ipsph.io import RUN_JSON

TANK = """
[simulation]
particle_radius = 0.04
end_time = 0.08

[[fluid]]
name = "column"
{fluid}

[[boundary]]
name = "tank"
box = {{ min = [0, 0, 0], max = [0.8, 0.8, 0.8] }}

[render]
enabled = false
"""
BOX_FLUID = "box = { min = [0, 0, 0], max = [0.4, 0.4, 0.4] }"


@pytest.fixture(autouse=True)
def _threads():
    import numba

    n = numba.get_num_threads()
    yield
    numba.set_num_threads(n)


def scene_file(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def run_cli(capsys, *args) -> tuple[int, str]:
    code = cli.main(["run", *map(str, args), "--quiet", "--no-render", "--threads", "1"])
    return code, capsys.readouterr().err


def one_error_line(err: str) -> str:
    """The stderr of a refused run: exactly one `ipsph: error:` line (warnings/notes may precede it)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("ipsph: error:")]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    return errors[0]


def assert_refused(capsys, out: Path, *args) -> str:
    code, err = run_cli(capsys, *args, "-o", out)
    assert code == 2, err
    assert not out.exists(), "bad input must stop before the output folder is created"
    return one_error_line(err)


def write_obj(path: Path, pts, faces) -> Path:
    with open(path, "w") as f:
        for p in pts:
            f.write(f"v {p[0]} {p[1]} {p[2]}\n")
        for t in faces:
            f.write("f " + " ".join(str(i + 1) for i in t) + "\n")
    return path


def cube(lo=0.1, hi=0.5):
    pts = np.array([[x, y, z] for z in (lo, hi) for y in (lo, hi) for x in (lo, hi)], dtype=float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return pts, faces


# -- scene files ----------------------------------------------------------------------------------
def test_syntax_error_names_line_and_column(tmp_path, capsys):
    s = scene_file(tmp_path, "[simulation]\nparticle_radius = 0.04\nend_time = = 0.1\n")
    line = assert_refused(capsys, tmp_path / "out", s)
    assert re.search(r"scene\.toml:3:\d+", line), line


def test_unknown_key_suggests_the_right_one(tmp_path, capsys):
    s = scene_file(tmp_path, "[simulation]\nparticle_radus = 0.04\n")
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "particle_radus" in line and "did you mean 'particle_radius'" in line, line


@pytest.mark.parametrize("value, expect", [('"big"', "expected a number"), ("-1", "allowed 0 < value")])
def test_wrong_type_or_range_names_key_and_range(tmp_path, capsys, value, expect):
    s = scene_file(tmp_path, f"[simulation]\nparticle_radius = {value}\n")
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "simulation.particle_radius" in line and expect in line, line


def test_set_override_out_of_range(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    line = assert_refused(capsys, tmp_path / "out", s, "--set", "simulation.gravity=[0,-1e5,0]")
    assert "simulation.gravity" in line and "allowed" in line, line


def test_missing_mesh_shows_given_and_resolved_path(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "meshes/bunny.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "'meshes/bunny.obj'" in line and str(tmp_path / "meshes" / "bunny.obj") in line, line


# -- meshes ---------------------------------------------------------------------------------------
def test_empty_mesh_refused(tmp_path, capsys):
    (tmp_path / "empty.obj").write_text("# nothing\n")
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "empty.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "empty.obj" in line and ("empty" in line or "no triangles" in line), line


def test_unreadable_mesh_refused(tmp_path, capsys):
    (tmp_path / "junk.stl").write_bytes(b"\x00\x01 not a mesh at all \xff" * 3)
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "junk.stl"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "junk.stl" in line, line


def test_open_mesh_fluid_refused_with_edge_count(tmp_path, capsys):
    pts, faces = cube()
    write_obj(tmp_path / "open.obj", pts, faces[:-2])  # one face missing: 4 open edges
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "open.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "open.obj" in line and "4 open edges" in line and "allow_open_mesh" in line, line


def test_zero_volume_mesh_refused(tmp_path, capsys):
    pts, faces = cube()
    pts[:, 1] = 0.3  # squashed flat: closed but encloses nothing
    write_obj(tmp_path / "flat.obj", pts, faces)
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "flat.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "flat.obj" in line and "zero volume" in line, line


@pytest.mark.parametrize("index", [99, 0])  # past the end; 0 (OBJ counts from 1) crashed VTK
def test_obj_face_naming_a_missing_vertex_names_the_line(tmp_path, capsys, index):
    pts, faces = cube()
    faces[5] = (faces[5][0], faces[5][1], index - 1)  # write_obj adds 1
    write_obj(tmp_path / "holey.obj", pts, faces)
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "holey.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "holey.obj" in line and "line 14" in line and f"names vertex {index}" in line, line


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_mesh_with_a_vertex_that_is_not_a_number_refused(tmp_path, capsys, bad):
    pts, faces = cube()
    write_obj(tmp_path / "bad.obj", pts, faces)
    text = (tmp_path / "bad.obj").read_text().splitlines()
    text[2] = f"v 0.1 {bad} 0.1"
    (tmp_path / "bad.obj").write_text("\n".join(text) + "\n")
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "bad.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "bad.obj" in line and "not a finite number" in line and "line 3" in line, line


OBSTACLE = """
[[boundary]]
name = "rock"
role = "obstacle"
mesh = "rock.obj"
"""


def test_open_obstacle_mesh_refused_naming_where(tmp_path, capsys):
    pts, faces = cube(0.5, 0.7)
    write_obj(tmp_path / "rock.obj", pts, faces[:-2])  # the x = 0.7 face missing: 4 open edges
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + OBSTACLE)
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "boundary[1] 'rock'" in line and "obstacle" in line and "4 open edges" in line, line
    assert re.search(r"one at \(0\.7, ", line) and "allow_open_mesh" in line, line


def test_open_obstacle_mesh_runs_as_a_thin_shell_when_allowed(tmp_path):
    from ipsph.run.preflight import check_geometry
    from ipsph.scene import load_scene

    pts, faces = cube(0.5, 0.7)
    write_obj(tmp_path / "rock.obj", pts, faces[:-2])
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + OBSTACLE + "allow_open_mesh = true\n")
    check_geometry(load_scene(s))  # passes the check that refuses it without the key


@pytest.mark.parametrize(
    "wall, says",
    [
        ('box = { min = [0.5, 0.5, 0.5], max = [0.7, 0.7, 0.7] }\nrole = "obstacle"', "mesh obstacles only"),
        ('mesh = "rock.obj"\nrole = "container"', "container's mesh may be open already"),
        ('mesh = "rock.obj"\nrole = "obstacle"\ndensity = 500.0', "dynamic body needs a closed surface"),
    ],
)
def test_allow_open_mesh_applies_to_mesh_obstacles_only(tmp_path, capsys, wall, says):
    pts, faces = cube(0.5, 0.7)
    write_obj(tmp_path / "rock.obj", pts, faces)
    extra = f'[[boundary]]\nname = "rock"\n{wall}\nallow_open_mesh = true\n'
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + extra)
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "boundary[1].allow_open_mesh" in line and says in line, line


def test_body_through_its_containers_wall_refused(tmp_path, capsys):
    crate = '[[boundary]]\nname = "crate"\nrole = "obstacle"\ndensity = 500.0\n'
    crate += "box = { min = [0.7, 0.4, 0.3], max = [0.9, 0.6, 0.5] }\n"  # 0.1 m past the tank's x = 0.8
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + crate)
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "boundary[1] 'crate'" in line and "wall of boundary[0] 'tank'" in line, line
    assert re.search(r"up to 0\.0[5-9]\d* m deep \(near \(0\.8", line), line


def test_overlapping_fluids_refused_naming_both_and_the_box(tmp_path, capsys):
    second = '[[fluid]]\nname = "second"\nbox = { min = [0.2, 0, 0], max = [0.6, 0.4, 0.4] }\n'
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + second)
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "fluid[0] 'column'" in line and "fluid[1] 'second'" in line, line
    assert "min (0.2, 0, 0), max (0.4, 0.4, 0.4)" in line, line


def test_overlapping_mesh_fluids_refused_naming_where(tmp_path, capsys):
    for name, lo in (("a.obj", 0.1), ("b.obj", 0.3)):  # two 0.3 m cubes, 0.1 m deep into each other
        pts, faces = cube(lo, lo + 0.3)
        write_obj(tmp_path / name, pts, faces)
    second = '[[fluid]]\nname = "second"\nmesh = "b.obj"\n'
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "a.obj"') + second)
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "fluid[0] 'column'" in line and "fluid[1] 'second'" in line, line
    box = re.search(r"min \(([^)]*)\), max \(([^)]*)\)", line)
    lo, hi = (np.array([float(v) for v in g.split(",")]) for g in box.groups())
    assert np.all(lo >= 0.3 - 1e-9) and np.all(hi <= 0.4 + 1e-9), line  # inside the cubes' common part


def test_fluids_that_only_touch_are_not_refused(tmp_path):
    from ipsph.sampling.scene import check_sampled, sample
    from ipsph.scene import load_scene

    second = '[[fluid]]\nname = "second"\nbox = { min = [0.4, 0, 0], max = [0.8, 0.4, 0.4] }\n'
    scene = load_scene(scene_file(tmp_path, TANK.format(fluid=BOX_FLUID) + second))
    sampled = sample(scene)
    check_sampled(scene, sampled)
    assert sampled.fluid_counts == [64, 64]


def test_inverted_mesh_is_flipped_and_runs(tmp_path, capsys):
    pts, faces = cube()
    write_obj(tmp_path / "inside_out.obj", pts, [t[::-1] for t in faces])
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "inside_out.obj"'))
    code, err = run_cli(capsys, s, "-o", tmp_path / "out")
    assert code == 0, err
    # a 0.4 m cube at d = 0.08 m holds 5^3 lattice points (some overlap the walls: none here)
    import json

    info = json.loads((tmp_path / "out" / RUN_JSON).read_text())
    assert info["fluid_particles"] > 0


# -- size guard ------------------------------------------------------------------------------------
def test_size_guard_reports_estimate_and_extent(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    line = assert_refused(capsys, tmp_path / "out", s, "--max-particles", "10")
    assert "64 particles" in line and "--max-particles" in line and "0.4 x 0.4 x 0.4 m" in line, line


def test_size_guard_hints_at_millimetres(tmp_path, capsys):
    pts, faces = cube(0.0, 400.0)  # a 0.4 m cube written in millimetres
    write_obj(tmp_path / "mm.obj", pts, faces)
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "mm.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s, "--max-particles", "100000")
    assert "400 x 400 x 400 m" in line and "millimetres" in line and "0.001" in line, line


def test_render_size_guard_names_the_image_and_the_way_out(tmp_path, capsys, monkeypatch):
    """An image whose render process would not fit in half the memory: exit 2 before output."""
    import collections

    import psutil

    mem = collections.namedtuple("mem", "available")
    monkeypatch.setattr(psutil, "virtual_memory", lambda: mem(1 << 30))  # a 1 GiB machine
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID).replace("enabled = false", "width = 8192\nheight = 8192"))
    out = tmp_path / "out"
    code = cli.main(["run", str(s), "--quiet", "--threads", "1", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not (out / RUN_JSON).exists(), err
    line = one_error_line(err)
    assert "8192 x 8192" in line and "GiB" in line and "--no-render" in line, line


def test_radius_too_large_for_the_fluid(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    # r = 0.1: d = 0.2, round(0.4 / 0.2) - 1 = 1 particle across the 0.4 m column
    line = assert_refused(capsys, tmp_path / "out", s, "--set", "simulation.particle_radius=0.1")
    assert "particle_radius 0.1 m is too large" in line and "0.4 m" in line and "<= 0.08 m" in line, line


def test_radius_too_large_for_a_mesh_fluid(tmp_path, capsys):
    pts, faces = cube(0.1, 0.3)
    write_obj(tmp_path / "small.obj", pts, faces)
    s = scene_file(tmp_path, TANK.format(fluid='mesh = "small.obj"'))
    line = assert_refused(capsys, tmp_path / "out", s, "--set", "simulation.particle_radius=0.06")
    assert "too large" in line and "0.2 m" in line, line


# -- output folder ---------------------------------------------------------------------------------
def test_output_folder_is_a_file(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    (tmp_path / "taken").write_text("x")
    code, err = run_cli(capsys, s, "-o", tmp_path / "taken")
    assert code == 2 and "is a file" in one_error_line(err), err


def test_output_folder_not_writable(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    (tmp_path / "file").write_text("x")
    code, err = run_cli(capsys, s, "-o", tmp_path / "file" / "sub")  # below a file: cannot be created
    line = one_error_line(err)
    assert code == 2 and "not writable" in line, err


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anywhere")
def test_output_folder_read_only(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        code, err = run_cli(capsys, s, "-o", ro / "out")
    finally:
        ro.chmod(0o755)
    assert code == 2 and "not writable" in one_error_line(err), err


def test_earlier_run_refused_without_overwrite(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    out = tmp_path / "out"
    code, err = run_cli(capsys, s, "-o", out)
    assert code == 0, err
    first = (out / RUN_JSON).read_bytes()
    code, err = run_cli(capsys, s, "-o", out)
    line = one_error_line(err)
    assert code == 2 and "earlier run" in line and "--overwrite" in line and "--resume" in line, err
    assert (out / RUN_JSON).read_bytes() == first, "a refused run must not touch the earlier one"
    code, err = run_cli(capsys, s, "-o", out, "--overwrite")
    assert code == 0, err


def test_resume_without_an_earlier_run(tmp_path, capsys):
    s = scene_file(tmp_path, TANK.format(fluid=BOX_FLUID))
    code, err = run_cli(capsys, s, "-o", tmp_path / "new", "--resume")
    assert code == 2 and "no earlier run" in one_error_line(err), err
