"""Plots from synthetic stats.csv / run.json folders (no solver needed)."""

from __future__ import annotations

import numpy as np
import pytest

from ipsph.errors import OutputError
from ipsph.io.provenance import write_run_json
from ipsph.io.stats import STATS_COLUMNS, StatsWriter
from ipsph.post.plots import plot_runs


def _run(folder, method, scale):
    folder.mkdir(parents=True)
    rng = np.random.default_rng(len(method))
    with StatsWriter(folder / "stats.csv", STATS_COLUMNS) as w:
        for k in range(1, 60):
            w.write(
                {
                    "step": k,
                    "time": 0.005 * k,
                    "dt": 0.005,
                    "particles": 1000,
                    "density_error_mean_pct": scale * (0.04 + 0.01 * rng.random()),
                    "density_error_max_pct": scale * (0.8 + 0.4 * rng.random()),
                    "divergence_error_pct": 0.05 + 0.02 * rng.random(),
                    "pd_passes": 3 + k % 3 if method != "dfsph" else 0,
                    "divergence_iterations": 2 + k % 2,
                    "density_iterations": 4 + k % 5 if method == "dfsph" else 0,
                    "max_speed": 0.1 * k,
                    "kinetic_energy": 1.0,
                    "dt_clamped": 0,
                    "ms_step": 40 * scale,
                    "ms_neighbourSearch": 8,
                    "ms_solvePDConstraints": 20 * scale,
                    "ms_divergenceSolve": 7,
                    "ms_densitySolve": 0 if method != "dfsph" else 15,
                    "ms_xsph": 3,
                }
            )
    write_run_json(folder / "run.json", {"method": method, "status": "completed", "completed": True})
    return folder


def _not_uniform(path):
    import imageio.v2 as imageio

    img = imageio.imread(path)
    return img.ndim == 3 and img[..., :3].std() > 5


def test_one_run_plots_into_its_plots_folder(tmp_path):
    out = _run(tmp_path / "dam_ipsph", "ipsph", 1.0)
    written = plot_runs([out])
    assert {p.name for p in written} == {"errors_iterations.png", "timings.png"}
    assert all(p.parent == out / "plots" and _not_uniform(p) for p in written)


def test_several_runs_overlaid(tmp_path):
    a = _run(tmp_path / "a", "ipsph", 1.0)
    b = _run(tmp_path / "b", "dfsph", 2.0)
    written = plot_runs([a, b], tmp_path / "cmp")
    assert all(p.parent == tmp_path / "cmp" and _not_uniform(p) for p in written)


def test_missing_stats_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match="stats.csv"):
        plot_runs([tmp_path])
