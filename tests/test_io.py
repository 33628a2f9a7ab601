"""Output folder writers: VTU/PVD/stats/run.json round trips and atomic, failure-safe writes."""

from __future__ import annotations

import os

import numpy as np
import pytest

from ipsph.errors import OutputError, WriteError
from ipsph.io import atomic_path, frame_file
from ipsph.io.provenance import read_run_json, versions, write_run_json
from ipsph.io.pvd import PvdSeries
from ipsph.io.stats import STATS_COLUMNS, StatsWriter, read_stats
from ipsph.io.vtu import read_particles, write_particles, write_surface


def _fields(n, rng):
    return {
        "velocity": rng.normal(size=(n, 3)),
        "density": 1000 + rng.normal(size=n),
        "pressure": rng.random(n).astype(np.float32),
        "mass": np.full(n, 0.125),
        "id": np.arange(n, dtype=np.int64),
    }


def test_vtu_round_trip_pyvista_meshio_and_own_reader(tmp_path):
    import meshio
    import pyvista as pv

    rng = np.random.default_rng(0)
    n = 257
    pts = rng.random((n, 3))
    fields = _fields(n, rng)
    f = tmp_path / "fluid_000003.vtu"
    nbytes = write_particles(f, pts, fields, time=0.12)
    assert nbytes == f.stat().st_size > n * 3 * 8
    assert [p.name for p in tmp_path.iterdir()] == [f.name]  # no temporary left behind

    p2, f2, t2 = read_particles(f)
    assert t2 == 0.12
    np.testing.assert_array_equal(p2, pts)
    for k, v in fields.items():
        np.testing.assert_array_equal(f2[k], v)  # exact: raw binary, no conversion

    grid = pv.read(f)
    assert grid.n_points == n and grid.n_cells == n  # one VERTEX per particle
    assert grid.field_data["TimeValue"][0] == 0.12
    for k, v in fields.items():
        np.testing.assert_array_equal(grid.point_data[k], v)

    m = meshio.read(f)
    assert m.cells[0].type == "vertex" and len(m.cells[0].data) == n
    for k, v in fields.items():
        np.testing.assert_array_equal(m.point_data[k], v)


def test_vtu_compressed_and_empty(tmp_path):
    rng = np.random.default_rng(1)
    pts = np.zeros((2000, 3))  # highly compressible
    raw = write_particles(tmp_path / "a.vtu", pts, {"id": np.arange(2000)}, 0.0)
    packed = write_particles(tmp_path / "b.vtu", pts, {"id": np.arange(2000)}, 0.0, compress=True)
    assert packed < raw / 2
    np.testing.assert_array_equal(read_particles(tmp_path / "b.vtu")[1]["id"], np.arange(2000))
    write_particles(tmp_path / "e.vtu", np.zeros((0, 3)), {"id": np.zeros(0, np.int64)}, 1.0)
    p, f, t = read_particles(tmp_path / "e.vtu")
    assert p.shape == (0, 3) and t == 1.0
    with pytest.raises(ValueError):
        write_particles(tmp_path / "x.vtu", rng.random((3, 3)), {"id": np.arange(4)}, 0.0)


def test_vtu_write_failure_raises_writeerror_and_keeps_old_file(tmp_path, monkeypatch):
    f = tmp_path / "fluid_000000.vtu"
    write_particles(f, np.ones((5, 3)), {"id": np.arange(5)}, 0.5)
    before = f.read_bytes()

    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    import ipsph.io.vtu as vtu

    class FullDiskWriter(vtkXMLUnstructuredGridWriter):  # writes half a file, then the disk is full
        def Write(self):
            with open(self.GetFileName(), "wb") as fh:
                fh.write(b"<VTKFile partial")
            return 0

    monkeypatch.setattr(vtu, "_make_writer", lambda kind: FullDiskWriter())
    with pytest.raises(WriteError) as info:
        write_particles(f, np.zeros((9, 3)), {"id": np.arange(9)}, 0.6)
    msg = str(info.value)
    assert "\n" not in msg and str(f) in msg
    assert f.read_bytes() == before  # previous content intact
    assert sorted(p.name for p in tmp_path.iterdir()) == [f.name]  # temp removed


