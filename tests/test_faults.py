"""Faults during a run (issue 6): numerical failure (exit 3), solver caps, disk full (exit 4),
SIGINT/SIGTERM (exit 130 with a final frame), SIGKILL (the .pvd lists only complete frames),
and determinism. Signals run `python -m ipsph run` as a subprocess; the rest runs in-process."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ipsph import cli
from ipsph.errors import NumericalFailure
from ipsph.io import RUN_JSON, RUN_PVD, STATS_CSV, vtu
from ipsph.io.pvd import PvdSeries
from ipsph.io.stats import read_stats
from ipsph.scene import default_scene_path, load_scene
from ipsph.simulation import Simulation, sample_scene

# runs, subprocesses and signals: the full suite only
pytestmark = pytest.mark.slow

# the default dam break, coarse: 378 fluid particles at r = 0.04 (about 0.05 s of wall time per step)
SMALL = ["--set", "simulation.particle_radius=0.04"]
REPO = Path(__file__).resolve().parents[1]


def run_cli(capsys, out: Path, *args) -> tuple[int, str]:
    code = cli.main(["run", "-o", str(out), "--quiet", "--no-render", "--threads", "1", *SMALL, *map(str, args)])
    return code, capsys.readouterr().err


def error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.startswith("ipsph: error:")]
    assert len(lines) == 1, err
    return lines[0]


def listed_frames(out: Path, killed: bool = False) -> list[tuple[float, str]]:
    """The .pvd's frames, each checked complete: it exists, VTK and pyvista read it, its time matches.
    Only a killed run may leave temporary files (unreferenced) behind."""
    import pyvista as pv

    series = PvdSeries.load(out / RUN_PVD)
    for t, f in series.frames:
        x, fields, tv = vtu.read_particles(out / f)
        assert tv == pytest.approx(t, abs=1e-12) and len(x) > 0 and set(fields) >= {"velocity", "id"}
        assert pv.read(out / f).n_points == len(x)
    assert killed or not list((out / "frames").glob(".*tmp")), "temporary files left behind"
    return series.frames


# -- numerical failure ---------------------------------------------------------------------------
def small_sim(end_time=0.2) -> Simulation:
    scene = load_scene(default_scene_path(), ["simulation.particle_radius=0.04", f"simulation.end_time={end_time}"])
    return Simulation(scene, *sample_scene(scene)[:3])


def test_nan_stops_within_one_step_naming_particle():
    sim = small_sim()
    for _ in range(3):
        sim.step()
    sim.state.v[17, 1] = np.nan
    with pytest.raises(NumericalFailure) as e:
        sim.step()
    msg = str(e.value)
    assert sim.steps == 4
    assert "step 4" in msg and f"t = {sim.time:.6g} s" in msg and "non-finite" in msg, msg
    # the NaN spreads through the neighbour passes in this step; the first unhealthy particle is named
    assert re.search(r"particle id \d+", msg) and "\n" not in msg, msg


def test_escape_exits_3_and_keeps_frames(tmp_path, capsys):
    out = tmp_path / "out"
    # a fixed 50 ms step (12 x the CFL step) blows the dam break apart within 1 s
    code, err = run_cli(
        capsys, out, "--end-time", "2", "--set", "time_step.dt_min=0.05", "--set", "time_step.dt_max=0.05"
    )
    assert code == 3, err
    line = error_line(err)
    assert re.search(r"at step \d+, t = [\d.]+ s: particle id \d+ (left the domain|non-finite)", line), line
    frames = listed_frames(out)
    assert len(frames) >= 2
    info = json.loads((out / RUN_JSON).read_text())
    assert info["status"] == "failed" and info["exit_code"] == 3 and "particle id" in info["error"]
    assert info["frames"] == len(frames)
    # stopped within one step: the last stats row is the failing step's predecessor
    assert read_stats(out / STATS_CSV)["step"][-1] == info["steps"] - 1


def test_solver_caps_are_counted_and_reported(tmp_path, capsys):
    out = tmp_path / "out"
    # one divergence iteration cannot bring the divergence error of the falling column to 0.001 %
    code, err = run_cli(
        capsys,
        out,
        "--end-time",
        "0.12",
        "--set",
        "solver.divergence.max_iterations=1",
        "--set",
        "solver.divergence.error_pct=0.001",
    )
    assert code == 0, err
    info = json.loads((out / RUN_JSON).read_text())
    per_step = read_stats(out / STATS_CSV)["solver_maxed"]
    assert info["solver_maxed"] == int(per_step.sum()) > 0
    assert "solves stopped at their iteration cap" in err and "max_iterations" in err, err


# -- disk full -----------------------------------------------------------------------------------
def full_disk_on_third_frame(monkeypatch):
    """Make the third fluid frame's VTK writer fail as on a full disk (half a file, OutOfDiskSpaceError)."""
    from vtkmodules.vtkCommonMisc import vtkErrorCode

    real_make = vtu._make_writer

    class FullDisk:
        """Writes half a file and fails the way VTK does when the disk fills up."""

        def __init__(self, real):
            self._real = real

        def __getattr__(self, name):
            return getattr(self._real, name)

        def Write(self):
            Path(self._real.GetFileName()).write_bytes(b'<?xml version="1.0"?><VTKFile type="Unstr')
            return 0

        def GetErrorCode(self):
            return vtkErrorCode.OutOfDiskSpaceError

    def make(kind):
        writer = real_make(kind)
        # the third fluid frame hits the full disk; boundary.vtu and frames 0, 1 are written
        make.calls += kind == "vtu"
        return FullDisk(writer) if make.calls == 4 else writer

    make.calls = 0
    monkeypatch.setattr(vtu, "_make_writer", make)


