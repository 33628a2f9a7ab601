"""Benchmark support: machine-load sampler and the SPlisHSPlasH peer runner.

The peer tests skip (with the reason) when pySPlisHSPlasH is not installed, which is the case in CI:
it is a benchmark peer, never a dependency.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import pytest

from ipsph.bench import machine
from ipsph.bench.machine import LoadSampler, load_sampler, machine_info, peak_rss_mb
from ipsph.errors import ConfigError

SCENES = Path(__file__).resolve().parent / "data" / "splishsplash" / "Scenes"


# ---------------------------------------------------------------------------------------------------
# machine.py
# ---------------------------------------------------------------------------------------------------
def test_load_sampler_fractions_are_sane():
    with load_sampler(interval=0.1) as sampler:
        time.sleep(0.45)
    s = sampler.summary()
    assert s.seconds >= 0.45  # slept 0.45 s (a loaded machine may delay the join, never shorten it)
    # at least the tail sample; at most one per full interval plus the tail (a starved sampler thread
    # takes fewer, so no lower count is asserted)
    assert 1 <= s.samples <= s.seconds / 0.1 + 1
    for x in (s.cpu_busy_mean, s.cpu_busy_max, s.others_busy_mean, s.others_busy_max):
        assert 0.0 <= x <= 1.0
    assert s.cpu_busy_mean <= s.cpu_busy_max + 1e-12
    assert s.others_busy_mean <= s.cpu_busy_mean + 1e-12  # others' share is part of the whole
    assert s.loadavg_max >= s.loadavg_mean >= 0.0
    assert s.cpus == os.cpu_count()
    assert set(s.as_dict()) >= {"loadavg_mean", "loadavg_max", "cpu_busy_mean", "others_busy_mean"}


def test_load_sampler_counts_own_work_as_busy_not_as_others():
    """Between two snapshots, the machine's busy jiffies are the busy fraction and this process's
    CPU seconds are taken out of them for others' share (the arithmetic, without the clock)."""
    hz = os.sysconf("SC_CLK_TCK")
    s = LoadSampler()
    # 10 s of jiffies summed over the CPUs, 6 s of them busy, 2 s of those ours (1 s in a child born since)
    s._record(((0, 0), {1: 5.0}), ((6 * hz, 10 * hz), {1: 5.0 + 1.0, 2: 1.0}))
    assert s._busy == [pytest.approx(0.6)] and s._others == [pytest.approx(0.4)]
    s._record(((0, 0), {1: 0.0}), ((1 * hz, 10 * hz), {1: 2.0}))  # more than all the busy time: clipped at 0
    assert s._others[-1] == 0.0


def test_load_sampler_sees_own_work():
    """Spinning this process shows as busy CPU (however little of a core a loaded machine gives it),
    and others' share never exceeds the whole."""
    with load_sampler(interval=0.2) as sampler:
        t_end = time.perf_counter() + 0.6
        while time.perf_counter() < t_end:
            pass
    s = sampler.summary()
    assert s.cpu_busy_mean > 0.0 and s.cpu_busy_max > 0.0
    assert s.others_busy_mean <= s.cpu_busy_mean + 1e-12


def test_load_sampler_short_run_still_gives_one_sample():
    s = LoadSampler(interval=5.0)
    s.start()
    time.sleep(0.15)  # > a few 10 ms jiffies so /proc/stat moves, far below the 5 s interval
    summary = s.stop()
    assert summary.samples == 1
    assert not math.isnan(summary.cpu_busy_mean)


def test_load_sampler_rejects_bad_interval():
    with pytest.raises(ValueError):
        LoadSampler(interval=0.0)


def test_proc_stat_parsing():
    stat = machine._read_proc_stat()
    if stat is None:
        pytest.skip("no /proc/stat on this platform")
    busy, total = stat
    assert 0 <= busy <= total


def test_peak_rss_and_machine_info():
    rss = peak_rss_mb()
    assert 5.0 < rss < 1e6  # a Python interpreter with numpy: tens of MiB, not bytes and not terabytes
    blob = bytearray(64 * 1024 * 1024)  # touch 64 MiB: the peak must grow by about that
    blob[::4096] = b"x" * len(blob[::4096])
    assert peak_rss_mb() >= rss or peak_rss_mb() >= 64.0
    del blob
    info = machine_info()
    assert info["logical_cores"] >= info["usable_cores"] >= 1
    assert isinstance(info["cpu_model"], str) and info["cpu_model"]
    assert info["memory_gb"] > 0.1