def test_vtu_write_into_missing_folder_raises_writeerror(tmp_path):
    # (chmod-based read-only folders do not stop root, so a missing folder stands in for an unwritable one)
    target = tmp_path / "no_such_dir" / "fluid_000000.vtu"
    with pytest.raises(WriteError) as info:
        write_particles(target, np.ones((3, 3)), {}, 0.0)
    assert "\n" not in str(info.value) and str(target) in str(info.value)
    assert not target.exists()


def test_surface_round_trip(tmp_path):
    import pyvista as pv

    box = pv.Box(bounds=(0, 1, 0, 2, 0, 3)).triangulate()
    write_surface(tmp_path / "boundary_surface.vtp", box)
    back = pv.read(tmp_path / "boundary_surface.vtp")
    assert back.n_cells == box.n_cells and back.bounds == box.bounds


def test_pvd_series_read_by_pyvista_with_two_parts(tmp_path):
    import pyvista as pv

    rng = np.random.default_rng(2)
    (tmp_path / "frames").mkdir()
    write_particles(
        tmp_path / "boundary.vtu", rng.random((10, 3)), {"volume": np.full(10, 1e-6), "id": np.arange(10)}, 0.0
    )
    series = PvdSeries(tmp_path / "run.pvd", "boundary.vtu")
    times = [0.0, 0.04, 0.08]
    for i, t in enumerate(times):
        write_particles(tmp_path / frame_file(i), rng.random((20 + i, 3)), _fields(20 + i, rng), t)
        series.add(t, tmp_path / frame_file(i))  # absolute paths are stored relative
    assert "frames/fluid_000001.vtu" in (tmp_path / "run.pvd").read_text()
    assert str(tmp_path) not in (tmp_path / "run.pvd").read_text()

    reader = pv.get_reader(str(tmp_path / "run.pvd"))
    assert reader.time_values == times
    reader.set_active_time_value(0.08)
    mb = reader.read()
    assert mb.n_blocks == 2
    assert mb[0].n_points == 22 and mb[1].n_points == 10
    assert "velocity" in mb[0].point_data and "volume" in mb[1].point_data

    loaded = PvdSeries.load(tmp_path / "run.pvd")
    assert loaded.times == times and loaded.boundary_file == "boundary.vtu"
    assert loaded.frames[2][1] == "frames/fluid_000002.vtu"
    dropped = loaded.truncate_after(0.04)
    assert dropped == [(0.08, "frames/fluid_000002.vtu")]
    assert pv.get_reader(str(tmp_path / "run.pvd")).time_values == [0.0, 0.04]
    with pytest.raises(ValueError):
        loaded.add(0.04, frame_file(9))  # times must increase


def test_pvd_without_boundary(tmp_path):
    s = PvdSeries(tmp_path / "run.pvd", None)
    s.add(0.0, "frames/fluid_000000.vtu")
    assert 'part="1"' not in (tmp_path / "run.pvd").read_text()
    assert PvdSeries.load(tmp_path / "run.pvd").boundary_file is None


def test_pvd_parts_are_named_and_declared_once(tmp_path):
    """Blocks carry their part's name (ParaView: /Root/fluid, ...); a part declared in io.PARTS
    with a file per frame gets its own series; undeclared parts are refused."""
    s = PvdSeries(tmp_path / "run.pvd", "boundary.vtu", static={"boundary_surface": "boundary_surface.vtp"})
    for i, t in enumerate((0.0, 0.04)):
        s.add(t, frame_file(i), surface=f"surfaces/surface_{i:06d}.vtp")
    text = (tmp_path / "run.pvd").read_text()
    assert '<DataSet timestep="0.04" group="" part="1" name="surface" file="surfaces/surface_000001.vtp"/>' in text
    assert text.count('name="boundary_surface"') == 2 and text.count('part="0" name="fluid"') == 2
    assert (tmp_path / "surface.pvd").read_text().count('name="surface"') == 2
    assert "boundary" not in (tmp_path / "fluid.pvd").read_text()
    back = PvdSeries.load(tmp_path / "run.pvd")
    assert back.static == {"boundary": "boundary.vtu", "boundary_surface": "boundary_surface.vtp"}
    assert back.frame_parts[1] == {"surface": "surfaces/surface_000001.vtp"}
    assert back.to_xml() == text
    with pytest.raises(ValueError, match="not a part"):
        s.add(0.08, frame_file(2), spray="x.vtu")
    with pytest.raises(ValueError, match="written once"):
        s.add(0.08, frame_file(2), boundary="x.vtu")


