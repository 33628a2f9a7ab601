"""`ipsph sweep` on a real Dask LocalCluster on the loopback interface (issue 21).

Members are the coarse default dam break (378 fluid particles at r = 0.04, no renders). A 2-worker
sweep gives bit for bit the frames of separate `ipsph run --threads 1`s; a failing member is recorded
and the others run; a worker SIGKILLed mid-member has its member finished from the checkpoint its
dying child wrote; Ctrl-C stops every member with a checkpoint and `--resume` finishes exactly the
unfinished ones; a completed sweep reruns nothing.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest

pytest.importorskip("distributed")  # the test extra installs it: a missing one fails test_extra_is_installed

import ipsph
from ipsph import cli
from ipsph.io import RUN_JSON, RUN_PVD, vtu
from ipsph.io.pvd import PvdSeries
from ipsph.scene import default_scene_path
from ipsph.sweeps import engine, member, spec

END = 1.0  # 125 steps at dt_max = 8 ms: over 1 s of stepping left to stop a member in, a few seconds per member
SWEEP = f"""
scene = "dam.toml"
[set]
"simulation.particle_radius" = 0.04
"simulation.end_time" = {END}
"render.enabled" = false
"output.checkpoint_interval" = 0.1
[grid]
"simulation.method" = ["ipsph", "dfsph"]
[zip]
"simulation.viscosity" = [0.01, 0.02]
"simulation.density0" = [1000.0, 1010.0]
"""
NAMES = [
    "method-ipsph_viscosity-0.01_density0-1000.0",
    "method-ipsph_viscosity-0.02_density0-1010.0",
    "method-dfsph_viscosity-0.01_density0-1000.0",
    "method-dfsph_viscosity-0.02_density0-1010.0",
]


def test_extra_is_installed():
    import distributed  # noqa: F401  (pip install -e ".[test]" brings ipsph[sweep])


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("sweep")
    shutil.copy(default_scene_path(), d / "dam.toml")
    f = d / "study.toml"
    f.write_text(SWEEP)
    return f


@pytest.fixture(scope="module")
def references(sweep_file, tmp_path_factory) -> dict[str, Path]:
    """Each member as its own `ipsph run --threads 1` (in-process)."""
    refs = {}
    for m in spec.load_sweep(sweep_file).members:
        out = tmp_path_factory.mktemp("ref") / m.name
        args = ["run", str(sweep_file.parent / "dam.toml"), "-o", str(out), "--quiet", "--threads", "1"]
        for s in m.set_args():
            args += ["--set", s]
        assert cli.main(args) == 0
        refs[m.name] = out
    assert sorted(refs) == sorted(NAMES)
    return refs


@pytest.fixture(scope="module")
def swept(sweep_file, tmp_path_factory) -> tuple[Path, list[dict]]:
    out = tmp_path_factory.mktemp("swept") / "out"
    recs = ipsph.sweep(sweep_file, out, workers=2, threads_per_worker=1, dashboard_address="127.0.0.1:0")
    return out, recs


def assert_same_frames(ref: Path, got: Path, max_extra: int = 0) -> None:
    """Every frame of `ref` bit for bit in `got` (positions, every field, time); `got` may hold
    `max_extra` more (the final frame of an interrupted attempt stays in its series)."""
    fa, fb = dict(PvdSeries.load(ref / RUN_PVD).frames), dict(PvdSeries.load(got / RUN_PVD).frames)
    assert set(fa) <= set(fb) and len(fb) - len(fa) <= max_extra, (sorted(fa), sorted(fb))
    assert len(fa) == round(END * 25) + 1
    for t in fa:
        xa, da, ta = vtu.read_particles(ref / fa[t])
        xb, db, tb = vtu.read_particles(got / fb[t])
        assert ta == tb and np.array_equal(xa, xb), fa[t]
        assert set(da) == set(db) == {"velocity", "density", "pressure", "mass", "id"}
        assert all(np.array_equal(da[k], db[k]) for k in da), fa[t]


def run_json(folder: Path) -> dict:
    return json.loads((folder / RUN_JSON).read_text())


@pytest.mark.slow
def test_two_worker_sweep_equals_separate_runs(swept, references, capsys):
    out, recs = swept
    assert [r["name"] for r in recs] == NAMES
    assert all(r["status"] == "completed" and r["exit_code"] == 0 and r["threads"] == 1 for r in recs), recs
    assert len({r["worker_pid"] for r in recs}) == 2, "both workers should have run members"
    for r in recs:
        folder = out / r["name"]
        assert_same_frames(references[r["name"]], folder)
        # everything `ipsph run` writes (renders are off in this sweep)
        for f in ("run.pvd", "stats.csv", "run.json", "boundary.vtu", "boundary_surface.vtp", "checkpoint.npz"):
            assert (folder / f).is_file(), f
        assert run_json(folder)["completed"] and run_json(folder)["threads"] == 1
    saved = json.loads((out / "sweep.json").read_text())
    assert saved["counts"] == {"members": 4, "completed": 4}
    assert saved["scheduler"]["kind"] == "LocalCluster" and saved["scheduler"]["address"].startswith("tcp://127.0.0.1:")
    assert saved["grid"] == {"simulation.method": ["ipsph", "dfsph"]}
    assert saved["members"][3]["parameters"]["simulation.density0"] == 1010.0
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["member"] for r in rows] == NAMES
    for row, name in zip(rows, NAMES):
        info = run_json(out / name)
        assert row["status"] == "completed" and int(row["fluid_particles"]) == info["fluid_particles"] == 378
        assert int(row["steps"]) == info["steps"] > 0 and row["simulation.method"] == name.split("_")[0][7:]
        assert 0 < float(row["density_error_mean_pct"]) <= float(row["density_error_worst_pct"])
    # `ipsph plot OUT` overlays the members
    assert cli.main(["plot", str(out)]) == 0
    pngs = capsys.readouterr().out.split()
    assert sorted(Path(p).name for p in pngs) == ["errors_iterations.png", "timings.png"]
    assert all(Path(p).parent == out / "plots" and Path(p).stat().st_size > 10_000 for p in pngs)


@pytest.mark.slow
def test_rerunning_a_complete_sweep_does_nothing(swept, sweep_file, monkeypatch, capsys):
    out, _ = swept
    before = {n: (out / n / RUN_JSON).stat().st_mtime_ns for n in NAMES}
    monkeypatch.setattr(engine, "start_local_cluster", lambda *a, **k: pytest.fail("started a cluster"))
    assert cli.main(["sweep", str(sweep_file), "-o", str(out)]) == 0
    assert "all 4 members" in capsys.readouterr().err
    assert before == {n: (out / n / RUN_JSON).stat().st_mtime_ns for n in NAMES}


@pytest.mark.slow
def test_resume_reruns_only_what_is_missing(swept, sweep_file, references, tmp_path, capsys):
    out = tmp_path / "out"
    shutil.copytree(swept[0], out)
    gone = NAMES[2]
    shutil.rmtree(out / gone)
    before = {n: (out / n / RUN_JSON).stat().st_mtime_ns for n in NAMES if n != gone}
    assert cli.main(["sweep", str(sweep_file), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unfinished sweep (3 of 4 members completed); pass --resume to run the other 1" in err, err
    recs = ipsph.sweep(sweep_file, out, resume=True, workers=2, threads_per_worker=1, dashboard_address="127.0.0.1:0")
    assert all(r["status"] == "completed" for r in recs)
    assert before == {n: (out / n / RUN_JSON).stat().st_mtime_ns for n in NAMES if n != gone}
    assert_same_frames(references[gone], out / gone)
    # the sweep file changed: its members no longer match the folder
    changed = sweep_file.with_name("changed.toml")
    changed.write_text(SWEEP.replace("1010.0", "1020.0"))
    with pytest.raises(ValueError, match="holds a different sweep"):
        ipsph.sweep(changed, out, resume=True)


@pytest.mark.slow
def test_failing_member_does_not_stop_the_others(sweep_file, tmp_path):
    f = sweep_file.with_name("failing.toml")
    # the middle member leaves the tank at 900 m/s within a few steps: ipsph run exits 3
    f.write_text(
        'scene = "dam.toml"\n[set]\n"simulation.particle_radius" = 0.04\n"simulation.end_time" = 0.12\n'
        '"render.enabled" = false\n[zip]\n"fluid.0.velocity" = [[0, 0, 0], [900, 0, 0], [0, 0, -1]]\n'
    )
    code, recs = engine.run_sweep(
        f,
        engine.SweepOptions(
            out=tmp_path / "out", workers=1, threads_per_worker=1, progress=False, dashboard_address="127.0.0.1:0"
        ),
    )
    assert code == engine.EXIT_MEMBERS_FAILED
    assert [r["status"] for r in recs] == ["completed", "failed", "completed"], recs
    bad = recs[1]
    assert bad["exit_code"] == 3 and "left the domain" in bad["reason"], bad
    assert run_json(tmp_path / "out" / bad["name"])["status"] == "failed"
    saved = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert saved["counts"] == {"members": 3, "completed": 2, "failed": 1}
    assert saved["members"][1]["reason"] == bad["reason"]


@pytest.mark.slow
def test_local_cluster_listens_on_loopback_only():
    cluster = engine.start_local_cluster(2, 1, "127.0.0.1:0")
    try:
        procs = [psutil.Process()] + psutil.Process().children(recursive=True)
        conns = lambda p: (getattr(p, "net_connections", None) or p.connections)(kind="inet")  # noqa: E731 (psutil < 6)
        listening = [c.laddr for p in procs for c in conns(p) if c.status == psutil.CONN_LISTEN]
        assert len(listening) >= 2 + 2 + 1  # scheduler, 2 nannies, 2 workers, dashboard (at least)
        assert {a.ip for a in listening} == {"127.0.0.1"}, listening
        workers = cluster.scheduler_info["workers"]
        assert len(workers) == 2 and all(w["resources"] == {member.RESOURCE: 1} for w in workers.values())
    finally:
        cluster.close()


# -- faults in a separate `ipsph sweep` process ------------------------------------------------------
def start_sweep(sweep_file: Path, out: Path, *extra: str) -> subprocess.Popen:
    cmd = [
        sys.executable,
        "-m",
        "ipsph",
        "sweep",
        str(sweep_file),
        "-o",
        str(out),
        "--workers",
        "2",
        "--threads-per-worker",
        "1",
        "--dashboard-address",
        "127.0.0.1:0",
        *extra,
    ]
    # its own process group, like a shell job: a terminal's Ctrl-C goes to the whole group
    # (and SIGINT at its default: a shell starts background jobs, like this test run may be, with it ignored)
    return subprocess.Popen(
        cmd,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def wait_mid_run(out: Path, proc: subprocess.Popen, running: int, timeout: float = 180.0) -> list[str]:
    """Names of the first `running` members seen at least 5 steps into their run (not finished)."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        assert proc.poll() is None, proc.stderr.read()
        mid = []
        for n in NAMES:
            try:
                rows = (out / n / "stats.csv").read_text().count("\n") - 1
                done = run_json(out / n)["status"] != "running"
            except (OSError, ValueError, KeyError):
                continue
            if 5 <= rows and not done:
                mid.append(n)
        if len(mid) >= running:
            return mid
        time.sleep(0.05)
    pytest.fail("no member got under way")