# ---------------------------------------------------------------------------------------------------
# peer.py (argument checks need no peer)
# ---------------------------------------------------------------------------------------------------
def test_peer_param_args_and_env():
    from ipsph.bench import peer

    args = peer._param_args(
        {
            "boundaryHandlingMethod": 0,
            "Fluid:viscosity": 0.01,
            "gravitation": [0, -9.81, 0],
            "enableDivergenceSolver": True,
        }
    )
    assert args == [
        "--param",
        "boundaryHandlingMethod:0",
        "--param",
        "Fluid:viscosity:0.01",
        "--param",
        "gravitation:0,-9.81,0",
        "--param",
        "enableDivergenceSolver:true",
    ]
    with pytest.raises(ConfigError):
        peer._param_args({"a:b:c": 1})
    env = peer.peer_env(3)
    assert env["OMP_NUM_THREADS"] == "3"
    assert str(peer._REPO_ROOT) in env["PYTHONPATH"].split(os.pathsep)
    assert (peer._REPO_ROOT / "ipsph" / "bench" / "peer.py").is_file()


def test_worker_scene_rewrite_keeps_stock_scene(tmp_path):
    """The rewritten scene has absolute mesh paths, the method, stopAt, no exports, and the overrides."""
    import json

    from ipsph.bench import _peer_worker as w

    src = tmp_path / "scenes" / "s.json"
    src.parent.mkdir()
    stock = {
        "Configuration": {"simulationMethod": 4, "enablePartioExport": True},
        "Materials": [{"id": "Fluid", "viscosity": 0.1}],
        "RigidBodies": [{"geometryFile": "../models/UnitBox.obj"}],
    }
    src.write_text(json.dumps(stock))
    params = w.parse_params(["boundaryHandlingMethod:0", "Fluid:viscosity:0.02", "gravitation:0,-1,0"])
    out = w.write_scene(src, tmp_path, "pf", 0.25, params)
    scene = json.loads(out.read_text())
    assert json.loads(src.read_text()) == stock
    conf = scene["Configuration"]
    assert conf["simulationMethod"] == 5 and conf["stopAt"] == 0.25
    assert conf["enablePartioExport"] is False and conf["enableVTKExport"] is False
    assert conf["boundaryHandlingMethod"] == 0 and conf["gravitation"] == [0, -1, 0]
    assert scene["Materials"][0]["viscosity"] == 0.02
    assert scene["RigidBodies"][0]["geometryFile"] == str(tmp_path / "models" / "UnitBox.obj")
    with pytest.raises(SystemExit):
        w.write_scene(src, tmp_path, "pf", 0.25, w.parse_params(["Water:viscosity:1"]))


def test_run_peer_rejects_bad_arguments(tmp_path):
    from ipsph.bench.peer import run_peer

    scene = tmp_path / "scene.json"  # argument checks come before the scene is read: any file will do
    scene.write_text("{}")
    with pytest.raises(ConfigError, match="not a file"):
        run_peer(tmp_path / "missing.json", "dfsph", 0.1, 1)
    with pytest.raises(ConfigError, match="unknown"):
        run_peer(scene, "sph", 0.1, 1)
    with pytest.raises(ConfigError, match="end_time"):
        run_peer(scene, "dfsph", 0.0, 1)
    with pytest.raises(ConfigError, match="threads"):
        run_peer(scene, "dfsph", 0.1, 0)


# ---------------------------------------------------------------------------------------------------
# peer.py against the real SPlisHSPlasH (skipped unless installed)
# ---------------------------------------------------------------------------------------------------
def _require_peer():
    from ipsph.bench.peer import peer_available

    ok, why = peer_available()
    if not ok:
        pytest.skip(f"SPlisHSPlasH peer not available: {why}")


def test_peer_available_reports_a_reason():
    from ipsph.bench.peer import peer_available

    ok, why = peer_available()
    assert isinstance(ok, bool) and isinstance(why, str) and why
    assert peer_available() is peer_available()  # cached


