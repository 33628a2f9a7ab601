"""Gauges (issue 36): [[gauge]] tables sampled into gauges.csv during a run and measured on a finished
run's frames (`ipsph gauge`). Short runs at coarse radii; every tolerance is named and justified
where it is declared. The CLI runs in-process (`cli.main`) as in tests/test_cli_errors.py."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from ipsph import cli
from ipsph.gauges import kernels
from ipsph.gauges.log import Schedule, read_gauges
from ipsph.gauges.recorder import GaugeLog
from ipsph.gauges.sampler import Gauges
from ipsph.io import RUN_JSON
from ipsph.scene import scene_from_dict
from ipsph.simulation import Simulation

REPO = Path(__file__).resolve().parents[1]
G, RHO0 = 9.81, 1000.0

# --- tolerances ------------------------------------------------------------------------------------
# Issue 36's acceptance on a tank at rest (means over the last 0.5 s of 1 s, the gauges sampled every
# step): a pressure gauge at mid-depth within 2 % of rho0 g depth, the level gauge within 0.25 d of the
# free surface (the top layer's mean height + r), the vertical force on the tank within 1 % of the
# water's weight. IPSPH misses two of them, measured and kept as expected failures (below).
TANK_PRESSURE_TOL = 0.02
TANK_LEVEL_TOL_D = 0.25
TANK_FORCE_TOL = 0.01
# Issue 36: in-run and after-the-fact values at frame times. Both read the fluid at the frames' float32
# precision through the same code in the same order, so they are equal bit for bit on static walls;
# moving walls' positions are recomputed from their poses after the run (a rounding apart), hence a
# tolerance relative to each column's largest magnitude.
AGREE_REL = 1e-9
# A pressure gauge on the far wall of the coarse dam break sampled every step: its impact peak (24 kPa
# here, 4 ms wide) against the largest value at the 25 fps frame times (11 kPa, 11 ms after the peak).
# Half again as high is the least "a peak the frames miss" means; the run is deterministic (one thread).
PEAK_OVER_FRAMES = 1.5
# Shepard interpolation of a linear field inside a complete lattice: exact at lattice points, off them
# the cubic spline's first moment over the lattice is not quite zero at H = 2d: measured 3.1e-3 of the
# field's change over H at worst (900 random points, 3 gradients); 0.1 % of a hydrostatic mid-depth reading.
LINEAR_FIELD_TOL = 5e-3
# A uniform flow u through a rectangle across a lattice block: the plane integrals of the cubic spline
# over rows spaced d = H/2 sum to exactly 1 for any offset (its B-spline partition of unity), so what is
# left is the frames' float32 rounding of masses and velocities (6e-8 each).
FLOW_TOL = 1e-6


def scene_dict(**extra) -> dict:
    d = {
        "simulation": {"particle_radius": 0.04, "end_time": 0.4},
        "fluid": [{"name": "column", "box": {"min": [0, 0, 0], "max": [0.6, 0.8, 0.6]}}],
        "boundary": [{"name": "tank", "box": {"min": [0, 0, 0], "max": [1.6, 1.2, 0.6]}}],
        "render": {"enabled": False},
    }
    d.update(extra)
    return d


def toml_file(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


DAM = """
[simulation]
particle_radius = 0.04
end_time = 0.4

[[fluid]]
name = "column"
box = { min = [0.0, 0.0, 0.0], max = [0.6, 0.8, 0.6] }

[[boundary]]
name = "tank"
box = { min = [0.0, 0.0, 0.0], max = [1.6, 1.2, 0.6] }

[render]
enabled = false
"""
GAUGES = """
[[gauge]]
name = "wall"
kind = "point"
position = [1.58, 0.1, 0.3]

[[gauge]]
name = "lvl"
kind = "level"
position = [0.3, 0.0, 0.3]
top = 1.1

[[gauge]]
name = "tank"
kind = "force"
wall = "tank"