def child_pid(folder: Path) -> int:
    return int((folder / member.PID_FILE).read_text().split()[0])


@pytest.mark.slow
def test_killed_worker_has_its_member_finished(sweep_file, references, tmp_path):
    out = tmp_path / "out"
    proc = start_sweep(sweep_file, out, "--quiet")
    try:
        victim = wait_mid_run(out, proc, 1)[0]
        worker = psutil.Process(child_pid(out / victim)).parent()
        assert "python" in worker.name() and worker.pid != proc.pid
        worker.kill()  # SIGKILL: the worker gets no say; its child gets SIGTERM from the kernel
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err
    recs = {r["name"]: r for r in json.loads((out / "sweep.json").read_text())["members"]}
    assert all(r["status"] == "completed" for r in recs.values()), recs
    assert recs[victim]["attempts"] == 2 and recs[victim]["resumed"], recs[victim]
    info = run_json(out / victim)
    assert info["completed"] and len(info["resumed"]) == 1
    for n in NAMES:  # the resumed member too: bit-identical continuation at the same thread count
        assert_same_frames(references[n], out / n, max_extra=1 if n == victim else 0)


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_and_resume_finishes(sweep_file, references, tmp_path):
    out = tmp_path / "out"
    proc = start_sweep(sweep_file, out)
    try:
        stopped = wait_mid_run(out, proc, 2)
        children = [child_pid(out / n) for n in stopped]
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in the terminal does
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert "--resume" in err.splitlines()[-1] or any("--resume" in ln for ln in err.splitlines()[-3:]), err
    for pid in children:  # no simulation is left running
        assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    recs = {r["name"]: r for r in json.loads((out / "sweep.json").read_text())["members"]}
    for n in stopped:
        assert recs[n]["status"] == "interrupted" and recs[n]["exit_code"] == 130, recs[n]
        assert run_json(out / n)["status"] == "interrupted" and (out / n / "checkpoint.npz").is_file()
    assert all(r["status"] in ("interrupted", "pending", "completed") for r in recs.values()), recs
    finished = {n: (out / n / RUN_JSON).stat().st_mtime_ns for n, r in recs.items() if r["status"] == "completed"}
    # the same command with --resume finishes the rest, continuing the stopped members from their checkpoints
    again = start_sweep(sweep_file, out, "--resume", "--quiet")
    _, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    recs = {r["name"]: r for r in json.loads((out / "sweep.json").read_text())["members"]}
    assert all(r["status"] == "completed" for r in recs.values()), recs
    assert finished == {n: (out / n / RUN_JSON).stat().st_mtime_ns for n in finished}
    for n in stopped:
        assert recs[n]["resumed"] and len(run_json(out / n)["resumed"]) == 1
    for n in NAMES:
        assert_same_frames(references[n], out / n, max_extra=1 if n in stopped else 0)


