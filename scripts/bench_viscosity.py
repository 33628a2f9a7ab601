"""Issue 30's viscosity figures on the built-in dam break (ipsph/scene/default.toml, 3,724
particles, IPSPH, settle off), through the Python API (not yet part of `ipsph bench`):

* the cost per step of each viscosity model at nu = 1e-2 m^2/s (xsph: the XSPH filter alone);
* the wall time per simulated second at nu = 1 m^2/s, implicit against the explicit Standard
  model, which needs dt <= H^2 / (60 nu).

Each run is warmed by two steps (compilation), then timed over the simulated span given.

    python scripts/bench_viscosity.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ipsph.scene import load_scene
from ipsph.simulation import Simulation

SCENE = Path(__file__).resolve().parents[1] / "ipsph" / "scene" / "default.toml"


def measure(model: str, nu: float, span: float) -> None:
    zeta = 0.01 if model == "xsph" else 0.0  # a physical viscosity runs without XSPH on top
    scene = load_scene(
        SCENE,
        [
            "simulation.settle=off",
            f"simulation.viscosity={zeta}",
            f"simulation.viscosity_model={model}",
            f"simulation.kinematic_viscosity_m2s={nu}",
        ],
    )
    sim = Simulation.from_scene(scene)
    sim.step()
    sim.step()
    t0, s0, start = time.perf_counter(), sim.steps, sim.time
    its, solve = [], []
    sim.run(
        end_time=start + span,
        fps=1.0 / span,
        on_step=lambda s: (its.append(s.viscosity_iterations), solve.append(s.timings.get("viscositySolve", 0.0))),
    )
    wall, steps = time.perf_counter() - t0, sim.steps - s0
    print(
        f"| {model} | {nu:g} | {steps} | {1000 * wall / steps:.1f} | {1000 * np.mean(solve):.1f} | "
        f"{np.mean(its):.1f} | {wall / (sim.time - start):.1f} |",
        flush=True,
    )


if __name__ == "__main__":
    print(
        "| model | nu [m^2/s] | steps | ms per step | of which the viscous solve | CG iterations | wall s per simulated s |"
    )
    print("|---|---|---|---|---|---|---|")
    for model in ("xsph", "standard", "implicit"):
        measure(model, 0.0 if model == "xsph" else 1e-2, 0.2)
    for model in ("implicit", "standard"):
        measure(model, 1.0, 0.1)
