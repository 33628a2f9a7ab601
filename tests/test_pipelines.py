"""Every shipped pipeline (pipelines/*.toml, the paper's Table 1) loads, samples and steps.

A smoke test at a coarser radius (r = 0.05 m: hundreds to a few thousand fluid particles), three steps per
method: the scene is valid, its meshes load, and the first steps stay healthy (Simulation.step
raises NumericalFailure on a non-finite or escaped particle) with a sane density error.
"""
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ipsph.params import METHOD_NAMES
from ipsph.scene import load_scene
from ipsph.simulation import Simulation, sample_scene

REPO = Path(__file__).resolve().parents[1]
PIPELINES = sorted((REPO / "pipelines").glob("*.toml"))
# A settling lattice starts under-dense (V = 0.8 d^3) and the first steps compress it by well
# under a percent; a broken scene (fluid inside a wall, a wrong radius) starts far above this.
FIRST_STEPS_DENSITY_ERROR = 0.01


def test_there_are_pipelines():
    assert {p.stem for p in PIPELINES} >= {"breaking_dam", "double_dam_break", "two_dragons"}


def _overrides(path: Path, tmp_path: Path) -> list[str]:
    over = ["simulation.particle_radius=0.05"]
    raw = tomllib.loads(path.read_text())  # the file as written
    for i, b in enumerate(raw.get("boundary", [])):
        mesh = b.get("mesh")
        if mesh is not None and not (path.parent / mesh).is_file():
            # a mesh the checkout does not ship (two_dragons' Dragon_50k.obj lives in the
            # SPlisHSPlasH data): a box obstacle of the dragon's size stands in, so the rest of
            # the pipeline is still stepped
            from ipsph.meshes import box_mesh
            stand_in = tmp_path / f"stand_in_{i}.stl"
            box_mesh((-0.4, 0.0, -0.25), (0.4, 0.6, 0.25)).save(stand_in)
            over.append(f"boundary.{i}.mesh={stand_in}")
    return over


@pytest.mark.parametrize("method", METHOD_NAMES)
@pytest.mark.parametrize("path", PIPELINES, ids=lambda p: p.stem)
def test_pipeline_steps(path, method, tmp_path):
    scene = load_scene(path, _overrides(path, tmp_path) + [f"simulation.method={method}"])
    sim = Simulation(scene, *sample_scene(scene)[:3])
    assert sim.n_fluid > 100 and sim.n_boundary > 0
    for _ in range(3):
        stats = sim.step()
    assert sim.steps == 3 and stats.time > 0
    assert np.all(np.isfinite(sim.positions)) and np.all(np.isfinite(sim.densities))
    assert 0.0 <= stats.density_error_mean <= FIRST_STEPS_DENSITY_ERROR
