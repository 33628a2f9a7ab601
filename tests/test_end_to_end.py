"""`ipsph run` as a user runs it: a subprocess writing a ParaView-ready folder (issue 2)."""

import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

from ipsph.io.provenance import read_run_json
from ipsph.io.stats import read_stats

SHARED = Path(__file__).resolve().parent / "data" / "splishsplash"  # tests/data/splishsplash/PROVENANCE.md
FIELDS = {"velocity": 3, "density": 1, "pressure": 1, "mass": 1, "id": 1}


def ipsph(*args, cwd=None, timeout=600):
    return subprocess.run(
        [sys.executable, "-m", "ipsph", *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("default") / "out"
    res = ipsph("run", "-o", out, "--end-time", 1.0, "--no-render")
    assert res.returncode == 0, res.stderr
    return out


@pytest.mark.slow
def test_default_scene_writes_a_readable_series(default_run):
    import pyvista as pv

    out = default_run
    reader = pv.get_reader(str(out / "run.pvd"))
    times = reader.time_values
    assert len(times) >= 26  # t = 0 and 25 frames per simulated second
    assert np.allclose(np.diff(times), 0.04, atol=1e-9)  # frames land exactly on output times
    reader.set_active_time_value(times[-1])
    mb = reader.read()
    assert mb.n_blocks == 3  # fluid, boundary particles, wall surface (run.pvd's parts, named in ParaView)
    assert mb[2].n_cells > 0 and mb[2].bounds == pytest.approx(mb[1].bounds, abs=0.05)  # walls sampled on it
    run = read_run_json(out / "run.json")
    assert run["completed"] and run["status"] == "completed"
    assert run["wall_fit"] == {}  # simulation.fit_wall_volumes is off by default (method.md section 1)
    assert run["settle"] == {}  # a dam break's column is never settled (simulation.settle = auto)
    n = run["fluid_particles"]
    for f in sorted((out / "frames").glob("*.vtu")):
        m = meshio.read(f)
        assert len(m.points) == n
        for name, comps in FIELDS.items():
            a = m.point_data[name]
            assert a.shape[0] == n and (a.ndim == 1 or a.shape[1] == comps)
            assert np.all(np.isfinite(a))
    assert (out / "boundary.vtu").exists()
    stats = read_stats(out / "stats.csv")
    assert stats["time"][-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(stats["dt"] > 0)


@pytest.mark.slow
def test_pressure_is_physical_in_the_last_frame(default_run):
    m = meshio.read(sorted((default_run / "frames").glob("*.vtu"))[-1])
    p = m.point_data["pressure"]
    y = m.points[:, 1]
    # the flow is still moving at 1 s (hydrostatics are tested on the tank in test_physics.py),
    # but pressure is never negative (compression-only constraint) and the deepest tenth of the
    # fluid is on average under more pressure than the highest tenth
    assert p.min() >= 0.0
    lo, hi = np.quantile(y, [0.1, 0.9])
    assert p[y <= lo].mean() > 2 * p[y >= hi].mean()


@pytest.mark.parametrize("scene,count", [("DamBreakModel.json", 6859), ("DoubleDamBreak.json", 4732)])
@pytest.mark.slow
def test_stock_splishsplash_scenes_run_unchanged(tmp_path, scene, count):
    path = SHARED / "Scenes" / scene
    res = ipsph("run", path, "-o", tmp_path / "out", "--end-time", 0.05, "--no-render")
    assert res.returncode == 0, res.stderr
    assert "warning" in res.stderr  # unsupported keys are listed, never silently ignored
    run = read_run_json(tmp_path / "out" / "run.json")
    assert run["fluid_particles"] == count
    assert run["method"] == "dfsph"


@pytest.mark.slow
def test_renders_during_a_run(gl, tmp_path):
    res = ipsph("run", "-o", tmp_path / "out", "--end-time", 0.08)
    assert res.returncode == 0, res.stderr
    pngs = sorted((tmp_path / "out" / "renders").glob("*.png"))
    assert len(pngs) == 3
    import imageio.v3 as iio

    img = iio.imread(pngs[-1])
    assert img.shape[:2] == (720, 1280) and img.std() > 5


def test_help_lists_the_commands():
    res = ipsph("--help")
    assert res.returncode == 0
    for cmd in ("run", "render", "plot", "bench"):
        assert cmd in res.stdout
    res = ipsph("run", "--help")
    for flag in ("--method", "--end-time", "--fps", "--every-step", "--set", "--no-render", "-o"):
        assert flag in res.stdout


def test_inverted_mesh_is_flipped_and_the_user_is_told(tmp_path):
    import pyvista as pv

    from ipsph.scene import scene_from_dict
    from ipsph.simulation import sample_scene

    box = pv.Box(bounds=(0.1, 0.5, 0.1, 0.5, 0.1, 0.5)).triangulate()
    faces = box.faces.reshape(-1, 4).copy()
    faces[:, [2, 3]] = faces[:, [3, 2]]  # every triangle wound the wrong way: normals point inward
    pv.PolyData(box.points, faces.ravel()).save(tmp_path / "inverted.stl")
    scene = scene_from_dict(
        {
            "simulation": {"particle_radius": 0.02},
            "fluid": [{"name": "blob", "mesh": str(tmp_path / "inverted.stl")}],
            "boundary": [{"role": "container", "box": {"min": [0, 0, 0], "max": [0.6, 0.6, 0.6]}}],
        },
        name="inverted",
    )
    fluid, _, _, notes = sample_scene(scene)
    assert len(fluid) == 10**3  # the 0.4 m cube at spacing 0.04 m: the flipped mesh is filled normally
    assert any("blob" in n and "flipped" in n for n in notes)