def test_disk_full_while_writing_a_frame(tmp_path, capsys, monkeypatch):
    full_disk_on_third_frame(monkeypatch)
    out = tmp_path / "out"
    code, err = run_cli(capsys, out, "--end-time", "0.2")
    assert code == 4, err
    line = error_line(err)
    assert "frames/fluid_000002.vtu" in line and "disk space" in line, line
    frames = listed_frames(out)
    assert [f for _, f in frames] == ["frames/fluid_000000.vtu", "frames/fluid_000001.vtu"]
    assert not (out / "frames" / "fluid_000002.vtu").exists(), "no partial frame under the final name"
    info = json.loads((out / RUN_JSON).read_text())
    assert info["status"] == "failed" and info["exit_code"] == 4 and info["frames"] == 2


def test_disk_full_message_names_the_reason(tmp_path, capsys, monkeypatch):
    full_disk_on_third_frame(monkeypatch)
    code, err = run_cli(capsys, tmp_path / "out", "--end-time", "0.2")
    assert code == 4 and "OutOfDiskSpace" in error_line(err), err


# -- signals -------------------------------------------------------------------------------------
def start_run(out: Path, *extra) -> subprocess.Popen:
    cmd = [
        sys.executable,
        "-m",
        "ipsph",
        "run",
        "-o",
        str(out),
        "--quiet",
        "--no-render",
        "--threads",
        "1",
        "--set",
        "simulation.particle_radius=0.03",
        "--end-time",
        "3",
        *extra,
    ]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(path: Path, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout, f"{path} did not appear"
        time.sleep(0.05)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_finishes_step_writes_final_frame_exits_130(tmp_path, sig):
    out = tmp_path / "out"
    proc = start_run(out)
    wait_for(out / "frames" / "fluid_000002.vtu", proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted at t =" in err and "--resume" in err, err
    frames = listed_frames(out)
    info = json.loads((out / RUN_JSON).read_text())
    assert info["status"] == "interrupted" and info["exit_code"] == 130
    # the final frame is the state at the interrupt: the last listed frame, at the run's final time
    assert frames[-1][0] == pytest.approx(info["sim_time"], abs=1e-12) and len(frames) >= 3
    assert info["checkpoint"]["time"] == info["sim_time"] and (out / "checkpoint.npz").is_file()


def test_sigkill_leaves_only_complete_frames_and_resumes(tmp_path, capsys):
    out = tmp_path / "out"
    proc = start_run(out, "--set", "output.checkpoint_interval=0.04")
    wait_for(out / "frames" / "fluid_000003.vtu", proc)
    time.sleep(0.13)  # somewhere in the middle of stepping / writing
    proc.kill()
    proc.communicate(timeout=30)
    frames = listed_frames(out, killed=True)
    assert len(frames) >= 3
    assert json.loads((out / RUN_JSON).read_text())["status"] == "running"  # it never got to say otherwise
    # the last checkpoint (one per frame here) carries on; stale temporary files are swept
    end = frames[-1][0] + 0.08
    code = cli.main(
        [
            "run",
            "-o",
            str(out),
            "--quiet",
            "--no-render",
            "--threads",
            "1",
            "--resume",
            "--set",
            "simulation.particle_radius=0.03",
            "--set",
            "output.checkpoint_interval=0.04",
            "--end-time",
            f"{end:.2f}",
        ]
    )
    assert code == 0, capsys.readouterr().err
    assert listed_frames(out)[-1][0] == pytest.approx(end)


# -- determinism ---------------------------------------------------------------------------------
def test_same_input_same_threads_identical_arrays():
    def run():
        sim = small_sim()
        for _ in range(15):
            sim.step()
        return sim

    a, b = run(), run()
    assert a.time == b.time
    for name in ("positions", "velocities", "densities", "pressures", "ids"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