@pytest.mark.parametrize("method", ["dfsph", "pf"])
def test_peer_short_double_dam_break(method):
    """DoubleDamBreak for 0.05 s with Akinci boundary particles (fast init: no volume map to build)."""
    _require_peer()
    from ipsph.bench.peer import run_peer

    r = run_peer(
        SCENES / "DoubleDamBreak.json", method, 0.05, threads=2, params={"boundaryHandlingMethod": 0}, timeout=600
    )
    assert r["fluid_particles"] == 4732  # two 0.7 x 0.75 x 0.7 m blocks at r = 0.025 m (SPlisHSPlasH's count)
    assert r["boundary_particles"] > 10_000  # a 3.1 m box sampled at ~r spacing: tens of thousands
    assert r["boundary_handling_method"] == 0
    assert r["time_step_class"] == {"dfsph": "TimeStepDFSPH", "pf": "TimeStepPF"}[method]
    assert r["completed"] and r["sim_time"] >= 0.05 - 1e-6
    # CFL cap 5 ms: at least 10 steps to reach 0.05 s; PF's adaptive steps may be smaller
    assert 10 <= r["steps"] <= 1000
    assert 0.0 < r["dt_min"] <= r["dt_max"] <= 0.005 + 1e-7
    assert r["ms_per_step"] > 0 and r["wall_seconds"] > 0 and r["init_seconds"] >= 0
    # the blocks are in free fall for the first 0.05 s: density error is tiny, never above 1 %
    assert 0.0 <= r["density_error_mean_pct"] <= r["density_error_worst_pct"] < 1.0
    assert r["density_error_nonfinite_steps"] == 0
    assert r["step_ms"] > 0 and r["pressure_solve_ms"] > 0 and r["neighborhood_search_ms"] > 0
    assert 10.0 < r["peak_rss_mb"] < 8000.0
    assert r["threads"] == 2
    # the fluid stays in the 3.1 m box centred at (0, 1.5, 0); one particle radius (0.025 m) of slack
    (x0, y0, z0), (x1, y1, z1) = r["fluid_bbox_end"]
    assert -1.575 <= min(x0, z0) and max(x1, z1) <= 1.575 and -0.075 <= y0 and y1 <= 3.075
    assert r["load"]["samples"] >= 1 and 0.0 <= r["load"]["cpu_busy_mean"] <= 1.0


def test_peer_runs_the_scaling_dam_break(tmp_path):
    """`ipsph bench --scaling`'s SPlisHSPlasH rows: its copy of our dam break holds our fluid count
    (the shared FluidBlocks rule), Akinci walls, and takes its 5 ms maximum step from rest."""
    _require_peer()
    from ipsph.bench.peer import run_peer
    from ipsph.bench.scenes import scaling_count, scaling_peer_scene

    n = 3000
    r = run_peer(scaling_peer_scene(n, tmp_path), "dfsph", 4 * 0.005 * (1 + 1e-6), threads=2, timeout=600)
    assert r["fluid_particles"] == scaling_count(n)
    assert r["boundary_handling_method"] == 0 and r["boundary_particles"] > 1000
    assert r["steps"] in (4, 5) and r["dt_max"] == pytest.approx(0.005)
    # our XSPH coefficient and no viscosity model (2.19 reads both from their named blocks)
    assert r["solver"]["viscosity_model"] == "None" and r["solver"]["xsph"] == pytest.approx(0.01)
    (x0, y0, z0), (x1, y1, z1) = r["fluid_bbox_end"]
    assert min(x0, y0, z0) > 0.0  # still inside the tank's corner where the column stands


def test_peer_failure_raises_with_stderr_tail(tmp_path):
    _require_peer()
    from ipsph.bench.peer import run_peer

    bad = tmp_path / "bad.json"
    bad.write_text('{"Configuration": {}, "RigidBodies": [{"geometryFile": "nope.obj"}]}')
    with pytest.raises(RuntimeError, match="SPlisHSPlasH peer failed"):
        run_peer(bad, "dfsph", 0.01, threads=1, timeout=120)


def test_peer_unavailable_is_reported_not_raised(monkeypatch, tmp_path):
    """Without pySPlisHSPlasH (as in CI): peer_available says why, run_peer raises RuntimeError."""
    from ipsph.bench import peer

    peer.peer_available.cache_clear()
    monkeypatch.setattr(peer.importlib.util, "find_spec", lambda name, *a: None)
    try:
        ok, why = peer.peer_available()
        assert not ok and "not installed" in why
        with pytest.raises(RuntimeError, match="unavailable"):
            scene = tmp_path / "scene.json"
            scene.write_text("{}")
            peer.run_peer(scene, "dfsph", 0.01, 1)
    finally:
        peer.peer_available.cache_clear()
