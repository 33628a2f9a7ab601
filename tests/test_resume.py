"""Checkpoint and --resume (issue 6): a resumed run is bit-identical to an uninterrupted one with the
same thread count; frames and stats rows after the checkpoint are replaced; a checkpoint from a
different scene or ipsph version is refused with exit 2. In-process through `cli.main`."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest

import ipsph
from ipsph import cli
from ipsph.io import RUN_JSON, RUN_PVD, STATS_CSV, vtu
from ipsph.io.pvd import PvdSeries
from ipsph.io.stats import read_stats
from ipsph.run.folder import RunFolder

# every test continues a run: the full suite only
pytestmark = pytest.mark.slow

T = 0.24  # 6 frames at 25 fps of the coarse dam break: the column is falling and splashing by then
BASE = [
    "--quiet",
    "--no-render",
    "--threads",
    "1",
    "--set",
    "simulation.particle_radius=0.04",
    "--set",
    "output.checkpoint_interval=0.08",
]


def run_cli(capsys, out: Path, *args) -> tuple[int, str]:
    code = cli.main(["run", "-o", str(out), *BASE, *map(str, args)])
    return code, capsys.readouterr().err


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("resume") / "A"
    assert cli.main(["run", "-o", str(out), *BASE, "--end-time", str(T)]) == 0
    return out


def assert_same_run(a: Path, b: Path, extra: tuple[float, ...] = ()) -> None:
    """Every frame, the final checkpoint and every stats figure (not the timings) bit for bit.

    `extra`: times of frames only `b` has (the final frame an interrupt writes stays in the series).
    """
    fa = dict(PvdSeries.load(a / RUN_PVD).frames)
    fb = dict(PvdSeries.load(b / RUN_PVD).frames)
    assert len(fa) == 7 and sorted(fb) == sorted([*fa, *extra])
    for t in fa:
        xa, da, ta = vtu.read_particles(a / fa[t])
        xb, db, tb = vtu.read_particles(b / fb[t])
        f = fa[t]
        assert ta == tb and np.array_equal(xa, xb), f
        assert set(da) == set(db) and all(np.array_equal(da[k], db[k]) for k in da), f
    ca, cb = np.load(a / "checkpoint.npz"), np.load(b / "checkpoint.npz")
    assert ca.files == cb.files
    for k in ca.files:  # float64 state, boundary order, grid, scalars (time, steps, dt_next, ...)
        if k == "scalars":
            sa, sb = json.loads(str(ca[k])), json.loads(str(cb[k]))
            assert sb.pop("frames") == sa.pop("frames") + len(extra) and sa == sb
        else:
            assert np.array_equal(ca[k], cb[k]), k
    sa, sb = read_stats(a / STATS_CSV), read_stats(b / STATS_CSV)
    for col in sa:
        if not col.startswith("ms_"):
            assert np.array_equal(sa[col], sb[col], equal_nan=True), col
    assert len(set(sa["step"])) == len(sa["step"]), "stats rows after the checkpoint must be cut, not repeated"


def test_resume_is_bit_identical(uninterrupted, tmp_path, capsys):
    out = tmp_path / "B"
    code, err = run_cli(capsys, out, "--end-time", "0.1")  # last checkpoint at 0.08; stats and state go on to 0.1
    assert code == 0, err
    assert json.loads((out / RUN_JSON).read_text())["checkpoint"]["time"] == pytest.approx(0.08)
    code, err = run_cli(capsys, out, "--end-time", str(T), "--resume")
    assert code == 0, err
    assert_same_run(uninterrupted, out)
    info = json.loads((out / RUN_JSON).read_text())
    assert info["status"] == "completed" and info["resumed"][0]["time"] == pytest.approx(0.08)


def test_resume_after_interrupt_is_bit_identical(uninterrupted, tmp_path, capsys, monkeypatch):
    step = RunFolder.step

    def interrupt_at_step_9(self, s):  # between frames 1 and 2
        if s.step == 9:
            os.kill(os.getpid(), signal.SIGINT)  # the runner's handler: finish the step, final frame, 130
        step(self, s)

    monkeypatch.setattr(RunFolder, "step", interrupt_at_step_9)
    out = tmp_path / "B"
    code, err = run_cli(capsys, out, "--end-time", str(T))
    assert code == 130, err
    frames = PvdSeries.load(out / RUN_PVD).frames
    stop = json.loads((out / RUN_JSON).read_text())["checkpoint"]["time"]
    assert frames[-1][0] == stop and 0.04 < stop < 0.08, "the final frame is at the interrupt, off the frame grid"
    monkeypatch.setattr(RunFolder, "step", step)
    code, err = run_cli(capsys, out, "--end-time", str(T), "--resume")
    assert code == 0, err
    assert_same_run(uninterrupted, out, extra=(stop,))
    assert len(list((out / "frames").glob("fluid_*.vtu"))) == 8


@pytest.fixture()
def stopped(tmp_path):
    """A copy of a run stopped at t = 0.1 with its checkpoint at 0.08."""
    out = tmp_path / "B"
    assert cli.main(["run", "-o", str(out), *BASE, "--end-time", "0.1"]) == 0
    return out


def test_checkpoint_from_a_modified_scene_is_refused(stopped, capsys):
    before = (stopped / RUN_PVD).read_bytes()
    code, err = run_cli(capsys, stopped, "--end-time", str(T), "--resume", "--set", "simulation.viscosity=0.02")
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("ipsph: error:") and "different scene" in line and "simulation.viscosity" in line, line
    assert (stopped / RUN_PVD).read_bytes() == before, "a refused resume must leave the run untouched"


def test_checkpoint_from_another_version_is_refused(stopped, capsys, monkeypatch):
    from ipsph import _version

    written_by = ipsph.__version__
    monkeypatch.setattr(_version, "__version__", "99.0.0")  # where every module reads it
    code, err = run_cli(capsys, stopped, "--end-time", str(T), "--resume")
    assert code == 2 and f"written by ipsph {written_by}, this is 99.0.0" in err, err


def test_corrupt_checkpoint_is_refused(stopped, capsys):
    ck = stopped / "checkpoint.npz"
    ck.write_bytes(ck.read_bytes()[:1000])  # torn (it is written atomically, but disks lie)
    code, err = run_cli(capsys, stopped, "--end-time", str(T), "--resume")
    assert code == 2 and "cannot read checkpoint" in err and "--overwrite" in err, err


def test_resume_needs_a_later_end_time(stopped, capsys):
    code, err = run_cli(capsys, stopped, "--end-time", "0.08", "--resume")
    assert code == 2 and "--end-time" in err and "t = 0.08 s" in err, err


def test_resume_needs_a_checkpoint(tmp_path, capsys):
    out = tmp_path / "C"
    assert run_cli(capsys, out, "--end-time", "0.05")[0] == 0  # before the first checkpoint time
    code, err = run_cli(capsys, out, "--end-time", str(T), "--resume")
    assert code == 2 and "no checkpoint to resume from" in err and "checkpoint_interval" in err, err


def test_resume_with_other_thread_count_says_so(stopped, capsys):
    code, err = (
        cli.main(["run", "-o", str(stopped), *BASE[:2], "--threads", "2", *BASE[4:], "--end-time", "0.12", "--resume"]),
        capsys.readouterr().err,
    )
    assert code == 0, err
    assert "checkpoint was written with 1" in err and "--threads 1" in err, err


@pytest.mark.parametrize("method", ["ipsph", "pf", "dfsph"])
def test_state_dict_continues_bit_identically(method):
    """Simulation.state_dict() / load_state_dict(): a copy that later steps do not change, and a
    continuation in a fresh Simulation that matches the uninterrupted one bit for bit."""
    from ipsph.scene import default_scene_path
    from ipsph.simulation import Simulation

    over = ["simulation.particle_radius=0.04", f"simulation.method={method}"]
    a = Simulation.from_scene(default_scene_path(), over)
    for _ in range(3):
        a.step()
    state = a.state_dict()
    for _ in range(4):
        a.step()
    b = Simulation.from_scene(default_scene_path(), over)
    b.load_state_dict(state)
    assert b.steps == 3
    for _ in range(4):
        b.step()
    for name in ("positions", "velocities", "densities", "pressures", "ids"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (a.time, a.dt_next) == (b.time, b.dt_next)