def test_pvd_rewrite_is_atomic(tmp_path, monkeypatch):
    s = PvdSeries(tmp_path / "run.pvd", "boundary.vtu")
    s.add(0.0, "frames/fluid_000000.vtu")
    good = (tmp_path / "run.pvd").read_text()

    real_replace = os.replace

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", full_disk)
    with pytest.raises(WriteError) as info:
        s.add(0.04, "frames/fluid_000001.vtu")
    assert "No space left" in str(info.value) and "\n" not in str(info.value)
    monkeypatch.setattr(os, "replace", real_replace)
    assert (tmp_path / "run.pvd").read_text() == good  # old series still valid
    assert PvdSeries.load(tmp_path / "run.pvd").times == [0.0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fluid.pvd", "run.pvd"]  # no temp left
    assert (tmp_path / "fluid.pvd").read_text().count("<DataSet") == 1


def test_atomic_path_passes_keyboard_interrupt_and_cleans_up(tmp_path):
    target = tmp_path / "x.txt"
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def _row(step):
    row = {c: 0.0 for c in STATS_COLUMNS}
    row.update(
        step=step,
        time=step * 0.001,
        dt=0.001,
        particles=1000,
        max_speed=0.1 * step,
        dt_clamped=step % 2 == 0,
        pd_passes=3,
    )
    return row


def test_stats_round_trip_and_truncate(tmp_path):
    p = tmp_path / "stats.csv"
    with StatsWriter(p, STATS_COLUMNS) as w:
        for k in range(1, 11):
            w.write(_row(k))
        # line buffered: readable while the writer is still open
        assert len(read_stats(p)["step"]) == 10
        with pytest.raises(KeyError):
            w.write({"step": 11, "bogus": 1})
    s = read_stats(p)
    assert list(s) == list(STATS_COLUMNS)
    np.testing.assert_array_equal(s["step"], np.arange(1, 11))
    np.testing.assert_array_equal(s["dt_clamped"], [0, 1] * 5)
    assert s["time"][2] == 0.003  # repr formatting round-trips floats exactly
    assert p.read_text().count("step,time,") == 1  # header once

    with open(p, "a") as f:
        f.write("11,0.011,0.0")  # torn last line of an interrupted run
    assert len(read_stats(p)["step"]) == 10

    with StatsWriter(p, STATS_COLUMNS, truncate_after_step=4) as w:
        w.write(_row(5))
        w.write({"step": 6, "time": 0.006})  # missing values -> NaN
    s = read_stats(p)
    np.testing.assert_array_equal(s["step"], [1, 2, 3, 4, 5, 6])
    assert np.isnan(s["max_speed"][-1])

    with pytest.raises(OutputError):
        StatsWriter(p, ["step", "time"], truncate_after_step=2)  # header mismatch


def test_stats_fresh_file_empty(tmp_path):
    p = tmp_path / "stats.csv"
    StatsWriter(p, ["step", "time"]).close()
    s = read_stats(p)
    assert list(s) == ["step", "time"] and len(s["step"]) == 0


def test_run_json_round_trip(tmp_path):
    from dataclasses import asdict

    from ipsph.config import RenderConfig, Scene

    scene = Scene(name="dam")
    info = {
        "scene": scene,
        "method": scene.method,
        "status": "running",
        "completed": False,
        "exit_code": None,
        "particle_radius": np.float64(0.025),
        "fluid_particles": np.int64(1000),
        "domain_bounds": np.array([0, 1, 0, 1, 0, 1.0]),
        "timings_ms": {"xsph": float("nan")},
        "render": {**asdict(RenderConfig()), "speed_range": (0.0, 3.5)},
    }
    write_run_json(tmp_path / "run.json", info)
    back = read_run_json(tmp_path / "run.json")
    assert back["scene"]["name"] == "dam" and back["method"] == "ipsph"
    assert back["scene"]["output"]["folder"] == "out"
    assert back["fluid_particles"] == 1000 and back["domain_bounds"] == [0, 1, 0, 1, 0, 1.0]
    assert back["timings_ms"]["xsph"] is None  # NaN is not JSON
    assert back["render"]["speed_range"] == [0.0, 3.5]
    assert back["versions"]["numpy"] == np.__version__
    assert set(versions()) >= {"python", "ipsph", "numpy", "numba", "vtk", "pyvista", "meshio", "platform", "cpu_count"}
    with pytest.raises(OutputError):
        read_run_json(tmp_path / "missing.json")