@pytest.mark.slow
def test_joins_an_existing_scheduler_and_uses_its_workers_threads(sweep_file, tmp_path):
    """--scheduler: a cluster the sweep did not start (here a 1-worker x 2-thread LocalCluster whose
    worker declares no ipsph_member resource): each member gets the worker's 2 threads, one at a time."""
    from distributed import LocalCluster

    f = sweep_file.with_name("two.toml")
    f.write_text(
        'scene = "dam.toml"\n[set]\n"simulation.particle_radius" = 0.04\n"simulation.end_time" = 0.08\n'
        '"render.enabled" = false\n[grid]\n"simulation.method" = ["pf", "dfsph"]\n'
    )
    with LocalCluster(
        n_workers=1, threads_per_worker=2, host="127.0.0.1", dashboard_address=None, memory_limit=0
    ) as cluster:
        out = tmp_path / "out"
        with pytest.raises(ValueError, match="--workers / --threads-per-worker size a LocalCluster"):
            ipsph.sweep(f, out, scheduler=cluster.scheduler_address, workers=2)
        recs = ipsph.sweep(f, out, scheduler=cluster.scheduler_address)
        assert len(cluster.scheduler_info["workers"]) == 1  # still up: the sweep leaves a cluster it joined
    assert [r["status"] for r in recs] == ["completed", "completed"]
    assert all(r["threads"] == 2 and run_json(out / r["name"])["threads"] == 2 for r in recs)
    saved = json.loads((out / "sweep.json").read_text())
    assert saved["scheduler"] == {"kind": "external", "address": cluster.scheduler_address, "worker_threads": [2]}
    # one member at a time on the one worker: their runs do not overlap
    (a, b) = [run_json(out / r["name"]) for r in recs]
    first, second = sorted((a, b), key=lambda i: i["started"])
    assert first["finished"] <= second["started"]


class FakeClient:
    def __init__(self, answers):
        self.answers = answers

    def run(self, fn, probe, token, on_error):
        # each "worker" answers as member.probe_folder would on its side of the filesystem
        return {addr: (fn(probe, token) if a == "real" else a) for addr, a in self.answers.items()}


@pytest.mark.slow
def test_shared_folder_check_names_a_worker_that_cannot_see_out(tmp_path):
    engine.check_shared_folder(FakeClient({"tcp://a:1": "real", "tcp://b:1": "real"}), tmp_path)
    assert list(tmp_path.iterdir()) == []  # the probe files are gone
    with pytest.raises(ValueError) as e:
        engine.check_shared_folder(
            FakeClient({"tcp://a:1": "real", "tcp://b:1": "FileNotFoundError: No such file"}), tmp_path
        )
    msg = str(e.value)
    assert "1 of 2 workers cannot use" in msg and "tcp://b:1" in msg and "shares" in msg and "\n" not in msg
    assert member.probe_folder(str(tmp_path / "missing"), "t").startswith("FileNotFoundError")
    (tmp_path / "p").write_text("other")
    assert "something else" in member.probe_folder(str(tmp_path / "p"), "t")