[[gauge]]
name = "q"
kind = "flow"
min = [0.8, 0.0, 0.0]
max = [0.8, 1.2, 0.6]
"""


def run_cli(capsys, *args) -> tuple[int, str]:
    code = cli.main([*map(str, args)])
    return code, capsys.readouterr().err


@pytest.fixture(autouse=True)
def _threads():
    import numba

    n = numba.get_num_threads()
    yield
    numba.set_num_threads(n)


# -- bad input: exit 2 naming the key, before anything is created -----------------------------------
@pytest.mark.parametrize(
    "table, expect",
    [
        ('kind = "pint"\nposition = [0.3, 0.3, 0.3]', "gauge[0].kind: a string ('pint') is not one of"),
        ('kind = "point"\nposition = [0.3, 0.3, 0.3]\nquantities = ["level"]', "gauge[0].quantities[0]: 'level'"),
        ('kind = "point"\nposition = [0.3, 0.3, 0.3]\nquantities = ["presure"]', "gauge[0].quantities[0]"),
        ('kind = "point"\nposition = [nan, 0.3, 0.3]', "gauge[0].position[0]: expected a finite number"),
        (
            'kind = "point"\nposition = [3.0, 0.3, 0.3]',
            "gauge[0].position: [3, 0.3, 0.3] of gauge 'gauge0' lies outside",
        ),
        ('kind = "level"\nposition = [0.3, 0.0, 0.3]\ntop = 2.0', "gauge[0].top: [0.3, 2, 0.3]"),
        ('kind = "force"\nwall = "tnak"', "gauge[0].wall: 'tnak' names no [[boundary]]"),
        ('kind = "flow"\nmin = [0.8, 0.0, 0.0]\nmax = [0.8, 0.0, 0.6]', "gauge[0].max: min [0.8, 0, 0] and max"),
        ('kind = "flow"\nmin = [0.8, 0.0, 0.0]\nmax = [0.8, 0.5, 0.6]\nwall = "tank"', "gauge[0].wall: does not apply"),
        ('kind = "level"\nposition = [0.3, 0.5, 0.3]\ntop = 0.2', "gauge[0].top: 0.2 m is not above"),
        ('kind = "point"', "gauge[0].position: missing"),
        (
            'name = "p 1, left"\nkind = "point"\nposition = [0.3, 0.3, 0.3]',
            "gauge[0].name: 'p 1, left': a gauge's name",
        ),
    ],
)
def test_bad_gauges_exit_2_naming_the_key_before_any_output(tmp_path, capsys, table, expect):
    s = toml_file(tmp_path, DAM + "\n[[gauge]]\n" + table + "\n")
    out = tmp_path / "out"
    code, err = run_cli(capsys, "run", s, "-o", out, "--quiet", "--no-render", "--threads", "1")
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("ipsph: error:") and expect in line, line
    assert not out.exists(), "a refused run creates nothing"


def test_ipsph_gauge_refuses_bad_tables_before_writing(tmp_path, capsys, dam_break):
    g = toml_file(tmp_path, '[[gauge]]\nkind = "force"\nwall = "nowhere"\n', "g.toml")
    code, err = run_cli(capsys, "gauge", dam_break, "--scene", g, "-o", tmp_path / "g.csv")
    assert code == 2 and "g.toml: gauge[0].wall: 'nowhere' names no [[boundary]]" in err, err
    assert not (tmp_path / "g.csv").exists()


# -- the numerics on lattices (no stepping) ----------------------------------------------------------
def lattice(n=(10, 10, 10), d=0.04, lo=(0.0, 0.0, 0.0)):
    idx = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    return np.asarray(lo) + (idx + 1) * d


def test_point_gauge_interpolates_a_linear_field_and_reports_nan_when_dry():
    r = 0.02
    x = lattice()
    p = 1000.0 + 5000.0 * x[:, 1] - 300.0 * x[:, 0]
    v = np.zeros_like(x)
    rho, m = np.full(len(x), RHO0), np.full(len(x), RHO0 * (2 * r) ** 3)
    scene = scene_from_dict(
        {
            "simulation": {"particle_radius": r},
            "fluid": [{"box": {"min": [0, 0, 0], "max": [0.44, 0.44, 0.44]}}],
            "gauge": [
                {"kind": "point", "position": [0.2131, 0.1877, 0.2219]},
                {"kind": "point", "position": [0.2, 1.0, 0.2]},
            ],
        }  # fmt: skip
    )
    g = Gauges(scene)
    vals = g.values(0.0, x, v, rho, p, m)
    expect = 1000.0 + 5000.0 * 0.1877 - 300.0 * 0.2131
    assert abs(vals[0] - expect) <= LINEAR_FIELD_TOL * 5000.0 * scene.support, (vals[0], expect)
    assert abs(vals[4] - RHO0) < 1e-6 * RHO0 and vals[1:4] == [0.0, 0.0, 0.0]
    assert np.all(np.isnan(vals[5:])), "a point in the air reports NaN"
    assert "NaN where fewer than 4 fluid particles" in g.columns[5].note


@pytest.mark.parametrize("offset", [0.0, 0.37, 0.5])
def test_flow_gauge_measures_a_uniform_stream(offset):
    r, u = 0.02, 1.5
    d = 2 * r
    x = lattice((20, 8, 6), d)
    plane = 0.4 + offset * d
    v = np.tile([u, 0.0, 0.0], (len(x), 1))
    rho, m = np.full(len(x), RHO0), np.full(len(x), RHO0 * d**3)
    scene = scene_from_dict(
        {
            "simulation": {"particle_radius": r},
            "fluid": [{"box": {"min": [0, 0, 0], "max": [0.8, 0.4, 0.4]}}],
            "gauge": [{"kind": "flow", "min": [plane, 0.0, 0.0], "max": [plane, 1.0, 1.0]}],
        }  # fmt: skip
    )
    (q,) = Gauges(scene).values(0.0, x, v, rho, np.zeros(len(x)), m)
    area = 8 * 6 * d * d  # the rows of particles crossing the plane
    assert abs(q / (u * area) - 1.0) < FLOW_TOL, q / (u * area)


def test_plane_kernel_integrates_to_one():
    h = 0.08
    s = np.linspace(-h, h, 20001)
    f = np.array([kernels.plane_kernel(si, h) for si in s])
    assert abs(np.trapezoid(f, s) - 1.0) < 1e-6 and f[0] == 0.0 and f[-1] == 0.0


def test_schedule_samples_at_each_interval_and_resumes_where_it_stopped():
    s = Schedule([None, 0.1])
    times = [0.0, 0.03, 0.07, 0.1 - 1e-13, 0.12, 0.25, 0.31]
    due = [sorted(s.due(t)) for t in times]
    assert due == [[0, 1], [0], [0], [0, 1], [0], [0, 1], [0, 1]]
    resumed = Schedule([None, 0.1], t=0.25, sampled=True)
    assert sorted(resumed.due(0.31)) == [0, 1] and sorted(resumed.due(0.35)) == [0]


# -- a tank at rest: issue 36's acceptance -----------------------------------------------------------
TANK_R = 0.04  # 252 particles: 1 s of the tank in about 10 s (DFSPH) and 20 s (IPSPH) on one core
MID_Y = 0.25  # the settled water stands 0.50 m deep


def run_tank(method: str) -> dict:
    scene = scene_from_dict(
        {
            "simulation": {"method": method, "particle_radius": TANK_R, "end_time": 1.0},
            "time_step": {"dt_max": 0.005},
            "fluid": [{"box": {"min": [0, 0, 0], "max": [0.6, 0.6, 0.6]}}],
            "boundary": [{"name": "tank", "box": {"min": [0, 0, 0], "max": [0.6, 1.0, 0.6]}}],
            "gauge": [
                {"name": "mid", "kind": "point", "position": [0.3, MID_Y, 0.3], "quantities": ["pressure"]},
                {"name": "lvl", "kind": "level", "position": [0.3, 0.0, 0.3], "top": 1.0},
                {"name": "tank", "kind": "force", "wall": "tank", "quantities": ["force"]},
            ],
        }
    )
    sim = Simulation.from_scene(scene)
    log = GaugeLog(sim)
    sim.run(on_step=log.on_step)
    a = log.arrays()
    last = a["time"] >= 0.5
    y = np.sort(sim.positions[:, 1])
    top_layer = y[y > y[-1] - TANK_R]  # the particles of the top lattice layer
    return {
        "level": a["lvl.level"][last].mean(),
        "surface": top_layer.mean() + TANK_R,
        "pressure": a["mid.pressure"][last].mean(),
        "fy": a["tank.fy_pressure"][last].mean(),
        "weight": sim.n_fluid * scene.fluid_mass * G,
    }


_TANKS: dict = {}


def tank(method):
    if method not in _TANKS:
        _TANKS[method] = run_tank(method)
    return _TANKS[method]


# IPSPH's own pressure field is ~3 % above hydrostatic in the settled tank (tests/test_physics.py
# PRESSURE_SLOPE_TOL: +3.7 to +4.1 % on the 4 s tank), and the gauge reads it faithfully (the lattice
# test above): measured +4.5 % here. Its wall force reads the pressure field through Akinci's term, not
# the PF multipliers the step applied (step noise 5 % std): measured -1.7 % over the last 0.5 s. At
# r = 0.02 m (2,744 particles, 2 s; too long for this suite) IPSPH meets both (+1.7 %, -0.9 %), while
# DFSPH's pressure reads +2.3 % (docs/gauges.md, "Accuracy").
IPSPH_MISSES = {
    "pressure": "IPSPH's pressure field sits +4.5 % above rho0 g depth at mid-depth (the solver's, read faithfully)",
    "force": "IPSPH's wall force from its pressure field reads -1.7 % of the weight (step noise 5 % std)",
}


# DFSPH's pressure field in the same tank read +0.96 % when the test was written, +3.3 % on numba
# 0.68.1 / llvmlite 0.50 from d0ad209 (bit-identical commits: the settled trajectory moves with the
# compiler's and the CPU's rounding, not with the code) and +0.7 % on the machine of 2026-12-08 (then
# it xpasses); issue 42 tracks it.
DFSPH_MISSES = {
    "pressure": "DFSPH's pressure field sits +3.3 % above rho0 g depth at mid-depth on numba 0.68.1 (issue 42)",
}


def _method(what):
    dfsph = "dfsph"
    if what in DFSPH_MISSES:
        dfsph = pytest.param("dfsph", marks=pytest.mark.xfail(reason=DFSPH_MISSES[what], strict=False))
    return [dfsph, pytest.param("ipsph", marks=pytest.mark.xfail(reason=IPSPH_MISSES[what], strict=False))]


@pytest.mark.parametrize("method", ["dfsph", "ipsph"])
def test_tank_level_gauge_finds_the_free_surface(method):
    t = tank(method)
    assert abs(t["level"] - t["surface"]) <= TANK_LEVEL_TOL_D * 2 * TANK_R, t


@pytest.mark.parametrize("method", _method("pressure"))
def test_tank_pressure_gauge_reads_hydrostatic_at_mid_depth(method):
    t = tank(method)
    hydrostatic = RHO0 * G * (t["level"] - MID_Y)
    assert abs(t["pressure"] / hydrostatic - 1.0) <= TANK_PRESSURE_TOL, (t["pressure"], hydrostatic)


@pytest.mark.parametrize("method", _method("force"))
def test_tank_force_gauge_carries_the_weight(method):
    t = tank(method)
    assert abs(-t["fy"] / t["weight"] - 1.0) <= TANK_FORCE_TOL, (t["fy"], t["weight"])


# -- a dam break: in-run against after-the-fact, the impact peak ------------------------------------
@pytest.fixture(scope="module")
def dam_break(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("gauges")
    s = tmp / "dam.toml"
    s.write_text(DAM + GAUGES)
    out = tmp / "out"
    assert cli.main(["run", str(s), "-o", str(out), "--quiet", "--no-render", "--threads", "1"]) == 0
    return out


def frame_rows(run: dict, frames: dict) -> tuple[dict, dict]:
    """The in-run rows at the frame times, and the after-the-fact rows, column by column."""
    at = [int(np.flatnonzero(run["time"] == t)[0]) for t in frames["time"]]
    return {k: v[at] for k, v in run.items()}, frames


def assert_agree(run: dict, frames: dict, skip=()) -> None:
    a, b = frame_rows(run, frames)
    for k in a:
        if k in skip:
            continue
        scale = np.nanmax(np.abs(run[k])) if np.any(np.isfinite(run[k])) else 0.0
        same_nan = np.array_equal(np.isnan(a[k]), np.isnan(b[k]))
        diff = np.nanmax(np.abs(a[k] - b[k])) if np.any(np.isfinite(a[k])) else 0.0
        assert same_nan and diff <= AGREE_REL * scale, (k, diff, scale)


def test_run_writes_gauges_csv_lists_it_and_plots_it(dam_break):
    info = json.loads((dam_break / RUN_JSON).read_text())
    cols = info["gauges"]["columns"]
    assert info["gauges"]["file"] == "gauges.csv" and cols[0]["name"] == "time"
    header = (dam_break / "gauges.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["time [s]", "wall.pressure [Pa]", "wall.vx [m/s]"] and len(header) == len(cols)
    assert "tank.fy_pressure [N]" in header and "q.flow [m^3/s]" in header and "lvl.level_max [m]" in header
    assert all(c["note"] for c in cols) and info["gauges"]["plot"] == "plots/gauges.png"
    assert (dam_break / "plots" / "gauges.png").stat().st_size > 10_000
    stats = np.loadtxt(dam_break / "stats.csv", delimiter=",", skiprows=1, usecols=1, ndmin=1)
    g = read_gauges(dam_break / "gauges.csv")
    assert np.array_equal(g["time"], np.concatenate([[0.0], stats])), "one row at t = 0 and one per step"


def test_overwrite_removes_the_gauges_of_the_earlier_run(tmp_path, capsys):
    s = toml_file(tmp_path, DAM.replace("end_time = 0.4", "end_time = 0.04") + GAUGES)
    out = tmp_path / "out"
    args = ["-o", out, "--quiet", "--no-render", "--threads", "1"]
    assert run_cli(capsys, "run", s, *args)[0] == 0
    assert run_cli(capsys, "gauge", out)[0] == 0 and (out / "gauges_frames.csv").is_file()
    plain = toml_file(tmp_path, DAM.replace("end_time = 0.4", "end_time = 0.04"), "plain.toml")
    assert run_cli(capsys, "run", plain, *args, "--overwrite")[0] == 0
    assert not (out / "gauges.csv").exists() and not (out / "gauges_frames.csv").exists()
    assert "gauges" not in json.loads((out / RUN_JSON).read_text())


def test_after_the_fact_gauges_agree_with_the_run_at_frame_times(dam_break, capsys):
    code, err = run_cli(capsys, "gauge", dam_break)
    assert code == 0, err
    run, frames = read_gauges(dam_break / "gauges.csv"), read_gauges(dam_break / "gauges_frames.csv")
    assert len(frames["time"]) == 11 and list(run) == list(frames)
    # level_max is the highest of the series' own samples: every step in the run, the frames after it
    assert_agree(run, frames, skip=("lvl.level_max",))
    a, b = frame_rows(run, frames)
    for k in a:  # static walls: not merely close, the same numbers
        if k != "lvl.level_max":
            assert np.array_equal(a[k], b[k], equal_nan=True), k
    assert (dam_break / "plots" / "gauges_frames.png").is_file()


def test_every_step_pressure_gauge_catches_the_impact_the_frames_miss(dam_break):
    g = read_gauges(dam_break / "gauges.csv")
    at_frames = np.isclose(g["time"] / 0.04, np.round(g["time"] / 0.04), atol=1e-9)
    p = g["wall.pressure"]
    peak, framed = np.nanmax(p), np.nanmax(p[at_frames])
    assert peak >= PEAK_OVER_FRAMES * framed, (peak, framed)


def test_ipsph_gauge_takes_new_gauges_for_an_old_run(dam_break, tmp_path, capsys):
    g = toml_file(tmp_path, '[[gauge]]\nname = "front"\nkind = "level"\nposition = [1.0, 0.0, 0.3]\ntop = 1.0\n')
    code, err = run_cli(capsys, "gauge", dam_break, "--scene", g, "-o", tmp_path / "front.csv")
    assert code == 0, err
    front = read_gauges(tmp_path / "front.csv")
    assert list(front) == ["time", "front.level", "front.level_max"]
    assert np.isnan(front["front.level"][0]) and np.nanmax(front["front.level"]) > 0.05, "dry, then the front passes"


# -- moving walls and rigid bodies ----------------------------------------------------------------
def test_force_gauges_on_a_paddle_and_a_crate_agree_after_the_run(tmp_path, capsys):
    from test_moving_walls import paddle_and_crate

    from ipsph.run.runner import RunOptions, run

    d = paddle_and_crate(0.05, ([0.2, 0.25, 0.1], [0.4, 0.35, 0.3]))
    d["simulation"]["end_time"] = 0.2
    d["gauge"] = [
        {"name": "paddle", "kind": "force", "wall": "paddle"},
        {"name": "crate", "kind": "force", "wall": "crate", "point": [0.3, 0.3, 0.2]},
    ]
    out = tmp_path / "out"
    assert run(scene_from_dict(d), RunOptions(out_dir=out, render=False, threads=1, progress=False)) == 0
    code, err = run_cli(capsys, "gauge", out)
    assert code == 0, err
    run_rows, frames = read_gauges(out / "gauges.csv"), read_gauges(out / "gauges_frames.csv")
    assert_agree(run_rows, frames)
    assert np.nanmax(np.abs(run_rows["paddle.fx_pressure"])) > 1.0, "the paddle pushes water"
    assert np.nanmax(np.abs(run_rows["crate.fy_pressure"])) > 1.0, "the water carries the crate"


# -- resume and kill -9 ---------------------------------------------------------------------------
RESUME = ["--quiet", "--no-render", "--threads", "1", "--set", "output.checkpoint_interval=0.08"]


def test_resume_neither_repeats_nor_loses_rows(tmp_path, capsys):
    s = tmp_path / "dam.toml"
    s.write_text(DAM + GAUGES.replace("top = 1.1", "top = 1.1\ninterval = 0.03"))
    a, b = tmp_path / "A", tmp_path / "B"
    assert run_cli(capsys, "run", s, "-o", a, *RESUME, "--end-time", "0.24")[0] == 0
    assert run_cli(capsys, "run", s, "-o", b, *RESUME, "--end-time", "0.1")[0] == 0  # checkpoint at 0.08
    code, err = run_cli(capsys, "run", s, "-o", b, *RESUME, "--end-time", "0.24", "--resume")
    assert code == 0, err
    assert (a / "gauges.csv").read_text() == (b / "gauges.csv").read_text(), "resumed: the same rows, once"


def test_kill_9_leaves_a_valid_csv_and_resume_carries_on(tmp_path, capsys):
    s = tmp_path / "dam.toml"
    s.write_text(DAM.replace("end_time = 0.4", "end_time = 3.0") + GAUGES)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ipsph", "run", str(s), "-o", str(out), *RESUME]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    while not (out / "frames" / "fluid_000003.vtu").exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 120, "no frames"
        time.sleep(0.05)
    time.sleep(0.13)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=30)
    lines = (out / "gauges.csv").read_text().splitlines(keepends=True)
    width = lines[0].count(",")
    assert all(ln.endswith("\n") and ln.count(",") == width for ln in lines[:-1]), "whole rows up to the last"
    killed = read_gauges(out / "gauges.csv")
    assert len(killed["time"]) >= 3 and np.all(np.diff(killed["time"]) > 0)
    ck = json.loads((out / RUN_JSON).read_text())
    assert ck["status"] == "running"
    end = float(killed["time"][-1]) + 0.08
    code, err = run_cli(capsys, "run", s, "-o", out, *RESUME, "--end-time", f"{end:.2f}", "--resume")
    assert code == 0, err
    after = read_gauges(out / "gauges.csv")
    stats = np.loadtxt(out / "stats.csv", delimiter=",", skiprows=1, usecols=1, ndmin=1)
    assert np.array_equal(after["time"], np.concatenate([[0.0], stats])), "one row per step, none twice"


# -- the viscous part: a slab sliding into a wall -------------------------------------------------
# The force on the tank's walls over 0.1 s against the fluid's loss of x momentum (the only
# external x force is the walls'; XSPH conserves momentum): IPSPH's pressure plus viscous part
# account for it within 3 % (measured 1.03 of it, no-slip walls, implicit viscosity nu = 0.01).
# 10 %: the gauge reads the end-of-step fields, the step applied its impulses along the way.
# DFSPH's frames carry its density solve's pressure only (p = k_dens rho^2): the divergence solve's
# share, most of an impact's impulse, is in neither its frames nor its gauges (measured 0.77).
MOMENTUM_TOL = 0.10


def sliding_slab(method: str, walls: str = "no-slip") -> dict:
    return {
        "simulation": {
            "method": method,
            "particle_radius": 0.02,
            "end_time": 0.1,
            "viscosity_model": "implicit",
            "kinematic_viscosity_m2s": 0.01,
            "viscosity_walls": walls,
        },
        "fluid": [{"box": {"min": [0, 0, 0], "max": [0.8, 0.12, 0.4]}, "velocity": [0.5, 0, 0]}],
        "boundary": [{"name": "tank", "box": {"min": [0, 0, 0], "max": [0.8, 0.5, 0.4]}}],
        "gauge": [{"name": "f", "kind": "force", "wall": "tank", "quantities": ["force"]}],
    }


@pytest.mark.parametrize(
    "method",
    [
        "ipsph",
        pytest.param(
            "dfsph",
            marks=pytest.mark.xfail(
                reason="DFSPH's frames lack the divergence solve's pressure (0.77 of the impulse)", strict=False
            ),
        ),
    ],
)
def test_force_gauge_accounts_for_the_momentum_the_walls_take(method):
    sim = Simulation.from_scene(sliding_slab(method))
    log = GaugeLog(sim)
    px = [float(sim.masses @ sim.velocities[:, 0])]
    dts = []

    def on_step(s):
        log.sample()
        px.append(float(sim.masses @ sim.velocities[:, 0]))
        dts.append(s.dt)

    sim.run(on_step=on_step)
    g = log.arrays()
    assert np.all(g["f.fx_viscous"][1:6] > 0.0), "the slab drags the tank along"
    impulse = np.sum(np.array(dts) * (g["f.fx_pressure"] + g["f.fx_viscous"])[1:])  # on the walls
    assert abs((px[0] - px[-1]) / impulse - 1.0) <= MOMENTUM_TOL, (px[0] - px[-1], impulse)


def test_viscous_columns_only_where_walls_have_friction():
    free = Gauges(scene_from_dict(sliding_slab("ipsph", "free-slip")), walls=_NoWalls())
    sticky = Gauges(scene_from_dict(sliding_slab("ipsph")), walls=_NoWalls())
    assert [c.quantity for c in free.columns] == ["fx_pressure", "fy_pressure", "fz_pressure"]
    assert [c.quantity for c in sticky.columns][3:] == ["fx_viscous", "fy_viscous", "fz_viscous"]


class _NoWalls:
    def centre(self, name):
        return np.zeros(3)


# -- the Python API ---------------------------------------------------------------------------------
def test_python_api_gives_arrays():
    d = scene_dict(gauge=[{"name": "lvl", "kind": "level", "position": [0.3, 0.0, 0.3], "top": 1.1, "interval": 0.05}])
    d["simulation"]["end_time"] = 0.1
    sim = Simulation.from_scene(d)
    log = GaugeLog(sim)
    sim.run(on_step=log.on_step)
    a = log.arrays()
    assert list(a) == ["time", "lvl.level", "lvl.level_max"]
    sampled = np.flatnonzero(np.isfinite(a["lvl.level"]))  # every 0.05 s: the first step at or after each
    t = a["time"]
    assert len(sampled) == 3 and t[sampled[0]] == 0.0 and t[sampled[-1]] == 0.1
    assert t[sampled[1] - 1] < 0.05 <= t[sampled[1]] and a["lvl.level"][0] > 0.75
