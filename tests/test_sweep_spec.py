"""Sweep files (issue 21) without a cluster: expansion of [set] / [grid] / [zip] into members, their
readable folder names, the scene path relative to the sweep file, and bad sweeps exiting 2 in one line
that names the member and the key before any cluster starts or any folder is created."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from ipsph import cli
from ipsph.scene import default_scene_path, load_scene
from ipsph.sweeps import engine, spec


@pytest.fixture
def scene_dir(tmp_path) -> Path:
    d = tmp_path / "scenes"
    d.mkdir()
    shutil.copy(default_scene_path(), d / "dam.toml")
    return d


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_grid_times_zip_in_file_order(scene_dir):
    f = write(
        scene_dir / "study.toml",
        """
scene = "dam.toml"
[set]
"simulation.end_time" = 0.5
[grid]
"simulation.method" = ["ipsph", "pf", "dfsph"]
[grid.simulation]
particle_radius = [0.04, 0.03]
[zip]
"simulation.viscosity" = [0.01, 0.02]
"fluid.0.velocity" = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
""",
    )
    sw = spec.load_sweep(f)
    assert sw.scene == (scene_dir / "dam.toml").resolve()  # relative to the sweep file, not the cwd
    assert len(sw.members) == 3 * 2 * 2
    first, last = sw.members[0], sw.members[-1]
    assert first.name == "method-ipsph_particle_radius-0.04_viscosity-0.01_velocity-0.0-0.0-0.0"
    assert last.name == "method-dfsph_particle_radius-0.03_viscosity-0.02_velocity-1.0-0.0-0.0"
    assert len({m.name for m in sw.members}) == len(sw.members)
    # [set] first, then the varied keys; every value goes through --set and back unchanged
    assert first.overrides[0] == ("simulation.end_time", 0.5)
    scene = load_scene(sw.scene, last.set_args())
    assert (scene.method.value, scene.particle_radius, scene.viscosity, scene.end_time) == ("dfsph", 0.03, 0.02, 0.5)
    assert tuple(scene.fluids[0].velocity) == (1.0, 0.0, 0.0)


def test_shared_leaf_names_use_the_full_key(scene_dir):
    f = write(
        scene_dir / "s.toml",
        'scene = "dam.toml"\n[grid]\n"solver.pf.passes" = [2, 3]\n'
        '"solver.ipsph.max_passes" = [50]\n"solver.ipsph.min_passes" = [1]\n',
    )
    names = [m.name for m in spec.load_sweep(f).members]
    assert names == ["passes-2_max_passes-50_min_passes-1", "passes-3_max_passes-50_min_passes-1"]
    f2 = write(
        scene_dir / "t.toml",
        'scene = "dam.toml"\n[grid]\n"simulation.viscosity" = [0.01]\n'
        '"solver.pf.stiffness" = [1e4]\n"solver.dfsph.density_error_pct" = [0.05]\n',
    )
    assert spec.load_sweep(f2).members[0].name == "viscosity-0.01_stiffness-10000.0_density_error_pct-0.05"


def test_no_varied_keys_is_one_member(scene_dir):
    f = write(scene_dir / "one.toml", 'scene = "dam.toml"\n[set]\n"simulation.end_time" = 0.1\n')
    assert [m.name for m in spec.load_sweep(f).members] == ["base"]


BAD = [
    # (sweep body after scene = ..., what the one error line must contain)
    ('[grid]\n"simulation.methd" = ["ipsph"]\n', ["member methd-ipsph", "simulation.methd", "did you mean"]),
    ('[grid]\n"simulation.particle_radius" = [0.04, -0.01]\n', ["member particle_radius--0.01", "particle_radius"]),
    (
        '[grid]\n"simulation.particle_radius" = [0.04, 0.2]\n',
        ["member particle_radius-0.2", "fluid[0].box", "particle_radius 0.2 m"],
    ),
    ('[zip]\n"simulation.viscosity" = [0.01, 0.02]\n"simulation.method" = ["pf"]\n', ["[zip]", "equal lengths"]),
    (
        '[set]\n"simulation.method" = "pf"\n[grid]\n"simulation.method" = ["pf"]\n',
        ["simulation.method", "[set] and [grid]"],
    ),
    ('[grid]\n"simulation.method" = "pf"\n', ["simulation.method", "non-empty list"]),
    ('[gird]\n"simulation.method" = ["pf"]\n', ["unknown key 'gird'"]),
]


@pytest.mark.parametrize("body,expect", BAD, ids=[b[1][0] for b in BAD])
def test_bad_sweep_exits_2_in_one_line_before_any_cluster(scene_dir, tmp_path, capsys, monkeypatch, body, expect):
    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started for a bad sweep")

    monkeypatch.setattr(engine, "start_local_cluster", no_cluster)
    f = write(scene_dir / "bad.toml", 'scene = "dam.toml"\n' + body)
    out = tmp_path / "out"
    code = cli.main(["sweep", str(f), "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("ipsph: error: "), err
    for e in expect:
        assert e in lines[0], lines[0]
    assert not out.exists()


def test_missing_scene_names_the_sweep_file(tmp_path, capsys):
    f = write(tmp_path / "s.toml", 'scene = "nowhere.toml"\n')
    assert cli.main(["sweep", str(f), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "s.toml: scene = 'nowhere.toml': file not found" in err and not (tmp_path / "o").exists()


def test_local_layout_from_the_machine(monkeypatch):
    from ipsph.sweeps import cluster

    monkeypatch.setattr(cluster, "usable_cores", lambda: 8)
    assert cluster.local_layout(None, None) == (8, 1)
    assert cluster.local_layout(None, 2) == (4, 2)
    assert cluster.local_layout(2, None) == (2, 4)
    assert cluster.local_layout(3, 3) == (3, 3)
    assert engine.local_layout is cluster.local_layout  # what run_sweep calls
    with pytest.raises(ValueError, match="--workers 0"):
        cluster.local_layout(0, None)


def test_docs_summary_table_is_generated_from_the_columns():
    from ipsph.sweeps import records

    page = (Path(__file__).resolve().parents[1] / "docs" / "sweeps.md").read_text(encoding="utf-8")
    table = page.split("<!-- summary-columns: generated -->\n", 1)[1].split("<!-- /summary-columns -->", 1)[0]
    assert table == records.summary_columns_markdown(), "regenerate it with `python -m ipsph.sweeps`"


def test_bench_sweep_table_leaves_loaded_repeats_out():
    from benchmarks.sweep_bench import table

    def row(wall, seq, loaded):
        return {
            "sweep_wall": wall,
            "sequential_wall": seq,
            "ratio": seq / wall,
            "makespan": wall - 4.0,
            "overhead_per_member": 1.0,
            "dispatch_per_member": 0.05,
            "loaded": loaded,
            "sweep_others_cores": 0.1,
            "sequential_others_cores": 0.1,
            "timings": {"cluster_start": 3.0, "members": wall - 3.5, "close": 0.5},
        }

    result = {
        "end_time": 1.0,
        "members": ["a", "b", "c", "d"],
        "rows": [row(10.0, 20.0, False), row(12.0, 18.0, False), row(100.0, 20.0, True)],
    }
    text = table(result, markdown=False, max_load=0.5)
    import re

    lines = dict(re.split(r"\s{2,}", ln.strip(), maxsplit=1) for ln in text.splitlines()[1:])
    assert float(lines["sweep wall, 2 workers x 1 thread [s]"]) == 11.0  # the loaded 100 s repeat is left out
    assert float(lines["ratio sequential / sweep"]) == pytest.approx((2.0 + 1.5) / 2, abs=0.005)
    assert lines["repeats counted / run"].strip() == "2 / 3"
